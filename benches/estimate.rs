//! Criterion benchmarks of one pose solve per method, on realistic noisy corners.
//!
//! `cargo bench --bench estimate`. Inputs: the first 256 cases of the default
//! `qrpose_sim::dataset` (50 mm marker at 200-1500 mm in front of a 1280×720 camera with
//! fx = 1000 px, tilt up to 60°, σ = 0.5 px corner noise), cycled so that every iteration
//! solves a different view. Targets (one core): paper ≤ 1 µs, depth-newton ≤ 2 µs,
//! reprojection (both candidates and LM) ≤ 10 µs. `scripts/bench_opencv_pose.sh` times
//! OpenCV's IPPE_SQUARE + RefineLM on the same cases in C++.

use criterion::{Criterion, criterion_group, criterion_main};
use qrpose::api::{estimate_corners, request::CornersRequest};
use qrpose::estimate::{Method, ValidSolver, estimate_pose};
use qrpose::geometry::{marker::CornerOrder, quad::ImageQuad};
use qrpose_sim::dataset::{DatasetSpec, generate};
use std::hint::black_box;

const CASES: usize = 256;

fn per_method(c: &mut Criterion) {
    let spec = DatasetSpec {
        cases: CASES,
        ..DatasetSpec::default()
    };
    let cases = generate(&spec).expect("dataset");
    let (camera, marker) = (
        spec.camera().expect("camera"),
        spec.marker().expect("marker"),
    );
    let quads: Vec<ImageQuad> = cases
        .iter()
        .map(|c| ImageQuad::try_new(c.noisy_px, CornerOrder::Qr).expect("valid quad"))
        .collect();
    let mut group = c.benchmark_group("estimate");
    for method in [Method::Paper, Method::DepthNewton, Method::Reprojection] {
        let params = ValidSolver::default_for(method);
        let mut i = 0;
        group.bench_function(method.as_str(), |b| {
            b.iter(|| {
                i = (i + 1) % quads.len();
                black_box(estimate_pose(
                    black_box(&quads[i]),
                    &camera,
                    &marker,
                    &params,
                ))
            })
        });
    }
    group.finish();
}

fn full_request(c: &mut Criterion) {
    let spec = DatasetSpec {
        cases: CASES,
        ..DatasetSpec::default()
    };
    let requests: Vec<CornersRequest> = generate(&spec)
        .expect("dataset")
        .iter()
        .map(|case| {
            let body = serde_json::json!({
                "corners_px": case.noisy_px.iter().map(|p| [p.u(), p.v()]).collect::<Vec<_>>(),
                "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
                "marker": {"size_mm": 50.0}
            });
            serde_json::from_value(body).expect("valid request")
        })
        .collect();
    let mut i = 0;
    c.bench_function(
        "api/estimate_corners (validate, reprojection, response)",
        |b| {
            b.iter(|| {
                i = (i + 1) % requests.len();
                black_box(estimate_corners(black_box(&requests[i]), None))
            })
        },
    );
}

criterion_group!(benches, per_method, full_request);
criterion_main!(benches);
