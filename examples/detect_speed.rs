//! Per-stage time of the image path on the speed benchmark's frame (the frame of
//! `benches/detect.rs`), for quick comparisons and for `valgrind --tool=callgrind`
//! instruction counts, which are stable on a shared machine where wall time is not.
//!
//! ```sh
//! cargo run --release --example detect_speed -- [auto|rqrr|rxing|zxing-cpp] [1280x720|1920x1080|FILE] [ITERATIONS]
//! valgrind --tool=callgrind target/release/examples/detect_speed auto 1280x720 1
//! ```
//! Prints the median of each stage (decode, find candidates, refine) over the iterations,
//! and how each code's refinement ended. FILE: any JPEG or PNG instead of the bench frame.
//! With `QRPOSE_WRITE_FRAME=path.jpg` the frame is also written there (to time other
//! readers on the very same bytes).

#[path = "../benches/common/mod.rs"]
mod common;

use qrpose::detect::refine::refine_corners;
use qrpose::detect::{Backend, DetectorChoice, decode, find_candidates};
use std::time::Instant;

fn median_ms(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let choice = match args.first().map(String::as_str).unwrap_or("auto") {
        "rqrr" => DetectorChoice::Only(Backend::Rqrr),
        "rxing" => DetectorChoice::Only(Backend::Rxing),
        "zxing-cpp" => DetectorChoice::Only(Backend::ZxingCpp),
        _ => DetectorChoice::Auto,
    };
    let size = args.get(1).map(String::as_str).unwrap_or("1280x720");
    let iterations: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20);
    let jpeg = match common::FRAMES.iter().find(|(name, ..)| *name == size) {
        Some(&(_, w, h, f)) => common::frame(w, h, f),
        None => std::fs::read(size).unwrap_or_else(|e| {
            eprintln!("{size} is neither a frame size nor a readable file: {e}");
            std::process::exit(2);
        }),
    };
    if let Ok(path) = std::env::var("QRPOSE_WRITE_FRAME")
        && let Err(e) = std::fs::write(&path, &jpeg)
    {
        eprintln!("cannot write {path}: {e}");
    }
    let limits = decode::DecodeLimits::default();
    let (mut t_decode, mut t_find, mut t_refine) = (Vec::new(), Vec::new(), Vec::new());
    let mut found = 0;
    let mut statuses = Vec::new();
    for _ in 0..iterations {
        let t0 = Instant::now();
        let Ok(image) = decode::decode_gray(&jpeg, &limits) else {
            eprintln!("the frame does not decode");
            std::process::exit(1);
        };
        let t1 = Instant::now();
        let candidates = match find_candidates(&image, choice) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let t2 = Instant::now();
        let refined: Vec<_> = candidates
            .iter()
            .map(|c| refine_corners(&image, &c.corners_px, c.module_count))
            .collect();
        let t3 = Instant::now();
        found = refined.len();
        statuses = refined
            .iter()
            .zip(&candidates)
            .map(|(r, c)| {
                format!(
                    "{} {} {:?}",
                    c.backend.as_str(),
                    r.status.as_str(),
                    c.text.as_deref().unwrap_or("-")
                )
            })
            .collect();
        t_decode.push((t1 - t0).as_secs_f64() * 1e3);
        t_find.push((t2 - t1).as_secs_f64() * 1e3);
        t_refine.push((t3 - t2).as_secs_f64() * 1e3);
    }
    let (d, fi, r) = (median_ms(t_decode), median_ms(t_find), median_ms(t_refine));
    println!(
        "{size} codes {found} ({}): decode {d:.2} ms, find {fi:.2} ms, refine {r:.2} ms, total {:.2} ms (medians of {iterations})",
        statuses.join(", "),
        d + fi + r
    );
}
