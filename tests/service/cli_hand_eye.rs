//! `qrpose calibrate hand-eye`: a rendered session in, the same JSON as
//! `POST /v1/calibrate/hand-eye` out (field for field but the timings), with the flange poses
//! from a file in any robot form; a refusal is a problem document on stderr, exit code 2.

#[path = "../support/hand_eye.rs"]
mod session;

use qrpose::api::hand_eye::{HandEyeRequest, respond};
use qrpose::app::{CancelFlag, ImageLimits};
use serde_json::{Value, json};
use session::Setup;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_qrpose");

/// A directory of its own for this test, emptied.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-hand-eye-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}

/// Writes `photos` and `poses` into `dir` and runs the command on them with `setup`.
fn run(dir: &Path, setup: &str, photos: &[Vec<u8>], poses: &Value) -> Output {
    let poses_path = dir.join("poses.json");
    std::fs::write(&poses_path, poses.to_string()).expect("writes the poses");
    let paths: Vec<PathBuf> = photos
        .iter()
        .enumerate()
        .map(|(k, bytes)| {
            let path = dir.join(format!("view_{k:02}.jpg"));
            std::fs::write(&path, bytes).expect("writes a photo");
            path
        })
        .collect();
    Command::new(BIN)
        .args(["calibrate", "hand-eye", "--setup", setup, "--flange-poses"])
        .arg(&poses_path)
        .args([
            "--fx-px", "600", "--fy-px", "600", "--cx-px", "321", "--cy-px", "238",
        ])
        .arg("--distortion-coefficients=-0.12,0.03,0,0,0")
        .args(["--marker-size-mm", &session::CODE_MM.to_string()])
        .args(&paths)
        .output()
        .expect("qrpose runs")
}

/// `value` without its timings.
fn untimed(mut value: Value) -> Value {
    value["timing_ms"] = Value::Null;
    value
}

#[test]
fn the_command_prints_what_the_route_answers() {
    let dir = scratch("same");
    let views = session::views();
    let photos = session::photos(&views);
    let poses = session::flange_poses(Setup::EyeToHand, &views);
    let request = session::request(Setup::EyeToHand, &poses, session::euler_zyx_json);
    let output = run(&dir, "eye-to-hand", &photos, &request["flange_poses"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let printed: Value = serde_json::from_slice(&output.stdout).expect("JSON on stdout");
    let request: HandEyeRequest = serde_json::from_value(request).expect("a request");
    let answered = respond(
        &request,
        &ImageLimits::default(),
        None,
        &photos,
        &CancelFlag::new(),
    )
    .expect("calibrates");
    let answered = serde_json::to_value(answered).expect("JSON");
    assert_eq!(untimed(printed.clone()), untimed(answered));
    let (deg, mm) = session::pose_error(
        &printed["camera_pose"],
        &session::camera_pose(Setup::EyeToHand),
    );
    assert!(deg < 0.2 && mm < 1.5, "mount off by {deg}° {mm} mm");
}

#[test]
fn a_refusal_is_a_problem_document_on_stderr_with_exit_code_2() {
    let dir = scratch("refused");
    let views = session::views();
    let photos = session::photos(&views[..4]);
    let poses = session::flange_poses(Setup::EyeInHand, &views[..3]);
    let output = run(
        &dir,
        "eye-in-hand",
        &photos,
        &json!(
            poses
                .iter()
                .map(session::quaternion_json)
                .collect::<Vec<_>>()
        ),
    );
    assert_eq!(output.status.code(), Some(2));
    let problem: Value = serde_json::from_slice(&output.stderr).expect("a problem document");
    assert_eq!(problem["code"], "flange_poses_mismatch", "{problem}");
}
