//! Accuracy of the calibration on synthetic sets with known truth: for each lens model (on
//! the camera of its round-trip test) and noise level, 20 seeded sets of the round trips'
//! reference design (15 views of a 120 mm QR-code-like target, 236 points each, 0.3-0.7 m,
//! tilted 10-40°). Prints one Markdown table row per case.
//!
//! ```text
//! cargo run --release -p qrpose-calib --example calib_accuracy
//! ```

#[path = "../tests/support/mod.rs"]
mod support;

use qrpose_calib::compare::{distortion_field_difference_px, projection_difference_px};
use qrpose_calib::{Options, calibrate};
use qrpose_core::geometry::camera::DistortionModel;
use support::{IMAGE, good_set};

/// Sets per case.
const SETS: u64 = 20;

fn rms(values: &[f64]) -> f64 {
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}

fn max(values: &[f64]) -> f64 {
    values.iter().fold(0.0, |m, v| m.max(v.abs()))
}

fn main() {
    println!(
        "| model | noise px | focal error % (RMS / max) | std fx % (mean) | principal point error px (RMS / max) | field p95 px (max) | projection p95 px (max) | (est − true)/std RMS fx, cx | iterations (max) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (model, truth) in [
        (DistortionModel::PlumbBob, support::barrel_camera()),
        (
            DistortionModel::RationalPolynomial,
            support::wide_angle_camera(),
        ),
        (DistortionModel::Equidistant, support::fisheye_camera()),
    ] {
        let options = Options {
            model,
            ..Options::default()
        };
        for noise in [0.1, 0.2, 0.3] {
            let (mut focal, mut std, mut pp, mut field, mut moved, mut zf, mut zc, mut it) =
                (vec![], vec![], vec![], vec![], vec![], vec![], vec![], 0);
            for seed in 0..SETS {
                let set = good_set(&truth, noise, 1000 + seed);
                let r = calibrate(&set.views, IMAGE, &options).expect("calibrates");
                let c = &r.camera;
                focal.push(100.0 * (c.fx() / truth.fx() - 1.0));
                std.push(100.0 * r.std.fx_px / c.fx());
                pp.push((c.cx() - truth.cx()).hypot(c.cy() - truth.cy()));
                field.push(
                    distortion_field_difference_px(&truth, c, IMAGE, 0.9, 0.95).unwrap_or(f64::NAN),
                );
                moved.push(
                    projection_difference_px(&truth, c, IMAGE, 0.9, 0.95).unwrap_or(f64::NAN),
                );
                zf.push((c.fx() - truth.fx()) / r.std.fx_px);
                zc.push((c.cx() - truth.cx()) / r.std.cx_px);
                it = it.max(r.iterations);
            }
            println!(
                "| {model} | {noise} | {:.3} / {:.3} | {:.3} | {:.2} / {:.2} | {:.2} | {:.2} | {:.2}, {:.2} | {it} |",
                rms(&focal),
                max(&focal),
                std.iter().sum::<f64>() / std.len() as f64,
                rms(&pp),
                max(&pp),
                max(&field),
                max(&moved),
                rms(&zf),
                rms(&zc),
            );
        }
    }
}
