//! `POST /v1/calibrate`: rendered photos of a printed code with a known camera give that
//! camera, with the names of the spec (camera, std, reprojection_rms_px, views, warnings,
//! opencv_yaml, ros_camera_info_yaml), every view's points with their residuals, and files
//! the site's reader takes as they are; and every refusal as its problem: too few photos or
//! usable views, too many photos, photos of different sizes, no code anywhere, an
//! undecodable photo, a missing or unknown part, an unknown lens model, a body that is not
//! multipart.

#[path = "../support/calibration.rs"]
mod photos;

use crate::helpers::{
    BOUNDARY, Part, TestApp, assert_problem, image_part, multipart_body, request_part, spawn_app,
};
use qrpose::api::problem::ErrorCode;
use qrpose_site::calibration::parse_calibration;
use reqwest::Response;
use serde_json::{Value, json};
use std::sync::LazyLock;

/// The rendered photos, once for every test of this module.
static PHOTOS: LazyLock<Vec<Vec<u8>>> = LazyLock::new(photos::photos);

/// A PNG of `w` × `h` light pixels: no code in it.
fn blank_png(w: u32, h: u32) -> Vec<u8> {
    let image = image::GrayImage::from_pixel(w, h, image::Luma([230u8]));
    let mut out = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .expect("a PNG encodes");
    out
}

fn request() -> Vec<u8> {
    serde_json::to_vec(&json!({"marker": {"size_mm": photos::CODE_MM}, "model": "plumb_bob"}))
        .expect("JSON")
}

/// `POST /v1/calibrate` with the `request` part `request` and one `image` part per photo.
async fn calibrate(app: &TestApp, request: &[u8], photos: &[&[u8]]) -> Response {
    let mut parts = vec![request_part(request)];
    parts.extend(photos.iter().map(|p| image_part(p)));
    post(app, multipart_body(&parts)).await
}

async fn post(app: &TestApp, body: Vec<u8>) -> Response {
    app.client
        .post(format!("{}/v1/calibrate", app.address))
        .header(
            "content-type",
            format!("multipart/form-data; boundary={BOUNDARY}"),
        )
        .body(body)
        .send()
        .await
        .expect("the server answers")
}

/// A used view's `image_points`: one per point, inside the image, each with its residual
/// and weight, the residuals' RMS length the view's `rms_px`.
fn assert_points_drawable(view: &Value, (width, height): (f64, f64)) {
    let points = view["image_points"].as_array().expect("image_points");
    assert_eq!(Some(points.len() as u64), view["points"].as_u64(), "{view}");
    let pair = |p: &Value| -> [f64; 2] {
        let xy = p.as_array().expect("a pair");
        assert_eq!(xy.len(), 2, "{p}");
        [xy[0].as_f64().expect("u"), xy[1].as_f64().expect("v")]
    };
    let mut squares = 0.0;
    for point in points {
        let [u, v] = pair(&point["image_px"]);
        assert!(
            (-0.5..width).contains(&u) && (-0.5..height).contains(&v),
            "{point}"
        );
        let [du, dv] = pair(&point["residual_px"]);
        squares += du * du + dv * dv;
        let weight = point["weight"].as_f64().expect("a weight");
        assert!(weight > 0.0 && weight <= 1.0, "{point}");
    }
    let rms = (squares / points.len() as f64).sqrt();
    let reported = view["rms_px"].as_f64().expect("rms_px");
    assert!(
        (rms - reported).abs() < 1e-9 * reported.max(1.0),
        "{rms} against {reported}"
    );
}

#[tokio::test]
async fn photos_of_a_printed_code_give_its_camera() {
    let app = spawn_app().await;
    let photos: Vec<&[u8]> = PHOTOS.iter().map(Vec::as_slice).collect();
    let response = calibrate(&app, &request(), &photos).await;
    assert_eq!(response.status(), 200);
    let body: Value = response.json().await.expect("JSON");
    let truth = photos::camera();
    let camera = &body["camera"];
    let got = |key: &str| camera[key].as_f64().expect("a number");
    assert!((got("fx_px") / truth.fx() - 1.0).abs() < 0.002, "{camera}");
    assert!((got("fy_px") / truth.fy() - 1.0).abs() < 0.002, "{camera}");
    assert!((got("cx_px") - truth.cx()).abs() < 1.5, "{camera}");
    assert!((got("cy_px") - truth.cy()).abs() < 1.5, "{camera}");
    assert_eq!(camera["distortion"]["model"], "plumb_bob");
    for name in ["k1", "k2", "p1", "p2", "k3"] {
        assert!(camera["distortion"][name].is_f64(), "{name}: {camera}");
    }
    // Every parameter has its standard deviation, small against the truth's tolerance.
    let std = &body["std"];
    for key in ["fx_px", "fy_px", "cx_px", "cy_px"] {
        let s = std[key].as_f64().expect("a finite std");
        assert!(s > 0.0 && s < 1.0, "std {key} {s}");
    }
    let names: Vec<&String> = std["distortion"]
        .as_object()
        .expect("named")
        .keys()
        .collect();
    assert_eq!(names, ["k1", "k2", "k3", "p1", "p2"]);
    let rms = body["reprojection_rms_px"].as_f64().expect("rms");
    assert!(rms > 0.0 && rms < 0.2, "rms {rms}");
    let views = body["views"].as_array().expect("views");
    assert_eq!(views.len(), photos.len());
    for (k, v) in views.iter().enumerate() {
        assert_eq!(v["index"], k);
        assert_eq!(v["used"], true, "{v}");
        assert!(v["points"].as_u64().is_some_and(|n| n > 100), "{v}");
        assert!(v["rms_px"].as_f64().is_some_and(|r| r < 0.3), "{v}");
        assert_points_drawable(v, (640.0, 480.0));
    }
    assert!(body["warnings"].is_array());
    assert_eq!(body["image"], json!({"width_px": 640, "height_px": 480}));
    // The files are read by the site's reader as they are, as the same camera.
    for key in ["opencv_yaml", "ros_camera_info_yaml"] {
        let text = body[key].as_str().expect("a file");
        let read = parse_calibration(text).expect("the site reads it");
        assert_eq!(
            [
                read.camera.fx(),
                read.camera.fy(),
                read.camera.cx(),
                read.camera.cy()
            ],
            [got("fx_px"), got("fy_px"), got("cx_px"), got("cy_px")],
            "{key}"
        );
        assert_eq!(read.image_size_px, Some((640, 480)), "{key}");
    }
    // The camera is a pose request's camera as it is.
    let corners = app
        .post_corners(&json!({
            "corners_px": [[300, 200], [360, 202], [358, 262], [298, 260]],
            "camera": camera,
            "marker": {"size_mm": 100},
        }))
        .await;
    let status = corners.status();
    let answer: Value = corners.json().await.expect("JSON");
    assert_eq!(status, 200, "{answer}");
}

#[tokio::test]
async fn a_photo_without_a_code_is_reported_and_too_few_views_are_refused() {
    let app = spawn_app().await;
    let blank = blank_png(640, 480);
    let photos = [PHOTOS[0].as_slice(), blank.as_slice(), PHOTOS[1].as_slice()];
    let problem = assert_problem(
        calibrate(&app, &request(), &photos).await,
        422,
        ErrorCode::TooFewViews,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("image"));
    assert!(
        problem.detail.contains("without a code: 1"),
        "{}",
        problem.detail
    );
    let two = [PHOTOS[0].as_slice(), PHOTOS[1].as_slice()];
    let problem = assert_problem(
        calibrate(&app, &request(), &two).await,
        422,
        ErrorCode::TooFewViews,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("image"));
}

#[tokio::test]
async fn photos_that_cannot_calibrate_are_refused_with_their_problem() {
    let app = spawn_app().await;
    let tiny = b"x".to_vec();
    let many: Vec<&[u8]> = vec![tiny.as_slice(); 101];
    assert_problem(
        calibrate(&app, &request(), &many).await,
        422,
        ErrorCode::TooManyImages,
    )
    .await;
    let blank = blank_png(640, 480);
    let small = blank_png(320, 240);
    let mixed = [blank.as_slice(), small.as_slice(), blank.as_slice()];
    let problem = assert_problem(
        calibrate(&app, &request(), &mixed).await,
        422,
        ErrorCode::MixedImageSizes,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("image/1"));
    let blanks = [blank.as_slice(); 3];
    assert_problem(
        calibrate(&app, &request(), &blanks).await,
        422,
        ErrorCode::NoCodeFound,
    )
    .await;
    let broken = [blank.as_slice(), blank.as_slice(), tiny.as_slice()];
    let problem = assert_problem(
        calibrate(&app, &request(), &broken).await,
        422,
        ErrorCode::UndecodableImage,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("image/2"));
}

#[tokio::test]
async fn a_malformed_request_is_refused_before_any_photo_is_read() {
    let app = spawn_app().await;
    let blank = blank_png(64, 48);
    let photos = [blank.as_slice(); 3];
    let bad_model =
        serde_json::to_vec(&json!({"marker": {"size_mm": 100}, "model": "fisheye"})).expect("JSON");
    let problem = assert_problem(
        calibrate(&app, &bad_model, &photos).await,
        422,
        ErrorCode::UnknownVariant,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/model"));
    let bad_size = serde_json::to_vec(&json!({"marker": {"size_mm": -5}})).expect("JSON");
    let problem = assert_problem(
        calibrate(&app, &bad_size, &photos).await,
        422,
        ErrorCode::InvalidMarkerSize,
    )
    .await;
    assert_eq!(problem.field.as_deref(), Some("/marker/size_mm"));
    // No `request` part; no `image` part; a part of another name.
    let only_photos = multipart_body(&[image_part(&blank), image_part(&blank)]);
    let problem = assert_problem(post(&app, only_photos).await, 422, ErrorCode::MissingField).await;
    assert_eq!(problem.field.as_deref(), Some("request"));
    let only_request = multipart_body(&[request_part(&request())]);
    let problem =
        assert_problem(post(&app, only_request).await, 422, ErrorCode::MissingField).await;
    assert_eq!(problem.field.as_deref(), Some("image"));
    let other = multipart_body(&[
        request_part(&request()),
        Part {
            name: Some("photo"),
            content_type: "image/png",
            bytes: &blank,
        },
    ]);
    let problem = assert_problem(post(&app, other).await, 422, ErrorCode::UnknownField).await;
    assert_eq!(problem.field.as_deref(), Some("photo"));
    // Not multipart at all.
    let raw = app
        .client
        .post(format!("{}/v1/calibrate", app.address))
        .header("content-type", "image/png")
        .body(blank.clone())
        .send()
        .await
        .expect("the server answers");
    assert_problem(raw, 415, ErrorCode::UnsupportedMediaType).await;
}
