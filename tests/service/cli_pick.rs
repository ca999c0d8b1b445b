//! Picking from the command line (docs/pick.md): `qrpose estimate --image … --site …
//! --flange-pose …` prints what `POST /v1/pose/image` answers with the same arm pose in its
//! request part (field for field but the timings), the product and its grasps in the robot
//! frame; and a corners request file with `flange_pose` prints the route's answer.

#[path = "../support/pick.rs"]
mod scene;

use qrpose::api::image::{ImageRequest, respond};
use qrpose::app::{CancelFlag, ImageLimits, Site};
use serde_json::{Value, json};
use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;

const BIN: &str = env!("CARGO_BIN_EXE_qrpose");

/// A directory of its own with the site file and the photo.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-cli-pick-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    std::fs::write(dir.join("site.yaml"), scene::SITE).expect("writes the site");
    dir
}

/// `value` with every timing and duration field emptied.
fn untimed(mut value: Value) -> Value {
    value["timing_ms"] = Value::Null;
    if let Some(markers) = value["markers"].as_array_mut() {
        for marker in markers {
            marker["pose"]["diagnostics"]["elapsed_us"] = Value::Null;
        }
    }
    value
}

#[test]
fn a_photo_with_the_arms_pose_prints_what_the_route_answers() {
    let dir = scratch("photo");
    let flange = scene::flange_pose();
    let photo = scene::photo(&flange);
    std::fs::write(dir.join("photo.png"), &photo).expect("writes the photo");
    let flange_json = scene::pose_json(&flange);
    let output = Command::new(BIN)
        .args(["estimate", "--image"])
        .arg(dir.join("photo.png"))
        .arg("--site")
        .arg(dir.join("site.yaml"))
        .args(["--camera-id", "wrist", "--method", "reprojection"])
        .args(["--flange-pose", &flange_json.to_string()])
        .output()
        .expect("qrpose runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let printed: Value = serde_json::from_slice(&output.stdout).expect("JSON on stdout");
    let object = &printed["markers"][0]["pose"]["object"];
    assert_eq!(object["rule"], "prefix:SKU-", "{printed}");
    assert!(object["pose_in_robot"].is_object(), "{object}");

    let site = Site::load(&dir.join("site.yaml")).expect("the site");
    let request: ImageRequest = serde_json::from_value(json!({
        "camera": {"id": "wrist"},
        "solver": {"method": "reprojection"},
        "flange_pose": flange_json,
    }))
    .expect("a request");
    let setup = request
        .setup(&ImageLimits::default(), Some(Arc::new(site)))
        .expect("valid");
    let answered = respond(&setup, &photo, CancelFlag::new()).expect("answers");
    let answered = serde_json::to_value(answered).expect("JSON");
    assert_eq!(untimed(printed), untimed(answered));
}

#[test]
fn a_bad_flange_pose_flag_is_a_problem_naming_it() {
    let dir = scratch("bad");
    std::fs::write(dir.join("photo.png"), scene::photo(&scene::flange_pose())).expect("writes");
    let output = Command::new(BIN)
        .args(["estimate", "--image"])
        .arg(dir.join("photo.png"))
        .arg("--site")
        .arg(dir.join("site.yaml"))
        .args(["--camera-id", "wrist"])
        .args(["--flange-pose", r#"{"translation_mm": [0, 0, 0]}"#])
        .output()
        .expect("qrpose runs");
    assert_eq!(output.status.code(), Some(2));
    let problem: Value = serde_json::from_slice(&output.stderr).expect("a problem document");
    assert_eq!(problem["code"], "invalid_robot_pose", "{problem}");
    assert_eq!(problem["field"], "/flange_pose");
}
