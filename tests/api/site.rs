//! A site loaded with `--site` (docs/site.md): `GET /v1/site`, cameras by id, sizes by
//! payload, poses in the robot's and the warehouse's frame, the fused localisation, the
//! prior, and reloads (good, bad, under load).

use crate::helpers::{TestApp, assert_problem, spawn_app, spawn_app_with};
use qrpose::api::problem::ErrorCode;
use qrpose::config::Settings;
use qrpose::geometry::{camera::Camera, euler::EulerXyz, marker::Marker};
use qrpose_sim::render::{CodePlacement, EcLevel, Effects, Encoding, MultiScene, render_scene};
use reqwest::StatusCode;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/site");
/// The robot pose the fixture's map was made for: (12000, 4500, 0) mm, turned 90° about z.
const ROBOT_MM: [f64; 3] = [12000.0, 4500.0, 0.0];
const ROBOT_HEADING_DEG: f64 = 90.0;

/// A directory of its own with the fixture site (site file and calibration files).
fn site_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-api-site-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    for file in [
        "warehouse.yaml",
        "front-opencv.yaml",
        "rear-camera-info.yaml",
    ] {
        std::fs::copy(Path::new(FIXTURES).join(file), dir.join(file)).expect("copied");
    }
    dir
}

async fn spawn_with_site(dir: &Path) -> TestApp {
    spawn_app_with(Settings {
        site: Some(dir.join("warehouse.yaml")),
        ..Settings::default()
    })
    .await
}

fn placement(payload: &str, size_mm: f64, centre: [f64; 3], euler_deg: [f64; 3]) -> CodePlacement {
    let marker = Marker::try_new(size_mm).expect("a size");
    let r = EulerXyz::from_degrees(euler_deg[0], euler_deg[1], euler_deg[2]).to_rotation();
    CodePlacement {
        payload: payload.as_bytes().to_vec(),
        ec_level: EcLevel::M,
        marker,
        pose: marker.pose_centred_at(r, nalgebra::Vector3::from(centre)),
    }
}

/// The codes of `tests/fixtures/site/scene.json`, seen by the front camera.
fn warehouse_scene() -> MultiScene {
    MultiScene {
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a camera"),
        width_px: 1280,
        height_px: 720,
        codes: vec![
            placement("LOC-0001", 80.0, [-220.0, 40.0, 900.0], [10.0, 35.0, 0.0]),
            placement(
                "LOC-0002",
                80.0,
                [230.0, -30.0, 1000.0],
                [-10.0, -30.0, 0.0],
            ),
            placement("SKU-1", 50.0, [0.0, 80.0, 600.0], [15.0, 0.0, 5.0]),
        ],
    }
}

fn photo(scene: &MultiScene) -> Vec<u8> {
    let effects = Effects {
        encoding: Encoding::Png,
        ..Effects::default()
    };
    render_scene(scene, &effects).expect("renders").encoded
}

/// Code `i`'s exact corners, paper order.
fn exact_corners(scene: &MultiScene, i: usize) -> Value {
    let code = &scene.codes[i];
    let corners: Vec<[f64; 2]> = code
        .marker
        .object_points()
        .iter()
        .map(|m| {
            let p = scene
                .camera
                .project(&code.pose.transform(m))
                .expect("in front");
            [p.u(), p.v()]
        })
        .collect();
    json!(corners)
}

fn corners_request(scene: &MultiScene, i: usize, payload: &str) -> Value {
    json!({
        "corners_px": exact_corners(scene, i),
        "corner_order": "paper",
        "camera": {"id": "front"},
        "payload": payload
    })
}

/// The position and heading (rotation about z, degrees) of a frame pose.
fn position_and_heading(pose: &Value) -> ([f64; 3], f64) {
    let p = &pose["position_mm"];
    let xyz = ["x", "y", "z"].map(|k| p[k].as_f64().expect("a number"));
    let heading = pose["rotation"]["euler_xyz_deg"]["gamma"]
        .as_f64()
        .expect("a number");
    (xyz, heading)
}

fn assert_robot_near(pose: &Value, tolerance_mm: f64, tolerance_deg: f64, what: &str) {
    let (xyz, heading) = position_and_heading(pose);
    let off_mm = xyz
        .iter()
        .zip(ROBOT_MM)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        off_mm < tolerance_mm,
        "{what}: robot at {xyz:?}, {off_mm} mm off"
    );
    let alpha = pose["rotation"]["euler_xyz_deg"]["alpha"]
        .as_f64()
        .unwrap_or(f64::NAN);
    let beta = pose["rotation"]["euler_xyz_deg"]["beta"]
        .as_f64()
        .unwrap_or(f64::NAN);
    for (angle, truth) in [(heading, ROBOT_HEADING_DEG), (alpha, 0.0), (beta, 0.0)] {
        assert!(
            (angle - truth).abs() < tolerance_deg,
            "{what}: angle {angle}°, expected {truth}°"
        );
    }
}

#[tokio::test]
async fn get_site_answers_what_is_loaded_with_the_files_sha256() {
    let dir = site_dir("get");
    let app = spawn_with_site(&dir).await;
    let response = app.get("/v1/site").await;
    assert_eq!(response.status(), StatusCode::OK);
    let body: Value = response.json().await.expect("JSON");
    let bytes = std::fs::read(dir.join("warehouse.yaml")).expect("read");
    assert_eq!(body["sha256"], json!(qrpose_site::site::sha256_hex(&bytes)));
    assert_eq!(body["cameras"]["front"]["camera"]["fx_px"], json!(1000.0));
    assert_eq!(
        body["cameras"]["rear"]["calibration"]["format"],
        json!("ros_camera_info")
    );
    assert_eq!(
        body["markers"]["sizes"][2]["pattern"],
        json!("^LOC-[0-9]{4}$")
    );
    assert_eq!(body["map"][1]["payload"], json!("LOC-0002"));
    // Each camera is shown as a pose request takes it: sent as it is, it gives the pose the
    // camera's id gives.
    for id in ["front", "rear"] {
        let by_id = json!({
            "corners_px": [[300, 200], [360, 202], [358, 262], [298, 260]],
            "camera": {"id": id},
            "marker": {"size_mm": 80},
        });
        let mut inline = by_id.clone();
        inline["camera"] = body["cameras"][id]["camera"].clone();
        let a: Value = app.post_corners(&by_id).await.json().await.expect("JSON");
        let b: Value = app.post_corners(&inline).await.json().await.expect("JSON");
        assert!(a["position_mm"].is_object(), "{a}");
        assert_eq!(a["position_mm"], b["position_mm"], "{id}: {b}");
        assert_eq!(a["rotation"], b["rotation"], "{id}");
    }
}

#[tokio::test]
async fn without_a_site_the_site_routes_answer_404_no_site() {
    let app = spawn_app().await;
    assert_problem(app.get("/v1/site").await, 404, ErrorCode::NoSite).await;
    let reload = app.request(reqwest::Method::POST, "/v1/site/reload").await;
    assert_problem(reload, 404, ErrorCode::NoSite).await;
    let mut body = corners_request(&warehouse_scene(), 0, "LOC-0001");
    body["marker"] = json!({"size_mm": 80});
    let problem =
        assert_problem(app.post_corners(&body).await, 422, ErrorCode::UnknownCamera).await;
    assert_eq!(problem.field.as_deref(), Some("/camera/id"));
}

#[tokio::test]
async fn a_corners_request_by_camera_id_gets_the_site_size_and_the_robot_frames() {
    let dir = site_dir("corners");
    let app = spawn_with_site(&dir).await;
    let scene = warehouse_scene();
    let response = app
        .post_corners(&corners_request(&scene, 0, "LOC-0001"))
        .await;
    assert_eq!(response.status(), StatusCode::OK);
    let pose: Value = response.json().await.expect("JSON");
    assert_eq!(pose["marker_size_mm"], json!(80.0));
    assert_eq!(pose["marker_size_source"], json!("site:pattern"));
    // The code's centre in the robot frame: camera (−220, 40, 900) through the mount.
    let (in_robot, _) = position_and_heading(&pose["pose_in_robot"]);
    let expected = [1200.0, 220.0, 460.0];
    for (a, b) in in_robot.iter().zip(expected) {
        assert!((a - b).abs() < 1e-6, "pose_in_robot {in_robot:?}");
    }
    assert_robot_near(
        &pose["robot_pose_in_world"],
        1.0,
        0.1,
        "robot_pose_in_world",
    );
    assert!(pose["robot_pose_in_world"]["covariance"]["matrix"].is_array());

    // An unmapped code: the robot frame, no world pose; the default size.
    let mut sku = corners_request(&scene, 2, "SKU-1");
    sku["payload"] = json!("SKU-1");
    let pose: Value = app.post_corners(&sku).await.json().await.expect("JSON");
    assert_eq!(pose["marker_size_source"], json!("site:default"));
    assert!(pose["pose_in_robot"].is_object() && pose["robot_pose_in_world"].is_null());

    // The request's size beats the site's.
    let mut sized = corners_request(&scene, 0, "LOC-0001");
    sized["marker"] = json!({"size_mm": 40});
    let pose: Value = app.post_corners(&sized).await.json().await.expect("JSON");
    assert_eq!(pose["marker_size_source"], json!("request"));
}

#[tokio::test]
async fn an_unknown_camera_id_is_422_unknown_camera_in_every_form() {
    let dir = site_dir("unknown");
    let app = spawn_with_site(&dir).await;
    let mut body = corners_request(&warehouse_scene(), 0, "LOC-0001");
    body["camera"] = json!({"id": "roof"});
    let problem =
        assert_problem(app.post_corners(&body).await, 422, ErrorCode::UnknownCamera).await;
    assert_eq!(problem.field.as_deref(), Some("/camera/id"));
    assert!(problem.detail.contains("front, rear"), "{}", problem.detail);
    let response = app
        .post_image(
            "camera_id=roof",
            photo(&warehouse_scene()),
            Some("image/png"),
        )
        .await;
    let problem = assert_problem(response, 422, ErrorCode::UnknownCamera).await;
    assert_eq!(problem.field.as_deref(), Some("camera_id"));
    body["camera"] = json!({"id": "front", "fx_px": 1000});
    assert_problem(
        app.post_corners(&body).await,
        422,
        ErrorCode::IncompleteCamera,
    )
    .await;
}

#[tokio::test]
async fn a_photo_by_camera_id_is_sized_per_code_and_localises_the_robot() {
    let dir = site_dir("photo");
    let app = spawn_with_site(&dir).await;
    let scene = warehouse_scene();
    let response = app
        .post_image("camera_id=front", photo(&scene), Some("image/png"))
        .await;
    assert_eq!(response.status(), StatusCode::OK);
    let body: Value = response.json().await.expect("JSON");
    let markers = body["markers"].as_array().expect("markers");
    assert_eq!(markers.len(), 3, "{body}");
    for m in markers {
        let payload = m["payload"].as_str().expect("decoded");
        let code = scene
            .codes
            .iter()
            .find(|c| c.payload == payload.as_bytes())
            .expect("a placed code");
        let truth_mm = code.pose.transform(&code.marker.centre()).0.coords.norm();
        let distance = m["pose"]["distance_mm"].as_f64().expect("a pose");
        assert!(
            (distance / truth_mm - 1.0).abs() < 0.005,
            "{payload}: {distance} mm, truth {truth_mm} mm"
        );
    }
    let localization = &body["localization"];
    assert_eq!(
        localization["codes"].as_array().map(Vec::len),
        Some(2),
        "{localization}"
    );
    assert_robot_near(
        &localization["robot_pose_in_world"],
        5.0,
        0.3,
        "localization",
    );
}

#[tokio::test]
async fn a_code_the_site_cannot_size_has_a_null_pose_and_its_problem() {
    let dir = site_dir("unsized");
    let text = std::fs::read_to_string(dir.join("warehouse.yaml")).expect("read");
    let without_default = text.replace("  default_size_mm: 50", "");
    std::fs::write(dir.join("warehouse.yaml"), without_default).expect("written");
    let app = spawn_with_site(&dir).await;
    let response = app
        .post_image(
            "camera_id=front",
            photo(&warehouse_scene()),
            Some("image/png"),
        )
        .await;
    assert_eq!(response.status(), StatusCode::OK);
    let body: Value = response.json().await.expect("JSON");
    let sku = body["markers"]
        .as_array()
        .and_then(|ms| ms.iter().find(|m| m["payload"] == json!("SKU-1")))
        .expect("SKU-1 found");
    assert!(sku["pose"].is_null(), "{sku}");
    assert_eq!(sku["problem"]["code"], json!("unknown_marker_size"));
    assert!(sku["corners_px"].is_array());
    let located = body["markers"]
        .as_array()
        .map(|ms| ms.iter().filter(|m| m["pose"].is_object()).count());
    assert_eq!(located, Some(2), "the sized codes keep their poses");
    // The corners endpoint has one code: the request fails.
    let problem = assert_problem(
        app.post_corners(&corners_request(&warehouse_scene(), 2, "SKU-1"))
            .await,
        422,
        ErrorCode::UnknownMarkerSize,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/payload"));
}

#[tokio::test]
async fn a_prior_resolves_the_ambiguity_and_says_so() {
    let dir = site_dir("prior");
    let app = spawn_with_site(&dir).await;
    let scene = warehouse_scene();
    let truth = scene.codes[0].pose.rotation();
    let q = qrpose::geometry::euler::quaternion_wxyz(&truth);
    let mut body = corners_request(&scene, 0, "LOC-0001");
    body["prior"] = json!({"marker_quaternion_wxyz": q, "sigma_deg": 10});
    let pose: Value = app.post_corners(&body).await.json().await.expect("JSON");
    assert_eq!(
        pose["diagnostics"]["ambiguity"]["resolved_by"],
        json!("prior")
    );
    body["prior"] = json!({"robot_quaternion_wxyz": [1, 0, 0, 1], "sigma_deg": 10});
    let pose: Value = app.post_corners(&body).await.json().await.expect("JSON");
    assert_eq!(
        pose["diagnostics"]["ambiguity"]["resolved_by"],
        json!("prior")
    );
    body.as_object_mut().map(|b| b.remove("prior"));
    let pose: Value = app.post_corners(&body).await.json().await.expect("JSON");
    assert_eq!(
        pose["diagnostics"]["ambiguity"]["resolved_by"],
        json!("fit")
    );
    body["prior"] = json!({"robot_quaternion_wxyz": [0, 0, 0, 0], "sigma_deg": 10});
    let problem = assert_problem(app.post_corners(&body).await, 422, ErrorCode::InvalidPrior).await;
    assert_eq!(
        problem.field.as_deref(),
        Some("/prior/robot_quaternion_wxyz")
    );
}

#[tokio::test]
async fn a_bad_reload_keeps_the_old_site_says_why_and_is_counted() {
    let dir = site_dir("reload");
    let app = spawn_with_site(&dir).await;
    let site_file = dir.join("warehouse.yaml");
    let before: Value = app.get("/v1/site").await.json().await.expect("JSON");
    let good = std::fs::read_to_string(&site_file).expect("read");
    std::fs::write(&site_file, good.replace("size_mm: 40", "size_mm: -40")).expect("written");
    let reload = app.request(reqwest::Method::POST, "/v1/site/reload").await;
    let problem = assert_problem(reload, 422, ErrorCode::InvalidSite).await;
    assert!(
        problem.detail.contains("warehouse.yaml:19:"),
        "{}",
        problem.detail
    );
    assert!(problem.detail.contains("positive"), "{}", problem.detail);
    let after: Value = app.get("/v1/site").await.json().await.expect("JSON");
    assert_eq!(after["sha256"], before["sha256"], "the old site stays");
    let metrics = app.get("/metrics").await.text().await.expect("text");
    assert!(
        metrics.contains("qrpose_site_reloads_total{outcome=\"failed\"} 1"),
        "{metrics}"
    );
    std::fs::write(
        &site_file,
        good.replace("default_size_mm: 50", "default_size_mm: 55"),
    )
    .expect("written");
    let reload = app.request(reqwest::Method::POST, "/v1/site/reload").await;
    assert_eq!(reload.status(), StatusCode::OK);
    let reloaded: Value = reload.json().await.expect("JSON");
    assert_ne!(reloaded["sha256"], before["sha256"]);
    assert_eq!(reloaded["markers"]["default_size_mm"], json!(55.0));
    assert_eq!(app.state.metrics.site_reload_count(true), 1);
}
