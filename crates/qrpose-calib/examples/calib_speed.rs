//! Times one calibration of the round trips' reference set: 15 views of a 120 mm QR-code-like
//! target (236 points each) at 0.3-0.7 m, tilted 10-40°, 0.2 px of noise, for each lens
//! model, on the camera of that model's round-trip test. Reports the wall-clock median and
//! minimum and, on Linux, the CPU time per solve from `/proc/self/schedstat` (time spent
//! running, which other processes sharing the core do not inflate).
//!
//! ```text
//! cargo build --release -p qrpose-calib --example calib_speed
//! taskset -c 0 target/release/examples/calib_speed
//! ```

#[path = "../tests/support/mod.rs"]
mod support;

use qrpose_calib::{Options, calibrate};
use qrpose_core::geometry::camera::DistortionModel;
use std::time::{Duration, Instant};
use support::{IMAGE, good_set};

/// Timed solves per model (after one untimed warm-up); the median is reported.
const RUNS: usize = 15;

fn main() {
    for (model, truth) in [
        (DistortionModel::PlumbBob, support::barrel_camera()),
        (
            DistortionModel::RationalPolynomial,
            support::wide_angle_camera(),
        ),
        (DistortionModel::Equidistant, support::fisheye_camera()),
    ] {
        let set = good_set(&truth, 0.2, 7);
        let points: usize = set.views.iter().map(|v| v.points.len()).sum();
        let options = Options {
            model,
            ..Options::default()
        };
        let solve =
            || calibrate(&set.views, IMAGE, &options).expect("the reference set calibrates");
        let first = solve();
        let cpu_before = cpu_time_ns();
        let mut times: Vec<Duration> = (0..RUNS)
            .map(|_| {
                let start = Instant::now();
                let result = solve();
                let elapsed = start.elapsed();
                assert_eq!(result, first, "deterministic");
                elapsed
            })
            .collect();
        let cpu_ms = cpu_before
            .zip(cpu_time_ns())
            .map(|(a, b)| format!("{:.1} ms", (b - a) as f64 * 1e-6 / RUNS as f64))
            .unwrap_or_else(|| "unknown".to_owned());
        times.sort();
        println!(
            "{model:<20} {} views, {points} points: CPU {cpu_ms} a solve; wall median {:.1} ms (min {:.1}, max {:.1}); {} iterations, fx {:.2} px, rms {:.3} px",
            set.views.len(),
            times[RUNS / 2].as_secs_f64() * 1e3,
            times[0].as_secs_f64() * 1e3,
            times[RUNS - 1].as_secs_f64() * 1e3,
            first.iterations,
            first.camera.fx(),
            first.reprojection_rms_px
        );
    }
}

/// This process's time on a CPU so far, ns (Linux `/proc/self/schedstat`, first field).
fn cpu_time_ns() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/schedstat").ok()?;
    text.split_whitespace().next()?.parse().ok()
}
