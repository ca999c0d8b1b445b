//! Times qrpose's solvers exactly as `benches/opencv/pose_bench.cpp` times OpenCV: the same
//! cases (target/accuracy/corners.csv), one thread, 2 warm-up rounds and 15 timed rounds over
//! all cases, median per call. Prints "<method> <median ns per call> <calls per round>".
//!
//! `cargo run --release --example pose_timing -- [CSV] [METHOD]` (run by
//! scripts/bench_opencv_pose.sh); with METHOD only that solver.

use qrpose::estimate::{Method, ValidSolver, estimate_pose};
use qrpose::geometry::{
    camera::Camera,
    frames::PixelPoint,
    marker::{CornerOrder, Marker},
    quad::ImageQuad,
};
use std::collections::HashMap;
use std::hint::black_box;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/accuracy/corners.csv".to_owned());
    let text = std::fs::read_to_string(&path)?;
    let mut lines = text.lines();
    let header: HashMap<&str, f64> = lines
        .next()
        .ok_or("empty file")?
        .trim_start_matches('#')
        .split_whitespace()
        .filter_map(|kv| {
            kv.split_once('=')
                .and_then(|(k, v)| Some((k, v.parse().ok()?)))
        })
        .collect();
    let get = |k: &str| header.get(k).copied().ok_or(format!("header lacks {k}"));
    let camera = Camera::from_pixels(get("f_px")?, get("f_px")?, get("cx_px")?, get("cy_px")?)?;
    let marker = Marker::try_new(get("marker_mm")?)?;
    let mut quads = Vec::new();
    for line in lines.skip(1) {
        let v: Vec<f64> = line.split(',').map(str::parse).collect::<Result<_, _>>()?;
        let corners: [PixelPoint; 4] =
            std::array::from_fn(|k| PixelPoint::new(v[13 + 2 * k], v[14 + 2 * k]));
        quads.push(ImageQuad::try_new(corners, CornerOrder::Qr)?);
    }
    let only = std::env::args().nth(2);
    for method in [Method::Paper, Method::DepthNewton, Method::Reprojection] {
        if only.as_deref().is_some_and(|m| m != method.as_str()) {
            continue;
        }
        let params = ValidSolver::default_for(method);
        let mut per_call = Vec::new();
        for round in 0..17 {
            let start = Instant::now();
            for q in &quads {
                black_box(estimate_pose(black_box(q), &camera, &marker, &params)?);
            }
            if round >= 2 {
                per_call.push(start.elapsed().as_nanos() as f64 / quads.len() as f64);
            }
        }
        per_call.sort_by(f64::total_cmp);
        println!(
            "qrpose_{} {:.0} {}",
            method.as_str(),
            per_call[per_call.len() / 2],
            quads.len()
        );
    }
    Ok(())
}
