//! Accuracy of the three methods on noisy corners, and the shared dataset for OpenCV.
//!
//! `cargo run --release --example corner_accuracy -- [OUT_DIR] [SIGMA_PX] [CASES] [SEED]`
//! writes `OUT_DIR/corners.csv` (the dataset, see `qrpose_sim::dataset`) and
//! `OUT_DIR/qrpose_results.csv` (per case and method: rotation error in degrees, centre
//! error in mm, converged, ambiguous), and prints a summary. `scripts/accuracy_corners.py`
//! runs it and adds OpenCV's solvePnP on the same corners.

use qrpose::estimate::{Method, ValidSolver, Warning, estimate_pose};
use qrpose::geometry::{euler::angle_between, marker::CornerOrder, quad::ImageQuad};
use qrpose_sim::dataset::{DatasetSpec, generate, to_csv};
use qrpose_sim::report::quantile;
use std::fmt::Write;
use std::path::PathBuf;

fn arg<T: std::str::FromStr>(i: usize, default: T) -> T {
    std::env::args()
        .nth(i)
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out: PathBuf = arg(1, PathBuf::from("target/accuracy"));
    let spec = DatasetSpec {
        sigma_px: arg(2, 0.5),
        cases: arg(3, 2000),
        seed: arg(4, 2022),
        ..DatasetSpec::default()
    };
    std::fs::create_dir_all(&out)?;
    let cases = generate(&spec)?;
    std::fs::write(out.join("corners.csv"), to_csv(&spec, &cases))?;
    let (camera, marker) = (spec.camera()?, spec.marker()?);
    let mut csv =
        String::from("id,method,rotation_error_deg,position_error_mm,converged,ambiguous\n");
    println!(
        "{} cases, sigma {} px, seed {}",
        cases.len(),
        spec.sigma_px,
        spec.seed
    );
    println!(
        "| method | rotation error median / mean / p95 (deg) | position error median / mean / p95 (mm) | converged |"
    );
    println!("|---|---|---|---|");
    for method in [Method::Reprojection, Method::DepthNewton, Method::Paper] {
        let params = ValidSolver::default_for(method);
        let (mut rot, mut pos, mut converged) = (Vec::new(), Vec::new(), 0usize);
        for (i, c) in cases.iter().enumerate() {
            let quad = ImageQuad::try_new(c.noisy_px, CornerOrder::Qr)?;
            let e = estimate_pose(&quad, &camera, &marker, &params)?;
            let r = angle_between(&e.pose.rotation(), &c.truth.rotation()).to_degrees();
            let p = (e.centre_mm - c.centre_mm).norm();
            converged += usize::from(e.diagnostics.converged);
            let ambiguous = e.diagnostics.warnings.contains(&Warning::PoseAmbiguous);
            writeln!(
                csv,
                "{i},{},{r:.9e},{p:.9e},{},{ambiguous}",
                method.as_str(),
                e.diagnostics.converged
            )?;
            rot.push(r);
            pos.push(p);
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (rm, pm) = (mean(&rot), mean(&pos));
        println!(
            "| qrpose {} | {:.3} / {rm:.3} / {:.3} | {:.3} / {pm:.3} / {:.3} | {:.1} % |",
            method.as_str(),
            quantile(&mut rot.clone(), 0.5),
            quantile(&mut rot, 0.95),
            quantile(&mut pos.clone(), 0.5),
            quantile(&mut pos, 0.95),
            100.0 * converged as f64 / cases.len() as f64
        );
    }
    std::fs::write(out.join("qrpose_results.csv"), csv)?;
    Ok(())
}
