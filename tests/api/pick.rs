//! Picking (docs/pick.md): a product's code seen by a camera on the arm's flange gives the
//! product's box and its grasps in the robot's frame when the request carries the arm's
//! pose, with the probability of landing within tolerance and `graspable`; every reason
//! that forbids a grasp, and every refusal of the request's picking fields.

#[path = "../support/pick.rs"]
mod scene;

use crate::helpers::{
    TestApp, assert_problem, image_part, multipart_body, request_part, spawn_app_with,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use qrpose::api::problem::ErrorCode;
use qrpose::config::Settings;
use scene::{
    code_on_box, corners, flange_pose, marker_in_camera, mount, object_in_robot, pose_json,
};
use serde_json::{Value, json};
use std::path::PathBuf;

async fn spawn_with_site(name: &str) -> TestApp {
    let dir: PathBuf =
        std::env::temp_dir().join(format!("qrpose-api-pick-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    std::fs::write(dir.join("site.yaml"), scene::SITE).expect("writes the site");
    spawn_app_with(Settings {
        site: Some(dir.join("site.yaml")),
        ..Settings::default()
    })
    .await
}

fn request(flange: Option<&Isometry3<f64>>) -> Value {
    let mut body = json!({
        "corners_px": corners(&marker_in_camera(&flange_pose())),
        "corner_order": "paper",
        "camera": {"id": "wrist"},
        "payload": "SKU-0042",
        "solver": {"method": "reprojection", "corner_sigma_px": 0.1},
    });
    if let Some(f) = flange {
        body["flange_pose"] = pose_json(f);
    }
    body
}

async fn answer(app: &TestApp, body: &Value) -> Value {
    let response = app.post_corners(body).await;
    let status = response.status();
    let answer: Value = response.json().await.expect("JSON");
    assert_eq!(status, 200, "{answer}");
    answer
}

fn position(pose: &Value) -> Vector3<f64> {
    let p = &pose["position_mm"];
    Vector3::new(
        p["x"].as_f64().expect("x"),
        p["y"].as_f64().expect("y"),
        p["z"].as_f64().expect("z"),
    )
}

#[tokio::test]
async fn with_the_arms_pose_the_product_and_its_grasps_are_in_the_robot_frame() {
    let app = spawn_with_site("robot").await;
    let body = answer(&app, &request(Some(&flange_pose()))).await;
    let object = &body["object"];
    assert_eq!(object["rule"], "prefix:SKU-", "{body}");
    assert_eq!(object["box_mm"], json!([200.0, 150.0, 224.0]));
    let truth = object_in_robot();
    let off = (position(&object["pose_in_robot"]) - truth.translation.vector).norm();
    assert!(off < 1.0, "object {off} mm off: {object}");
    let grasps = object["grasps"].as_array().expect("grasps");
    assert_eq!(grasps.len(), 2);
    let top = &grasps[0];
    assert_eq!(
        (top["name"].as_str(), top["kind"].as_str()),
        (Some("top"), Some("suction"))
    );
    assert_eq!(top["width_mm"], Value::Null);
    assert_eq!(grasps[1]["width_mm"], 150.0);
    let grasp_truth = truth * Point3::new(0.0, 0.0, 112.0);
    let off = (position(&top["pose_in_robot"]) - grasp_truth.coords).norm();
    assert!(off < 1.5, "grasp {off} mm off");
    // The pre-grasp is 80 mm back along the grasp's −z: the grasp turns the object's z over,
    // so it lies 80 mm above the top.
    let pre = position(&top["pre_grasp_in_robot"]) - position(&top["pose_in_robot"]);
    let up = truth.rotation * Vector3::z();
    assert!((pre - 80.0 * up).norm() < 1e-6, "{pre}");
    let p = top["within_tolerance_probability"].as_f64().expect("p");
    assert!(p > 0.95, "p {p}");
    assert_eq!(top["graspable"], true, "{top}");
    assert_eq!(top["reasons"], json!([]));
    // The camera-frame poses are there too, the box's the code's moved to the box's centre.
    assert!(
        object["pose"]["covariance"]["matrix"].is_array(),
        "{object}"
    );
}

#[tokio::test]
async fn without_the_arms_pose_a_flange_camera_has_no_robot_frame_and_nothing_is_graspable() {
    let app = spawn_with_site("no-flange").await;
    let body = answer(&app, &request(None)).await;
    assert_eq!(body["pose_in_robot"], Value::Null);
    let object = &body["object"];
    assert!(object["pose"].is_object(), "{body}");
    assert_eq!(object["pose_in_robot"], Value::Null);
    for grasp in object["grasps"].as_array().expect("grasps") {
        assert_eq!(grasp["graspable"], false);
        assert_eq!(grasp["reasons"], json!(["no_robot_pose"]), "{grasp}");
        assert_eq!(grasp["pre_grasp_in_robot"], Value::Null);
    }
    // A camera fixed on the robot needs no flange pose.
    let mut fixed = request(None);
    fixed["camera"] = json!({"id": "fixed"});
    let body = answer(&app, &fixed).await;
    assert!(body["object"]["pose_in_robot"].is_object(), "{body}");
}

/// Whether `reasons` names `reason`.
fn has_reason(reasons: &Value, reason: &str) -> bool {
    reasons
        .as_array()
        .expect("reasons")
        .contains(&json!(reason))
}

/// `grasp` is not graspable, and `reason` is among its reasons.
fn assert_refused_for(grasp: &Value, reason: &str) {
    assert_eq!(grasp["graspable"], false, "{grasp}");
    assert!(has_reason(&grasp["reasons"], reason), "{grasp}");
}

#[tokio::test]
async fn each_reason_that_forbids_a_grasp_is_named() {
    let app = spawn_with_site("reasons").await;
    // Corners known to 6 px: the grasp may be off by more than its tolerance.
    let mut loose = request(Some(&flange_pose()));
    loose["solver"]["corner_sigma_px"] = json!(3.0);
    let body = answer(&app, &loose).await;
    let top = &body["object"]["grasps"][0];
    let p = top["within_tolerance_probability"].as_f64().expect("p");
    assert!(p < 0.95, "p {p}");
    assert_refused_for(top, "below_probability");
    // The same grasp passes a bar below its probability.
    loose["min_grasp_probability"] = json!(p / 2.0);
    let body = answer(&app, &loose).await;
    let reasons = &body["object"]["grasps"][0]["reasons"];
    assert!(!has_reason(reasons, "below_probability"), "{reasons}");
    // Without a covariance (the paper's method) the probability is unknown.
    let mut paper = request(Some(&flange_pose()));
    paper["solver"] = json!({"method": "paper"});
    let body = answer(&app, &paper).await;
    let top = &body["object"]["grasps"][0];
    assert_eq!(top["within_tolerance_probability"], Value::Null);
    assert_refused_for(top, "below_probability");
    // A code seen from afar, tilted by 15°, with noisy corners: its mirror fits as well.
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 15f64.to_radians());
    let far = Isometry3::from_parts(
        Translation3::from(tilt * Vector3::new(0.0, 0.0, -1500.0)),
        tilt,
    );
    let code = object_in_robot() * code_on_box();
    let flange = code * far * mount().inverse();
    let mut ambiguous = request(Some(&flange));
    ambiguous["corners_px"] = corners(&marker_in_camera(&flange));
    ambiguous["solver"] = json!({"method": "reprojection", "corner_sigma_px": 1.0});
    let body = answer(&app, &ambiguous).await;
    let top = &body["object"]["grasps"][0];
    assert_refused_for(top, "pose_ambiguous");
    // One corner measured 2 px off: the fit is worse than 0.1 px corners allow, and the
    // covariance (small as it is) cannot be trusted.
    let mut bent = request(Some(&flange_pose()));
    let u = bent["corners_px"][2][0].as_f64().expect("u");
    bent["corners_px"][2][0] = json!(u + 2.0);
    let body = answer(&app, &bent).await;
    let top = &body["object"]["grasps"][0];
    assert_refused_for(top, "high_reprojection_error");
    // A payload no rule matches has no object.
    let mut other = request(Some(&flange_pose()));
    other["payload"] = json!("LOC-7");
    assert_eq!(answer(&app, &other).await["object"], Value::Null);
}

#[tokio::test]
async fn a_bad_flange_pose_or_grasp_bar_is_refused_naming_the_field() {
    let app = spawn_with_site("refused").await;
    let mut two = request(Some(&flange_pose()));
    two["flange_pose"]["rotation_vector_rad"] = json!([0.0, 0.0, 0.1]);
    let problem = assert_problem(
        app.post_corners(&two).await,
        422,
        ErrorCode::InvalidRobotPose,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/flange_pose"));
    let mut long = request(Some(&flange_pose()));
    long["flange_pose"]["quaternion_wxyz"] = json!([2.0, 0.0, 0.0, 0.0]);
    let problem = assert_problem(
        app.post_corners(&long).await,
        422,
        ErrorCode::InvalidRobotPose,
    )
    .await;
    assert_eq!(
        problem.field.as_deref(),
        Some("/flange_pose/quaternion_wxyz")
    );
    let mut bar = request(Some(&flange_pose()));
    bar["min_grasp_probability"] = json!(1.5);
    let problem = assert_problem(
        app.post_corners(&bar).await,
        422,
        ErrorCode::InvalidGraspProbability,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/min_grasp_probability"));
}

#[tokio::test]
async fn a_photo_with_the_arms_pose_in_its_request_part_gives_the_product_in_the_robot_frame() {
    let app = spawn_with_site("photo").await;
    let png = scene::photo(&scene::flange_pose());
    let part = serde_json::to_vec(&json!({
        "camera": {"id": "wrist"},
        "solver": {"method": "reprojection"},
        "flange_pose": pose_json(&flange_pose()),
    }))
    .expect("JSON");
    let body = multipart_body(&[request_part(&part), image_part(&png)]);
    let response = app.post_image_multipart(body).await;
    let status = response.status();
    let answer: Value = response.json().await.expect("JSON");
    assert_eq!(status, 200, "{answer}");
    let object = &answer["markers"][0]["pose"]["object"];
    assert!(object.is_object(), "{answer}");
    let off = (position(&object["pose_in_robot"]) - object_in_robot().translation.vector).norm();
    assert!(off < 3.0, "object {off} mm off: {object}");
    assert_eq!(object["grasps"][0]["name"], "top");
}
