//! `POST /v1/pose/image`: both input forms against photos rendered at test time with their
//! ground truth, the solver and detector options, metrics, the limits from the settings, and
//! saturation. The bad inputs are in `image_bad_inputs`.

use crate::helpers::{
    BOUNDARY, PHOTO, PHOTO_PAYLOAD, PHOTO_QUERY, assert_problem, image_part, multipart_body,
    occupy_worker, one_worker, photo_jpeg, photo_request, queue_reaches, render_photo,
    request_part, spawn_app, spawn_app_with,
};
use qrpose::api::image::{ImageResponse, MarkerResultDto, PointsDto};
use qrpose::api::problem::ErrorCode;
use qrpose::config::Settings;
use qrpose::detect::Backend;
use qrpose::estimate::Method;
use qrpose_sim::render::{Encoding, Rendered};
use reqwest::{Response, StatusCode, header};
use serde_json::json;

/// Largest corner error allowed against the render's ground truth, px (the detector's own
/// tests hold a single render to 0.35 px).
const CORNER_TOL_PX: f64 = 0.35;
/// Rotation error allowed, degrees.
const ROTATION_TOL_DEG: f64 = 0.5;
/// Position error of the marker centre allowed, mm (at 400 mm).
const POSITION_TOL_MM: f64 = 1.5;

async fn image_response(response: Response) -> ImageResponse {
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()[header::CONTENT_TYPE], "application/json");
    response.json().await.expect("an image response")
}

/// The one marker of `response`, checked against `photo`'s ground truth.
fn assert_matches_truth<'a>(response: &'a ImageResponse, photo: &Rendered) -> &'a MarkerResultDto {
    assert_eq!(
        (response.image.width_px, response.image.height_px),
        (1280, 720)
    );
    assert_eq!(response.markers.len(), 1, "{response:?}");
    let marker = &response.markers[0];
    assert_eq!(marker.payload.as_deref(), Some(PHOTO_PAYLOAD));
    assert!(marker.corners_refined, "{}", marker.refinement);
    for (k, (found, truth)) in marker
        .corners_px
        .iter()
        .zip(&photo.truth.corners_px)
        .enumerate()
    {
        let error_px = (found[0] - truth[0]).hypot(found[1] - truth[1]);
        assert!(error_px < CORNER_TOL_PX, "corner {k}: {error_px} px off");
    }
    let pose = marker.pose.as_ref().expect("a pose");
    let p = &pose.position_mm;
    let t = photo.truth.position_mm;
    let position_error_mm =
        ((p.x - t[0]).powi(2) + (p.y - t[1]).powi(2) + (p.z - t[2]).powi(2)).sqrt();
    assert!(
        position_error_mm < POSITION_TOL_MM,
        "position {position_error_mm} mm off"
    );
    let found = nalgebra::Matrix3::from_fn(|i, j| pose.rotation.matrix[i][j]);
    let truth = nalgebra::Matrix3::from_fn(|i, j| photo.truth.rotation_matrix[i][j]);
    let rotation_error_deg = nalgebra::Rotation3::from_matrix_unchecked(found.transpose() * truth)
        .angle()
        .to_degrees();
    assert!(
        rotation_error_deg < ROTATION_TOL_DEG,
        "rotation {rotation_error_deg}° off"
    );
    marker
}

#[tokio::test]
async fn a_raw_jpeg_body_gives_the_codes_corners_and_pose() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let response = app
        .post_image(PHOTO_QUERY, photo_jpeg(), Some("image/jpeg"))
        .await;

    // Assert
    let body = image_response(response).await;
    let marker = assert_matches_truth(&body, &PHOTO);
    assert_eq!(marker.points_used, PointsDto::Corners);
    let diagnostics = &marker.pose.as_ref().expect("a pose").diagnostics;
    assert_eq!(Method::from(diagnostics.method).as_str(), "reprojection");
    assert!(diagnostics.converged);
    assert!(body.timing_ms.decode > 0.0 && body.timing_ms.detect > 0.0);
}

#[tokio::test]
async fn a_multipart_form_gives_the_same_answer_as_the_raw_body() {
    // Arrange
    let app = spawn_app().await;
    let jpeg = photo_jpeg();
    let request = serde_json::to_vec(&photo_request()).expect("serialisable");
    let raw = image_response(
        app.post_image(PHOTO_QUERY, jpeg.clone(), Some("image/jpeg"))
            .await,
    )
    .await;

    // Act
    let response = app
        .post_image_multipart(multipart_body(&[request_part(&request), image_part(&jpeg)]))
        .await;

    // Assert
    let multipart = image_response(response).await;
    let marker = assert_matches_truth(&multipart, &PHOTO);
    assert_eq!(marker.corners_px, raw.markers[0].corners_px);
    let (a, b) = (
        marker.pose.as_ref().expect("a pose"),
        raw.markers[0].pose.as_ref().expect("a pose"),
    );
    assert_eq!(a.position_mm, b.position_mm);
    assert_eq!(a.rotation, b.rotation);
}

/// Query parameters come with a multipart body too (as a generated client sends
/// them): merged under the `request` part, the part's fields winning.
#[tokio::test]
async fn a_multipart_form_takes_query_parameters_under_its_part() {
    // Arrange
    let app = spawn_app().await;
    let jpeg = photo_jpeg();
    let mut without_camera = photo_request();
    let camera = without_camera
        .as_object_mut()
        .and_then(|m| m.remove("camera"))
        .expect("the photo request has a camera");
    let part = serde_json::to_vec(&without_camera).expect("serialisable");
    let camera_query: String = ["fx_px", "fy_px", "cx_px", "cy_px"]
        .iter()
        .map(|k| format!("{k}={}", camera[*k]))
        .collect::<Vec<_>>()
        .join("&");
    let body = multipart_body(&[request_part(&part), image_part(&jpeg)]);
    let content_type = format!("multipart/form-data; boundary={BOUNDARY}");

    // Act
    let camera_from_query = app
        .post_image(&camera_query, body, Some(&content_type))
        .await;
    let both = app
        .post_image(
            &format!("{PHOTO_QUERY}&effort=thorough&method=paper"),
            multipart_body(&[
                request_part(&serde_json::to_vec(&photo_request()).expect("json")),
                image_part(&jpeg),
            ]),
            Some(&content_type),
        )
        .await;

    // Assert
    let answer = image_response(camera_from_query).await;
    assert_matches_truth(&answer, &PHOTO);
    let answer = image_response(both).await;
    let pose = answer.markers[0].pose.as_ref().expect("a pose");
    assert_eq!(
        serde_json::to_value(pose.diagnostics.method).expect("json"),
        "paper",
        "a field only the query gives is the query's"
    );
}

#[tokio::test]
async fn a_multipart_form_from_a_client_library_is_read() {
    // Arrange: reqwest writes its own boundary, part headers and file name.
    let app = spawn_app().await;
    let form = reqwest::multipart::Form::new()
        .part(
            "image",
            reqwest::multipart::Part::bytes(photo_jpeg())
                .file_name("photo.jpg")
                .mime_str("image/jpeg")
                .expect("a media type"),
        )
        .text("request", photo_request().to_string());

    // Act
    let response = app
        .client
        .post(format!("{}/v1/pose/image", app.address))
        .multipart(form)
        .send()
        .await
        .expect("the server answers");

    // Assert
    let body = image_response(response).await;
    assert_matches_truth(&body, &PHOTO);
}

#[tokio::test]
async fn a_png_body_is_read_like_a_jpeg() {
    // Arrange
    let app = spawn_app().await;
    let png = render_photo(Encoding::Png, [-30.0, 15.0, 400.0]);

    // Act
    let response = app
        .post_image(PHOTO_QUERY, png.encoded.clone(), Some("image/png"))
        .await;

    // Assert
    let body = image_response(response).await;
    assert_matches_truth(&body, &png);
}

#[tokio::test]
async fn an_image_without_a_code_is_a_200_with_no_markers() {
    // Arrange
    let app = spawn_app().await;
    let blank =
        qrpose::detect::decode::GrayImage::new(320, 240, vec![180; 320 * 240]).expect("a size");
    let jpeg = qrpose_sim::render::encode(&blank, Encoding::Jpeg(90)).expect("encodes");

    // Act
    let response = app.post_image(PHOTO_QUERY, jpeg, Some("image/jpeg")).await;

    // Assert
    let body = image_response(response).await;
    assert!(body.markers.is_empty(), "{body:?}");
    assert_eq!((body.image.width_px, body.image.height_px), (320, 240));
}

#[tokio::test]
async fn query_parameters_choose_the_solver_and_the_points() {
    // Arrange
    let app = spawn_app().await;
    let cases = [
        (
            "method=paper&gain=1.2&trace=true",
            "paper",
            PointsDto::Corners,
        ),
        ("method=depth-newton", "depth-newton", PointsDto::Corners),
        ("points=finders", "reprojection", PointsDto::Finders),
    ];

    for (extra, method, points) in cases {
        // Act
        let query = format!("{PHOTO_QUERY}&{extra}");
        let response = app
            .post_image(&query, photo_jpeg(), Some("image/jpeg"))
            .await;

        // Assert
        let body = image_response(response).await;
        let marker = &body.markers[0];
        assert_eq!(marker.points_used, points, "{extra}");
        let diagnostics = &marker.pose.as_ref().expect("a pose").diagnostics;
        assert_eq!(Method::from(diagnostics.method).as_str(), method, "{extra}");
        assert_eq!(
            diagnostics.trace.is_some(),
            extra.contains("trace=true"),
            "{extra}"
        );
    }
}

#[tokio::test]
async fn the_request_part_chooses_the_detector() {
    // Arrange
    let app = spawn_app().await;
    let mut request = photo_request();
    request["detector"] = json!("rqrr");
    let request = serde_json::to_vec(&request).expect("serialisable");
    let jpeg = photo_jpeg();

    // Act
    let response = app
        .post_image_multipart(multipart_body(&[image_part(&jpeg), request_part(&request)]))
        .await;

    // Assert
    let body = image_response(response).await;
    let marker = assert_matches_truth(&body, &PHOTO);
    assert_eq!(marker.detector, "rqrr");
}

#[tokio::test]
async fn zxing_cpp_is_used_when_built_and_refused_otherwise() {
    // Arrange
    let app = spawn_app().await;
    let query = format!("{PHOTO_QUERY}&detector=zxing-cpp");

    // Act
    let response = app
        .post_image(&query, photo_jpeg(), Some("image/jpeg"))
        .await;

    // Assert
    if Backend::ZxingCpp.is_built() {
        let body = image_response(response).await;
        assert_eq!(body.markers[0].detector, "zxing-cpp");
    } else {
        let problem = assert_problem(response, 422, ErrorCode::DetectorUnavailable).await;
        assert_eq!(problem.field.as_deref(), Some("detector"));
    }
}

#[tokio::test]
async fn a_code_whose_pose_cannot_be_computed_carries_its_own_problem() {
    // Arrange: the code near the right edge, and a distortion so strong that its corners
    // cannot be undistorted.
    let app = spawn_app().await;
    let photo = render_photo(Encoding::Jpeg(90), [190.0, 0.0, 400.0]);
    let query = format!("{PHOTO_QUERY}&k1=-2.0");

    // Act
    let response = app
        .post_image(&query, photo.encoded.clone(), Some("image/jpeg"))
        .await;

    // Assert
    let body = image_response(response).await;
    assert_eq!(body.markers.len(), 1, "{body:?}");
    let marker = &body.markers[0];
    assert_eq!(marker.payload.as_deref(), Some(PHOTO_PAYLOAD));
    assert!(marker.pose.is_none());
    let problem = marker.problem.as_ref().expect("the marker's problem");
    assert_eq!(problem.code, ErrorCode::UndistortionFailed, "{problem:?}");
}

#[tokio::test]
async fn metrics_count_codes_per_image_and_each_markers_estimate() {
    // Arrange
    let app = spawn_app().await;
    let blank = qrpose_sim::render::encode(
        &qrpose::detect::decode::GrayImage::new(64, 48, vec![200; 64 * 48]).expect("a size"),
        Encoding::Jpeg(90),
    )
    .expect("encodes");
    let paper = format!("{PHOTO_QUERY}&method=paper");
    for (query, body) in [
        (PHOTO_QUERY, photo_jpeg()),
        (paper.as_str(), photo_jpeg()),
        (PHOTO_QUERY, blank),
    ] {
        let status = app
            .post_image(query, body, Some("image/jpeg"))
            .await
            .status();
        assert_eq!(status, StatusCode::OK);
    }
    let status = app
        .post_image(PHOTO_QUERY, b"no image".to_vec(), Some("image/jpeg"))
        .await
        .status();
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);

    // Act
    let text = app.get("/metrics").await.text().await.expect("text");

    // Assert
    for line in [
        r#"qrpose_http_requests_total{route="/v1/pose/image",method="POST",status="200"} 3"#,
        r#"qrpose_http_requests_total{route="/v1/pose/image",method="POST",status="422"} 1"#,
        r#"qrpose_image_codes_detected_bucket{le="0.0"} 1"#,
        r#"qrpose_image_codes_detected_bucket{le="1.0"} 3"#,
        "qrpose_image_codes_detected_count 3",
        r#"qrpose_estimator_iterations_count{method="reprojection"} 1"#,
        r#"qrpose_estimator_iterations_count{method="paper"} 1"#,
    ] {
        assert!(text.contains(line), "missing `{line}` in\n{text}");
    }
}

#[tokio::test]
async fn the_pixel_limit_comes_from_the_settings() {
    // Arrange: one pixel less than the 1280x720 photo.
    let app = spawn_app_with(Settings {
        max_image_pixels: 1280 * 720 - 1,
        ..Settings::default()
    })
    .await;

    // Act
    let response = app
        .post_image(PHOTO_QUERY, photo_jpeg(), Some("image/jpeg"))
        .await;

    // Assert
    let problem = assert_problem(response, 413, ErrorCode::ImageTooLarge).await;
    assert!(problem.detail.contains("1280 × 720"), "{}", problem.detail);
    app.assert_up("an image over the pixel limit").await;
}

#[tokio::test]
async fn the_body_limit_holds_for_both_forms() {
    // Arrange
    let limit = 16 * 1024;
    let app = spawn_app_with(Settings {
        body_limit_bytes: limit,
        ..Settings::default()
    })
    .await;
    let jpeg = photo_jpeg();
    assert!(jpeg.len() > limit);
    let request = serde_json::to_vec(&photo_request()).expect("serialisable");

    // Act
    let raw = app
        .post_image(PHOTO_QUERY, jpeg.clone(), Some("image/jpeg"))
        .await;
    let multipart = app
        .post_image_multipart(multipart_body(&[image_part(&jpeg), request_part(&request)]))
        .await;

    // Assert
    for response in [raw, multipart] {
        let problem = assert_problem(response, 413, ErrorCode::PayloadTooLarge).await;
        assert!(problem.detail.contains(&format!("{limit} bytes")));
    }
    app.assert_up("oversized images").await;
}

#[tokio::test]
async fn image_requests_share_the_bounded_queue() {
    // Arrange: one worker, busy, and no waiting place.
    let app = spawn_app_with(one_worker(0)).await;
    let gate = occupy_worker(&app).await;

    // Act
    let response = app
        .post_image(PHOTO_QUERY, photo_jpeg(), Some("image/jpeg"))
        .await;

    // Assert
    assert_eq!(response.headers()[header::RETRY_AFTER], "1");
    assert_problem(response, 503, ErrorCode::Overloaded).await;
    gate.release().await;
    queue_reaches(&app, 0, 0).await;
    let response = app
        .post_image(PHOTO_QUERY, photo_jpeg(), Some("image/jpeg"))
        .await;
    assert_eq!(response.status(), StatusCode::OK);
}

/// A fisheye camera goes in the query as in the JSON form (`distortion_model`, k1-k4): a
/// photo taken through one, sent as the raw body, gives the code at its true distance; the
/// same query without the lens does not.
#[tokio::test]
async fn a_fisheye_camera_comes_through_the_query_parameters() {
    // Arrange: a 60 mm code 250 mm away, seen through the fisheye of docs/calibration.md.
    let dir = std::env::temp_dir().join(format!("qrpose-fisheye-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    let path = dir.join("fisheye.png");
    let args = [
        "--out",
        path.to_str().expect("utf-8"),
        "--width-px",
        "848",
        "--height-px",
        "800",
        "--fx-px",
        "285.72",
        "--fy-px",
        "285.93",
        "--cx-px",
        "423.08",
        "--cy-px",
        "401.44",
        "--distortion-model",
        "equidistant",
        "--distortion-coefficients=-0.00566,0.04186,-0.03869,0.00673",
        "--x-mm",
        "60",
        "--z-mm",
        "250",
        "--beta-deg",
        "20",
        "--marker-size-mm",
        "60",
    ]
    .map(std::ffi::OsStr::new);
    let truth = qrpose_sim::cli::render(&args).expect("renders");
    let photo = std::fs::read(&path).expect("the photo");
    let camera = "fx_px=285.72&fy_px=285.93&cx_px=423.08&cy_px=401.44&marker_size_mm=60";
    let lens = "distortion_model=equidistant&k1=-0.00566&k2=0.04186&k3=-0.03869&k4=0.00673";
    let app = spawn_app().await;

    // Act
    let through = app
        .post_image(
            &format!("{camera}&{lens}"),
            photo.clone(),
            Some("image/png"),
        )
        .await;
    let pinhole = app.post_image(camera, photo, Some("image/png")).await;

    // Assert
    let z = |body: &ImageResponse| {
        let pose = body.markers[0].pose.as_ref().expect("a pose");
        pose.position_mm.z
    };
    let true_z = truth["truth"]["position_mm"][2]
        .as_f64()
        .expect("the true depth");
    let through = image_response(through).await;
    assert!(
        (z(&through) - true_z).abs() < 2.0,
        "{} vs {true_z}",
        z(&through)
    );
    let pinhole = image_response(pinhole).await;
    if let Some(marker) = pinhole.markers.first().and_then(|m| m.pose.as_ref()) {
        assert!(
            (marker.position_mm.z - true_z).abs() > 5.0,
            "the lens matters"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
