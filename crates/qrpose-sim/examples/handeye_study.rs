//! The hand-eye study's Rust side (`scripts/handeye_study.sh`, docs/measurements/hand-eye.md):
//! renders hand-eye sessions with known truth, reads the code's calibration points in every
//! photo (qrpose-detect's `calibration_points`), calibrates with qrpose-calib's
//! `calibrate_hand_eye` at each flange-noise level, and writes everything the OpenCV side
//! needs to run on the very same photos and the same reported flange poses.
//!
//! ```text
//! cargo run --release -p qrpose-sim --example handeye_study -- OUT_DIR [--seeds N] [--first-seed S]
//! ```
//!
//! Per setup (eye-in-hand, eye-to-hand) and seed: 12 views of a 120 mm version-4 code at
//! 0.3-0.7 m, tilted up to 40° (qrpose-sim's hand-eye generator), and a 10 × 10-square
//! checkerboard of the same size at the same poses; camera 1280 × 720, fx 1000, fy 1005,
//! cx 652, cy 349 px, plumb_bob k1 −0.12, k2 0.03, p1 5e-4, p2 −3e-4, k3 0; effects of the
//! calibration comparison (blur σ 0.8 px, noise σ 2, lighting 0.2, 20 background shapes,
//! JPEG 90). Flange noise levels: 0.2 mm / 0.02° and twice that, the same normal deviates
//! doubled. Writes OUT_DIR/<setup>-<seed>/photo-NNN.jpg, board-NNN.jpg and session.json (the
//! truth, the reported poses of each level, the board's corners in mm, and qrpose's answer
//! per level with its errors and normalised errors); photos already rendered are reused.
//! Prints one summary line per session.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use qrpose_calib::handeye::{HandEyeOptions, HandEyeSetup, HandEyeView, calibrate_hand_eye};
use qrpose_calib::{Correspondence, ImageSize};
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose_core::geometry::marker::Marker;
use qrpose_detect::decode::{DecodeLimits, decode_gray};
use qrpose_detect::refine::calibration_points;
use qrpose_detect::{DetectorChoice, detect_codes};
use qrpose_sim::render::hand_eye::{
    FlangeNoise, Setup, Transform, ViewGenerator, marker_to_camera, session_poses,
};
use qrpose_sim::render::{
    BoardScene, Checkerboard, EcLevel, Effects, Encoding, Scene, render, render_checkerboard,
};
use rayon::prelude::*;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::Instant;

const WIDTH_PX: u32 = 1280;
const HEIGHT_PX: u32 = 720;
const CODE_MM: f64 = 120.0;
const BOARD_SQUARES: u32 = 10;
const PAYLOAD: &str = "https://example.com/qrpose/calibration-target/120mm";
const LENS: [f64; 5] = [-0.12, 0.03, 5e-4, -3e-4, 0.0];
/// Flange noise levels: (mm, deg) per axis.
const LEVELS: [(f64, f64); 2] = [(0.2, 0.02), (0.4, 0.04)];

fn camera() -> Camera {
    Camera::from_pixels(1000.0, 1005.0, 652.0, 349.0)
        .expect("valid intrinsics")
        .with_distortion(
            Distortion::from_coefficients(DistortionModel::PlumbBob, &LENS).expect("valid lens"),
        )
}

fn iso(t: [f64; 3], euler: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(Vector3::from(t)),
        UnitQuaternion::from_euler_angles(euler[0], euler[1], euler[2]),
    )
}

/// The true mount and target of each setup: eye-in-hand, a wrist camera 95 mm out along
/// the flange looking along it and the code on the table; eye-to-hand, a camera on a post
/// beside the arm and the code held 160 mm out from the flange.
fn truth(setup: Setup) -> (Isometry3<f64>, Isometry3<f64>) {
    match setup {
        Setup::EyeInHand => (
            iso([42.0, -27.0, 95.0], [0.05, -0.08, 1.6]),
            iso([650.0, 120.0, 15.0], [3.1, 0.02, 0.4]),
        ),
        Setup::EyeToHand => (
            iso([900.0, 700.0, 850.0], [-2.2, 0.1, 1.9]),
            iso([10.0, -35.0, 160.0], [0.1, 3.0, -0.7]),
        ),
    }
}

fn effects(seed: u64) -> Effects {
    Effects {
        supersample: 4,
        blur_px: 0.8,
        noise: 2.0,
        lighting: 0.2,
        clutter: 20,
        encoding: Encoding::Jpeg(90),
        seed,
        ..Effects::default()
    }
}

fn name(setup: Setup) -> &'static str {
    match setup {
        Setup::EyeInHand => "eye_in_hand",
        Setup::EyeToHand => "eye_to_hand",
    }
}

/// The code's calibration points in one photo (the decoded code with the most), as
/// correspondences in qrpose-detect's marker frame.
fn points(path: &Path, marker: &Marker) -> Vec<Correspondence> {
    let Ok(bytes) = std::fs::read(path) else {
        return Vec::new();
    };
    let Ok(image) = decode_gray(&bytes, &DecodeLimits::default()) else {
        return Vec::new();
    };
    let codes = detect_codes(&image, DetectorChoice::Auto).unwrap_or_default();
    codes
        .iter()
        .map(|code| calibration_points(&image, code, marker))
        .max_by_key(Vec::len)
        .unwrap_or_default()
        .iter()
        .map(|p| Correspondence::new(p.marker.0.x, p.marker.0.y, p.pixel_px.u(), p.pixel_px.v()))
        .collect()
}

fn rotation_deg(a: &Isometry3<f64>, b: &Isometry3<f64>) -> f64 {
    a.rotation.angle_to(&b.rotation).to_degrees()
}

fn translation_mm(a: &Isometry3<f64>, b: &Isometry3<f64>) -> f64 {
    (a.translation.vector - b.translation.vector).norm()
}

/// One session: render (unless already there), detect, calibrate at each level.
fn session(out: &Path, setup: Setup, seed: u64) -> Value {
    let dir = out.join(format!("{}-{seed:02}", name(setup)));
    std::fs::create_dir_all(&dir).expect("create the session folder");
    let cam = camera();
    let marker = Marker::try_new(CODE_MM).expect("valid size");
    let (mount, target) = truth(setup);
    let generator = ViewGenerator::default();
    let levels: Vec<_> = LEVELS
        .iter()
        .map(|&(mm, deg)| {
            let noise = FlangeNoise {
                translation_mm: mm,
                rotation_deg: deg,
            };
            session_poses(
                setup,
                &mount,
                &target,
                None,
                &generator,
                &noise,
                &cam,
                [WIDTH_PX, HEIGHT_PX],
                &marker,
                seed,
            )
            .expect("views drawn")
        })
        .collect();
    let poses = &levels[0];
    let board = Checkerboard {
        squares: BOARD_SQUARES,
        size_mm: CODE_MM,
        border_mm: CODE_MM * 4.0 / 33.0,
    };
    let board_mm: Vec<Vec<[f64; 2]>> = poses
        .codes
        .par_iter()
        .enumerate()
        .map(|(k, code)| {
            let pose = marker_to_camera(code, &marker);
            let fx = effects(seed * 1000 + k as u64);
            let photo = dir.join(format!("photo-{k:03}.jpg"));
            if !photo.exists() {
                let scene = Scene {
                    payload: PAYLOAD.as_bytes().to_vec(),
                    ec_level: EcLevel::M,
                    marker,
                    camera: cam,
                    width_px: WIDTH_PX,
                    height_px: HEIGHT_PX,
                    pose,
                };
                let r = render(&scene, &fx).expect("renders");
                std::fs::write(&photo, &r.encoded).expect("write photo");
            }
            let scene = BoardScene {
                board,
                camera: cam,
                width_px: WIDTH_PX,
                height_px: HEIGHT_PX,
                pose,
            };
            let board_photo = dir.join(format!("board-{k:03}.jpg"));
            let truth = qrpose_sim::render::board_truth(&scene).expect("board in view");
            if !board_photo.exists() {
                let b = render_checkerboard(&scene, &fx).expect("renders");
                std::fs::write(&board_photo, &b.encoded).expect("write board");
            }
            truth.inner_corners_mm
        })
        .collect();
    let detect_started = Instant::now();
    let read: Vec<Vec<Correspondence>> = (0..poses.codes.len())
        .into_par_iter()
        .map(|k| points(&dir.join(format!("photo-{k:03}.jpg")), &marker))
        .collect();
    let detect_s = detect_started.elapsed().as_secs_f64();
    let he_setup = match setup {
        Setup::EyeInHand => HandEyeSetup::EyeInHand,
        Setup::EyeToHand => HandEyeSetup::EyeToHand,
    };
    let mut qrpose = serde_json::Map::new();
    for (level, &(mm, deg)) in levels.iter().zip(&LEVELS) {
        let views: Vec<HandEyeView> = read
            .iter()
            .zip(&level.reported)
            .map(|(c, f)| HandEyeView {
                correspondences: c.clone(),
                flange_pose: *f,
            })
            .collect();
        let mut options = HandEyeOptions::default();
        options.flange_noise.translation_std_mm = mm;
        options.flange_noise.rotation_std_rad = deg.to_radians();
        let started = Instant::now();
        let result = calibrate_hand_eye(
            &cam,
            ImageSize::new(WIDTH_PX, HEIGHT_PX),
            &marker,
            &views,
            he_setup,
            &options,
        );
        let solve_ms = started.elapsed().as_secs_f64() * 1e3;
        let entry = match result {
            Ok(found) => {
                let est = found.camera_pose;
                let w = (est.rotation * mount.rotation.inverse()).scaled_axis();
                let dt = est.translation.vector - mount.translation.vector;
                let e = [w.x, w.y, w.z, dt.x, dt.y, dt.z];
                let normalised: Vec<f64> = (0..6)
                    .map(|i| e[i] / found.covariance[(i, i)].sqrt())
                    .collect();
                json!({
                    "camera_pose": Transform::from_isometry(&est),
                    "target_pose": Transform::from_isometry(&found.target_pose),
                    "rotation_error_deg": rotation_deg(&est, &mount),
                    "translation_error_mm": translation_mm(&est, &mount),
                    "target_rotation_error_deg": rotation_deg(&found.target_pose, &target),
                    "target_translation_error_mm": translation_mm(&found.target_pose, &target),
                    "std_rotation_deg": found.std_rotation_deg(),
                    "std_translation_mm": found.std_translation_mm,
                    "normalised_errors": normalised,
                    "reprojection_rms_px": found.reprojection_rms_px,
                    "pixel_noise_px": found.pixel_noise_px,
                    "views_used": found.views.iter().filter(|v| v.used).count(),
                    "warnings": found.warnings.iter().map(|w| w.code()).collect::<Vec<_>>(),
                    "solve_ms": solve_ms,
                    "site_mount": found.site_mount(),
                })
            }
            Err(e) => json!({"error": e.code(), "detail": e.to_string()}),
        };
        qrpose.insert(format!("{mm}"), entry);
    }
    let views: Vec<Value> = (0..poses.codes.len())
        .map(|k| {
            json!({
                "photo": format!("photo-{k:03}.jpg"),
                "board": format!("board-{k:03}.jpg"),
                "points": read[k].len(),
                "flange_true": Transform::from_isometry(&poses.flanges[k]),
                "reported": levels.iter().zip(&LEVELS).map(|(l, &(mm, _))| {
                    (format!("{mm}"), serde_json::to_value(Transform::from_isometry(&l.reported[k])).expect("json"))
                }).collect::<serde_json::Map<_, _>>(),
                "code_in_camera": Transform::from_isometry(&poses.codes[k]),
                "board_inner_corners_mm": board_mm[k],
            })
        })
        .collect();
    let d = cam.distortion();
    let doc = json!({
        "setup": name(setup),
        "seed": seed,
        "image": {"width_px": WIDTH_PX, "height_px": HEIGHT_PX},
        "camera": {"fx_px": cam.fx(), "fy_px": cam.fy(), "cx_px": cam.cx(), "cy_px": cam.cy(),
                   "distortion": d.coefficients()},
        "marker": {"size_mm": CODE_MM, "payload": PAYLOAD},
        "board": {"squares": BOARD_SQUARES, "size_mm": CODE_MM},
        "levels": LEVELS.iter().map(|&(mm, deg)| json!({"translation_mm": mm, "rotation_deg": deg})).collect::<Vec<_>>(),
        "mount": Transform::from_isometry(&mount),
        "target": Transform::from_isometry(&target),
        "views": views,
        "qrpose": qrpose,
        "detect_s": detect_s,
    });
    std::fs::write(
        dir.join("session.json"),
        serde_json::to_vec_pretty(&doc).expect("json"),
    )
    .expect("write session.json");
    doc
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(out) = args.first().map(PathBuf::from) else {
        eprintln!("usage: handeye_study OUT_DIR [--seeds N] [--first-seed S]");
        std::process::exit(2);
    };
    let flag = |name: &str, default: u64| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .map_or(default, |v| v.parse().expect("a number"))
    };
    let seeds = flag("--seeds", 20);
    let first = flag("--first-seed", 1);
    for setup in [Setup::EyeInHand, Setup::EyeToHand] {
        for seed in first..first + seeds {
            let doc = session(&out, setup, seed);
            let q = &doc["qrpose"];
            let line: Vec<String> = LEVELS
                .iter()
                .map(|&(mm, _)| {
                    let r = &q[format!("{mm}")];
                    format!(
                        "{mm} mm: {:.4}° {:.3} mm {:?}",
                        r["rotation_error_deg"].as_f64().unwrap_or(f64::NAN),
                        r["translation_error_mm"].as_f64().unwrap_or(f64::NAN),
                        r["warnings"]
                    )
                })
                .collect();
            let read = doc["views"].as_array().map_or(0, |v| {
                v.iter().filter(|v| v["points"].as_u64() > Some(0)).count()
            });
            println!(
                "{} seed {seed}: {read}/12 read; {}",
                name(setup),
                line.join("; ")
            );
        }
    }
}
