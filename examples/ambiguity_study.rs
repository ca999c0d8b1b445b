//! How well the reported ambiguity tells a wrong pick of the planar ambiguity.
//!
//! `cargo run --release --example ambiguity_study`
//!
//! For corner noise σ = 0.25, 0.5, 1 and 2 px, solves a seeded noisy dataset each
//! (`qrpose_sim::dataset`: 50 mm marker at 200-1500 mm, tilt 0-60°, 1280×720, f = 1000 px,
//! 5000 cases) with the `reprojection` method, `corner_sigma_px` = σ, and records whether the
//! reported pose is the wrong one of the pair (the alternative is nearer the truth). It then
//! compares two ways to set `ambiguous`: the alternative's posterior probability
//! (`alternative_probability`, what qrpose uses) and a fixed threshold on the RMS ratio. For
//! each it prints the share of poses flagged, the share of wrong picks among the poses NOT
//! flagged (what trusting unflagged poses risks), and the share of wrong picks the flag
//! catches; then the probability's calibration (predicted against observed wrong rate).

use qrpose::estimate::{DISTINCT_ROTATION_DEG, ReprojectionParams, Solver, estimate_pose};
use qrpose::geometry::{euler::angle_between, marker::CornerOrder, quad::ImageQuad};
use qrpose_sim::dataset::{DatasetSpec, generate};

struct Record {
    ratio: f64,
    probability: f64,
    distinct: bool,
    wrong: bool,
}

fn row(label: &str, records: &[Record], flagged: impl Fn(&Record) -> bool) -> String {
    let n = records.len() as f64;
    let wrong_total = records.iter().filter(|r| r.wrong).count();
    let n_flagged = records.iter().filter(|r| flagged(r)).count();
    let unflagged_wrong = records.iter().filter(|r| !flagged(r) && r.wrong).count();
    let caught = records.iter().filter(|r| flagged(r) && r.wrong).count();
    format!(
        "| {label} | {:.1} % | {:.2} % | {:.1} % of {wrong_total} |",
        100.0 * n_flagged as f64 / n,
        100.0 * unflagged_wrong as f64 / (n - n_flagged as f64).max(1.0),
        100.0 * caught as f64 / wrong_total.max(1) as f64,
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut calibration = Vec::new();
    println!("| σ (px), rule | flagged | wrong among unflagged | wrong picks caught |");
    println!("|---|---|---|---|");
    for (k, sigma_px) in [0.25, 0.5, 1.0, 2.0].into_iter().enumerate() {
        let spec = DatasetSpec {
            cases: 5000,
            sigma_px,
            seed: 7 + k as u64,
            ..DatasetSpec::default()
        };
        let (camera, marker) = (spec.camera()?, spec.marker()?);
        let params = Solver::Reprojection(ReprojectionParams {
            corner_sigma_px: sigma_px,
            ..ReprojectionParams::default()
        })
        .validate()
        .expect("a valid corner noise");
        let mut records = Vec::new();
        for c in generate(&spec)? {
            let quad = ImageQuad::try_new(c.noisy_px, CornerOrder::Qr)?;
            let e = estimate_pose(&quad, &camera, &marker, &params)?;
            let Some(a) = e.diagnostics.ambiguity else {
                continue;
            };
            let best = angle_between(&e.pose.rotation(), &c.truth.rotation());
            let alternative = angle_between(&a.alternative.rotation(), &c.truth.rotation());
            let distinct = a.rotation_difference_rad.to_degrees() > DISTINCT_ROTATION_DEG;
            let probability = a.alternative_probability.unwrap_or(f64::NAN);
            records.push(Record {
                ratio: a.ratio,
                probability,
                distinct,
                wrong: distinct && best > alternative,
            });
        }
        for t in [0.001, 0.01, 0.05] {
            println!(
                "{}",
                row(&format!("{sigma_px}, probability ≥ {t}"), &records, |r| r
                    .distinct
                    && r.probability >= t)
            );
        }
        for t in [0.3, 0.5, 0.7] {
            println!(
                "{}",
                row(&format!("{sigma_px}, ratio ≥ {t}"), &records, |r| r
                    .distinct
                    && r.ratio >= t)
            );
        }
        for (lo, hi) in [(0.0, 0.01), (0.01, 0.1), (0.1, 0.3), (0.3, 0.5001)] {
            let bin: Vec<&Record> = records
                .iter()
                .filter(|r| r.distinct && r.probability >= lo && r.probability < hi)
                .collect();
            let predicted =
                bin.iter().map(|r| r.probability).sum::<f64>() / bin.len().max(1) as f64;
            let observed = bin.iter().filter(|r| r.wrong).count() as f64 / bin.len().max(1) as f64;
            calibration.push(format!(
                "| {sigma_px} | [{lo}, {}) | {} | {predicted:.3} | {observed:.3} |",
                hi.min(0.5),
                bin.len()
            ));
        }
    }
    println!("\n| σ (px) | probability bin | cases | predicted wrong rate | observed wrong rate |");
    println!("|---|---|---|---|---|");
    for line in calibration {
        println!("{line}");
    }
    Ok(())
}
