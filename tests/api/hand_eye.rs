//! `POST /v1/calibrate/hand-eye`: rendered sessions with a known mount give that mount in
//! both setups, with the names of the spec (camera_pose, target_pose, std, views, warnings,
//! site_mount); the flange poses in each robot form give the same answer; and every refusal
//! is its problem: not one pose per photo, motions about one axis, too few views read, a
//! robot pose with two rotations or a quaternion that is not unit.

#[path = "../support/hand_eye.rs"]
mod session;

use crate::helpers::{
    BOUNDARY, TestApp, assert_problem, image_part, multipart_body, request_part, spawn_app,
};
use qrpose::api::problem::ErrorCode;
use reqwest::Response;
use serde_json::{Value, json};
use session::Setup;
use std::sync::LazyLock;

/// The rendered photos of the eight views, once for every test of this module.
static PHOTOS: LazyLock<Vec<Vec<u8>>> = LazyLock::new(|| session::photos(&session::views()));

async fn calibrate(app: &TestApp, request: &Value, photos: &[Vec<u8>]) -> Response {
    let json = serde_json::to_vec(request).expect("JSON");
    let mut parts = vec![request_part(&json)];
    parts.extend(photos.iter().map(|p| image_part(p)));
    app.client
        .post(format!("{}/v1/calibrate/hand-eye", app.address))
        .header(
            "content-type",
            format!("multipart/form-data; boundary={BOUNDARY}"),
        )
        .body(multipart_body(&parts))
        .send()
        .await
        .expect("request sent")
}

async fn answer(app: &TestApp, request: &Value, photos: &[Vec<u8>]) -> Value {
    let response = calibrate(app, request, photos).await;
    let status = response.status();
    let body: Value = response.json().await.expect("JSON");
    assert_eq!(status, 200, "{body}");
    body
}

#[tokio::test]
async fn both_setups_give_the_mount_and_the_target_they_were_rendered_with() {
    let app = spawn_app().await;
    for setup in [Setup::EyeInHand, Setup::EyeToHand] {
        let poses = session::flange_poses(setup, &session::views());
        let body = answer(
            &app,
            &session::request(setup, &poses, session::quaternion_json),
            &PHOTOS,
        )
        .await;
        let (parent, target_parent, name) = match setup {
            Setup::EyeInHand => ("flange", "robot", "eye_in_hand"),
            Setup::EyeToHand => ("robot", "flange", "eye_to_hand"),
        };
        assert_eq!(body["setup"], name);
        assert_eq!(body["camera_pose"]["parent"], parent);
        assert_eq!(body["target_pose"]["parent"], target_parent);
        let (deg, mm) = session::pose_error(&body["camera_pose"], &session::camera_pose(setup));
        assert!(
            deg < 0.2 && mm < 1.5,
            "{name}: mount off by {deg}° {mm} mm: {body}"
        );
        let (deg, mm) = session::pose_error(&body["target_pose"], &session::target_pose(setup));
        assert!(
            deg < 0.3 && mm < 2.0,
            "{name}: target off by {deg}° {mm} mm"
        );
        for key in ["rotation_deg", "translation_mm"] {
            let std = body["std"][key].as_array().expect("three");
            assert_eq!(std.len(), 3);
            assert!(
                std.iter().all(|s| s.as_f64().is_some_and(|s| s > 0.0)),
                "{key}: {std:?}"
            );
        }
        let rms = body["reprojection_rms_px"].as_f64().expect("rms");
        assert!(rms > 0.0 && rms < 0.5, "rms {rms}");
        let views = body["views"].as_array().expect("views");
        assert_eq!(views.len(), PHOTOS.len());
        for (k, v) in views.iter().enumerate() {
            assert_eq!(v["index"], k);
            assert_eq!(v["used"], true, "{v}");
            for key in ["rms_px", "rotation_residual_deg", "translation_residual_mm"] {
                assert!(v[key].is_f64(), "{key}: {v}");
            }
        }
        let mount = body["site_mount"].as_str().expect("YAML");
        assert!(
            mount.starts_with(&format!("mount:\n  parent: {parent}\n")),
            "{mount}"
        );
        assert!(
            mount.contains("translation_mm: [") && mount.contains("std: {"),
            "{mount}"
        );
    }
}

#[tokio::test]
async fn every_robot_pose_form_of_the_same_motion_gives_the_same_mount() {
    let app = spawn_app().await;
    let poses = session::flange_poses(Setup::EyeInHand, &session::views());
    let quaternion = answer(
        &app,
        &session::request(Setup::EyeInHand, &poses, session::quaternion_json),
        &PHOTOS,
    )
    .await;
    for form in [session::rotation_vector_json, session::euler_zyx_json] {
        let other = answer(
            &app,
            &session::request(Setup::EyeInHand, &poses, form),
            &PHOTOS,
        )
        .await;
        for key in ["translation_mm", "quaternion_wxyz"] {
            for i in 0..3 {
                let a = quaternion["camera_pose"][key][i]
                    .as_f64()
                    .expect("a number");
                let b = other["camera_pose"][key][i].as_f64().expect("a number");
                assert!((a - b).abs() < 1e-6, "{key}[{i}]: {a} against {b}");
            }
        }
    }
}

#[tokio::test]
async fn the_controllers_stated_flange_noise_sets_the_mounts_uncertainty() {
    let app = spawn_app().await;
    let poses = session::flange_poses(Setup::EyeInHand, &session::views());
    let mut request = session::request(Setup::EyeInHand, &poses, session::quaternion_json);
    let default = answer(&app, &request, &PHOTOS).await;
    request["flange_noise"] = json!({"translation_mm": 2.0, "rotation_deg": 0.2});
    let noisy = answer(&app, &request, &PHOTOS).await;
    let std = |body: &Value, key: &str| -> f64 {
        body["std"][key]
            .as_array()
            .expect("three")
            .iter()
            .filter_map(Value::as_f64)
            .sum()
    };
    for key in ["rotation_deg", "translation_mm"] {
        assert!(
            std(&noisy, key) > 2.0 * std(&default, key),
            "{key}: {} against {}",
            std(&noisy, key),
            std(&default, key)
        );
    }
    request["flange_noise"] = json!({"translation_mm": 0.0, "rotation_deg": 0.02});
    let problem = assert_problem(
        calibrate(&app, &request, &PHOTOS).await,
        422,
        ErrorCode::SolverParameterOutOfRange,
    )
    .await;
    assert_eq!(
        problem.field.as_deref(),
        Some("/flange_noise/translation_mm")
    );
}

#[tokio::test]
async fn not_one_flange_pose_per_photo_is_refused_before_the_photos_are_read() {
    let app = spawn_app().await;
    let poses = session::flange_poses(Setup::EyeInHand, &session::views()[..7]);
    let request = session::request(Setup::EyeInHand, &poses, session::quaternion_json);
    let problem = assert_problem(
        calibrate(&app, &request, &PHOTOS).await,
        422,
        ErrorCode::FlangePosesMismatch,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/flange_poses"));
    assert!(
        problem.detail.contains("8 photos and 7 flange poses"),
        "{}",
        problem.detail
    );
}

#[tokio::test]
async fn motions_about_one_axis_are_refused_as_degenerate() {
    let app = spawn_app().await;
    let photos = session::photos(&session::orbit());
    let poses = session::flange_poses(Setup::EyeInHand, &session::orbit());
    let request = session::request(Setup::EyeInHand, &poses, session::quaternion_json);
    let problem = assert_problem(
        calibrate(&app, &request, &photos).await,
        422,
        ErrorCode::DegenerateMotion,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/flange_poses"));
}

#[tokio::test]
async fn fewer_than_four_photos_with_the_code_read_are_too_few() {
    let app = spawn_app().await;
    let mut photos: Vec<Vec<u8>> = PHOTOS[..3].to_vec();
    let (w, h) = session::SIZE_PX;
    let blank = image::GrayImage::from_pixel(w, h, image::Luma([230u8]));
    let mut png = Vec::new();
    blank
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("a PNG encodes");
    photos.push(png);
    let poses = session::flange_poses(Setup::EyeInHand, &session::views()[..4]);
    let request = session::request(Setup::EyeInHand, &poses, session::quaternion_json);
    let problem = assert_problem(
        calibrate(&app, &request, &photos).await,
        422,
        ErrorCode::TooFewViews,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("image"));
}

#[tokio::test]
async fn a_robot_pose_with_two_rotations_or_a_long_quaternion_is_refused_naming_it() {
    let app = spawn_app().await;
    let poses = session::flange_poses(Setup::EyeInHand, &session::views());
    let mut request = session::request(Setup::EyeInHand, &poses, session::quaternion_json);
    request["flange_poses"][3]["euler_zyx_deg"] = json!([0.0, 0.0, 0.0]);
    let problem = assert_problem(
        calibrate(&app, &request, &PHOTOS).await,
        422,
        ErrorCode::InvalidRobotPose,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/flange_poses/3"));
    let mut request = session::request(Setup::EyeInHand, &poses, session::quaternion_json);
    request["flange_poses"][5]["quaternion_wxyz"] = json!([1.0, 0.1, 0.0, 0.0]);
    let problem = assert_problem(
        calibrate(&app, &request, &PHOTOS).await,
        422,
        ErrorCode::InvalidRobotPose,
    )
    .await;
    assert_eq!(
        problem.field.as_deref(),
        Some("/flange_poses/5/quaternion_wxyz")
    );
    let mut request = session::request(Setup::EyeInHand, &poses, session::quaternion_json);
    request["marker"] = Value::Null;
    let problem = assert_problem(
        calibrate(&app, &request, &PHOTOS).await,
        422,
        ErrorCode::UnknownMarkerSize,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/marker"));
}
