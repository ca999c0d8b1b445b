//! qrpose's own picking on a rendered picking study (docs/measurements/pick.md), on the same
//! photos as the anchor (`scripts/pick_anchor.py`): per photo, qrpose-detect finds and
//! refines the code, the core's default solver (`reprojection`) gives its pose and
//! covariance, and `qrpose_site::pick::plan_pick` carries them through the study's site file
//! (the wrist camera on the flange, the objects) with the photo's flange pose into each
//! grasp's pose in the robot frame, its probability of being within tolerance, and
//! whether it is graspable. Printed: the grasp errors against the truth (median, p90, over
//! 20°), and how the stated probability compares with how often the grasps really are within
//! tolerance.
//!
//! `cargo run -p qrpose-sim --example pick_study -- DIR [CORNER_SIGMA_PX]` (DIR from
//! `qrpose-sim render --pick-study SEED --out DIR`, with its `site.yaml` and `truth.json`;
//! CORNER_SIGMA_PX: the solver's `corner_sigma_px`, the corner noise its covariance assumes,
//! default the core's 0.5 px). Also printed: the refined corners' error against the truth,
//! the noise the covariance should assume.

use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};
use qrpose_core::estimate::reprojection::ReprojectionParams;
use qrpose_core::estimate::solver::Solver;
use qrpose_core::geometry::marker::Marker;
use qrpose_detect::decode::{DecodeLimits, decode_gray};
use qrpose_detect::pipeline::{MarkerSizes, Options, Setup, locate_markers};
use qrpose_site::pick::{PickOptions, camera_in_robot, plan_pick};
use qrpose_site::transform::{Rigid, marker_in_camera};
use qrpose_site::{Site, sizes};
use serde_json::Value;
use std::path::PathBuf;

/// A grasp further off than this is a mirror pose of the planar ambiguity, degrees.
const MIRROR_DEG: f64 = 20.0;

/// The site's marker sizes, by payload.
struct SiteSizes<'a>(&'a sizes::MarkerSizes);

impl MarkerSizes for SiteSizes<'_> {
    type Source = ();

    fn marker_for(&self, payload: Option<&str>) -> Option<(Marker, ())> {
        let size = self.0.lookup(payload)?;
        Marker::try_new(size.size_mm).ok().map(|m| (m, ()))
    }
}

fn rigid(v: &Value) -> Rigid {
    let num = |key: &str, i: usize| v[key][i].as_f64().unwrap_or(f64::NAN);
    let q = Quaternion::new(
        num("quaternion_wxyz", 0),
        num("quaternion_wxyz", 1),
        num("quaternion_wxyz", 2),
        num("quaternion_wxyz", 3),
    );
    Rigid {
        rotation: UnitQuaternion::from_quaternion(q).to_rotation_matrix(),
        translation_mm: Vector3::new(
            num("translation_mm", 0),
            num("translation_mm", 1),
            num("translation_mm", 2),
        ),
    }
}

fn pct(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    // The nearest rank, as the anchor script takes it.
    let rank = ((v.len() - 1) as f64 * q).round();
    v[(0..v.len())
        .find(|&i| i as f64 >= rank)
        .unwrap_or(v.len() - 1)]
}

/// One grasp's outcome.
struct Outcome {
    approach: bool,
    distance_mm: f64,
    position_error_mm: f64,
    rotation_error_deg: f64,
    within: bool,
    probability: Option<f64>,
    graspable: bool,
    ambiguous: bool,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).ok_or("usage: pick_study DIR")?);
    let site = Site::load(&dir.join("site.yaml"))?;
    let wrist = site.camera("wrist").ok_or("the site has no camera wrist")?;
    let truth: Value = serde_json::from_slice(&std::fs::read(dir.join("truth.json"))?)?;
    let products = truth["scene"]["products"].as_array().ok_or("no products")?;
    let defaults = ReprojectionParams::default();
    let corner_sigma_px = match std::env::args().nth(2) {
        Some(s) => s.parse()?,
        None => defaults.corner_sigma_px,
    };
    let setup = Setup {
        camera: wrist.camera,
        sizes: SiteSizes(site.sizes()),
        solver: Solver::Reprojection(ReprojectionParams {
            corner_sigma_px,
            ..defaults
        })
        .validate()?,
    };
    let mut corner_errors_px = Vec::new();
    let mut outcomes = Vec::new();
    let (mut in_view, mut read) = (0, 0);
    for photo in truth["photos"].as_array().ok_or("no photos")? {
        let image_path = dir.join(photo["image"].as_str().ok_or("no image")?);
        let image = decode_gray(&std::fs::read(&image_path)?, &DecodeLimits::default())?;
        let located = locate_markers(&image, &setup, &Options::default())?;
        let flange = rigid(&photo["flange_pose"]);
        let label = photo["label"].as_str().unwrap_or_default();
        for seen in photo["products"].as_array().ok_or("no products")? {
            in_view += 1;
            let product = &products[usize::try_from(seen["product"].as_u64().ok_or("no index")?)?];
            let payload = product["payload"].as_str().ok_or("no payload")?;
            let Some(found) = located
                .markers
                .iter()
                .find(|m| m.code.candidate.payload.as_deref() == Some(payload.as_bytes()))
            else {
                continue;
            };
            let Ok(estimate) = found.pose.as_ref() else {
                continue;
            };
            for (p, t) in found
                .code
                .corners_px()
                .iter()
                .zip(seen["code"]["corners_px"].as_array().ok_or("no corners")?)
            {
                let (u, v) = (
                    t[0].as_f64().unwrap_or(f64::NAN),
                    t[1].as_f64().unwrap_or(f64::NAN),
                );
                corner_errors_px.push((p.u() - u).hypot(p.v() - v));
            }
            read += 1;
            let (_, rule) = site.object_for(payload).ok_or("no object rule")?;
            let in_robot = camera_in_robot(wrist.camera_mount.as_ref(), Some(&flange));
            let ambiguous = estimate
                .diagnostics
                .ambiguity
                .as_ref()
                .is_some_and(|a| a.ambiguous);
            let options = PickOptions {
                pose_ambiguous: ambiguous,
                not_converged: !estimate.diagnostics.converged,
                ..PickOptions::default()
            };
            let plan = plan_pick(
                &marker_in_camera(estimate),
                rule,
                in_robot.as_ref(),
                &options,
            )?;
            let distance_mm = rigid(&seen["marker_in_camera"]).translation_mm.norm();
            for ((planned, grasp), true_grasp) in plan
                .grasps
                .iter()
                .zip(&rule.grasps)
                .zip(seen["grasps"].as_array().ok_or("no grasps")?)
            {
                let est = planned.pose_in_robot.ok_or("no robot pose")?.pose;
                let truth = rigid(&true_grasp["in_robot"]);
                let position_error_mm = (est.translation_mm - truth.translation_mm).norm();
                let rotation_error_deg =
                    Rotation3::angle_to(&est.rotation, &truth.rotation).to_degrees();
                outcomes.push(Outcome {
                    approach: label.starts_with("approach"),
                    distance_mm,
                    position_error_mm,
                    rotation_error_deg,
                    within: position_error_mm <= grasp.tolerance.position_mm
                        && rotation_error_deg.to_radians() <= grasp.tolerance.rotation_rad,
                    probability: planned.within_tolerance_probability,
                    graspable: planned.graspable,
                    ambiguous,
                });
            }
        }
    }
    println!(
        "# qrpose on {}: {read} of {in_view} codes in view read; corner_sigma_px {corner_sigma_px}",
        dir.display()
    );
    println!(
        "refined corners against the truth: median {:.3} px, p90 {:.3} px",
        pct(&corner_errors_px, 0.5),
        pct(&corner_errors_px, 0.9)
    );
    println!();
    println!(
        "| photos | grasps | position error median / p90 mm | rotation error median / p90 ° | grasps off > 20° | flagged pose_ambiguous |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, approach) in [("pick", false), ("approach", true)] {
        let g: Vec<&Outcome> = outcomes.iter().filter(|o| o.approach == approach).collect();
        let pos: Vec<f64> = g.iter().map(|o| o.position_error_mm).collect();
        let rot: Vec<f64> = g.iter().map(|o| o.rotation_error_deg).collect();
        let mirrored = rot.iter().filter(|&&r| r > MIRROR_DEG).count();
        let flagged = g.iter().filter(|o| o.ambiguous).count();
        println!(
            "| {name} | {} | {:.2} / {:.2} | {:.2} / {:.2} | {mirrored} | {flagged} |",
            g.len(),
            pct(&pos, 0.5),
            pct(&pos, 0.9),
            pct(&rot, 0.5),
            pct(&rot, 0.9)
        );
    }
    println!();
    println!("By distance (picks):");
    println!(
        "| distance mm | grasps | position median / p90 mm | rotation median / p90 ° | off > 20° |"
    );
    println!("|---|---|---|---|---|");
    for (lo, hi) in [(250.0, 450.0), (450.0, 650.0), (650.0, 900.0)] {
        let g: Vec<&Outcome> = outcomes
            .iter()
            .filter(|o| !o.approach && (lo..hi).contains(&o.distance_mm))
            .collect();
        let pos: Vec<f64> = g.iter().map(|o| o.position_error_mm).collect();
        let rot: Vec<f64> = g.iter().map(|o| o.rotation_error_deg).collect();
        println!(
            "| {lo:.0}-{hi:.0} | {} | {:.2} / {:.2} | {:.2} / {:.2} | {} |",
            g.len(),
            pct(&pos, 0.5),
            pct(&pos, 0.9),
            pct(&rot, 0.5),
            pct(&rot, 0.9),
            rot.iter().filter(|&&r| r > MIRROR_DEG).count()
        );
    }
    println!();
    println!("Stated probability against the outcome (all grasps):");
    println!("| within_tolerance_probability | grasps | mean stated | really within tolerance |");
    println!("|---|---|---|---|");
    for (lo, hi) in [(0.0, 0.5), (0.5, 0.8), (0.8, 0.95), (0.95, 1.01)] {
        let g: Vec<&Outcome> = outcomes
            .iter()
            .filter(|o| o.probability.is_some_and(|p| (lo..hi).contains(&p)))
            .collect();
        if g.is_empty() {
            println!("| {lo:.2}-{:.2} | 0 | – | – |", hi.min(1.0));
            continue;
        }
        let mean = g.iter().filter_map(|o| o.probability).sum::<f64>() / g.len() as f64;
        let within = g.iter().filter(|o| o.within).count();
        println!(
            "| {lo:.2}-{:.2} | {} | {mean:.3} | {within} ({:.1} %) |",
            hi.min(1.0),
            g.len(),
            100.0 * within as f64 / g.len() as f64
        );
    }
    let graspable: Vec<&Outcome> = outcomes.iter().filter(|o| o.graspable).collect();
    let ok = graspable.iter().filter(|o| o.within).count();
    let missed = outcomes.iter().filter(|o| !o.graspable && o.within).count();
    println!();
    println!(
        "graspable: {} of {} grasps; {ok} of them really within tolerance ({:.1} %); {missed} grasps within tolerance were not graspable",
        graspable.len(),
        outcomes.len(),
        100.0 * ok as f64 / graspable.len().max(1) as f64
    );
    Ok(())
}
