//! `qrpose-sim render --hand-eye`: the photos of a hand-eye session agree with their truth
//! (the code is found where the truth puts its corners, and the truth's code pose is the
//! one the mount, target and true flange pose make), and the reported flange poses carry
//! the noise asked for, no more.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use qrpose_detect::decode::{DecodeLimits, decode_gray};
use qrpose_detect::{DetectorChoice, detect_codes};
use serde_json::{Value, json};
use std::ffi::OsStr;
use std::path::Path;

/// Detected corners within this of the truth, px: the detector fits straight sides, which
/// the session's barrel lens (k1 = −0.1) bends by up to ~0.6 px at these views; a wrong
/// pose in the truth would be tens of px off.
const CORNER_TOLERANCE_PX: f64 = 1.0;

fn iso(v: &Value) -> Isometry3<f64> {
    let t: Vec<f64> = serde_json::from_value(v["translation_mm"].clone()).expect("translation");
    let q: Vec<f64> = serde_json::from_value(v["quaternion_wxyz"].clone()).expect("quaternion");
    Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
    )
}

fn session(dir: &Path, setup: &str) -> Value {
    let file = dir.join("session.json");
    let spec = json!({
        "setup": setup,
        "camera": {"fx_px": 1000, "fy_px": 1000,
                   "distortion": {"model": "plumb_bob", "coefficients": [-0.1, 0.02, 0, 0, 0]}},
        "marker": {"size_mm": 120, "payload": "hand-eye test"},
        "mount": {"translation_mm": [40, -20, 90], "quaternion_wxyz": [1, 0, 0, 1]},
        "target": {"translation_mm": [650, 100, 10], "quaternion_wxyz": [0, 1, 0, 0]},
        "generator": {"views": 3},
        "flange_noise": {"translation_mm": 0.5, "rotation_deg": 0.05},
        "seed": 7,
        "checkerboard": {"squares": 10}
    });
    std::fs::write(&file, spec.to_string()).expect("write session");
    let out = dir.join(setup);
    let args: Vec<&OsStr> = vec![
        "--hand-eye".as_ref(),
        file.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--supersample".as_ref(),
        "2".as_ref(),
    ];
    qrpose_sim::cli::render(&args).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn hand_eye_photos_show_the_code_where_the_truth_says_for_both_setups() {
    let dir = std::env::temp_dir().join(format!("qrpose-sim-hand-eye-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    for setup in ["eye_in_hand", "eye_to_hand"] {
        let truth = session(&dir, setup);
        let on_disk: Value = serde_json::from_slice(
            &std::fs::read(dir.join(setup).join("truth.json")).expect("truth.json"),
        )
        .expect("json");
        // The file holds what was printed (floats to JSON's round trip).
        assert_eq!(truth["setup"], on_disk["setup"]);
        assert_eq!(truth["views"][2]["photo"], on_disk["views"][2]["photo"]);
        let mount = iso(&truth["mount"]);
        let target = iso(&truth["target"]);
        let views = truth["views"].as_array().expect("views");
        assert_eq!(views.len(), 3);
        for v in views {
            let flange = iso(&v["flange_pose_true"]);
            let code = iso(&v["code_in_camera"]);
            // T_camera←marker = X⁻¹·F⁻¹·Y (eye-in-hand) or X⁻¹·F·Y.
            let expected = if setup == "eye_in_hand" {
                mount.inverse() * flange.inverse() * target
            } else {
                mount.inverse() * flange * target
            };
            let gap = (expected.to_homogeneous() - code.to_homogeneous()).norm();
            assert!(gap < 1e-6, "{setup}: code pose off by {gap}");
            // The reported pose: noisy, by about the noise asked for.
            let reported = iso(&v["flange_pose_reported"]);
            let dt = (reported.translation.vector - flange.translation.vector).norm();
            let dr = reported.rotation.angle_to(&flange.rotation).to_degrees();
            assert!(dt > 0.0 && dt < 0.5 * 5.0, "{setup}: {dt} mm");
            assert!(dr > 0.0 && dr < 0.05 * 5.0, "{setup}: {dr} deg");
            // The code is found at the truth's corners.
            let photo = dir.join(setup).join(v["photo"].as_str().expect("name"));
            let bytes = std::fs::read(&photo).expect("photo");
            let image = decode_gray(&bytes, &DecodeLimits::default()).expect("decodes");
            let codes = detect_codes(&image, DetectorChoice::Auto).expect("detects");
            let found = codes
                .first()
                .unwrap_or_else(|| panic!("{setup}: no code in {photo:?}"));
            let corners: Vec<[f64; 2]> =
                serde_json::from_value(v["corners_px"].clone()).expect("corners");
            for (p, [u, w]) in found.corners_px().iter().zip(corners) {
                let d = (p.u() - u).hypot(p.v() - w);
                assert!(
                    d < CORNER_TOLERANCE_PX,
                    "{setup} {photo:?}: corner {d} px off"
                );
            }
            let board = dir
                .join(setup)
                .join(v["board"]["photo"].as_str().expect("board"));
            assert!(board.exists(), "{board:?}");
            assert_eq!(
                v["board"]["truth"]["inner_corners_px"]
                    .as_array()
                    .map(Vec::len),
                Some(81)
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
