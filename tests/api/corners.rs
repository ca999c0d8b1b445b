//! `POST /v1/pose/corners`: answers for valid requests.

use crate::helpers::{spawn_app, valid_request};
use qrpose::api::{
    estimate_corners, problem::parse_json, request::CornersRequest, response::PoseResponse,
};
use qrpose::estimate::Method;
use reqwest::{StatusCode, header};
use serde_json::{Value, json};

#[tokio::test]
async fn returns_the_pose_of_a_valid_request() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let response = app.post_corners(&valid_request()).await;

    // Assert
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()[header::CONTENT_TYPE], "application/json");
    let pose: PoseResponse = response.json().await.expect("a pose");
    assert_eq!(
        Method::from(pose.diagnostics.method).as_str(),
        "reprojection"
    );
    assert!(pose.diagnostics.converged);
    assert!(
        (pose.position_mm.z - 498.0).abs() < 5.0,
        "depth {} mm, expected about 498 mm",
        pose.position_mm.z
    );
    assert_eq!(pose.corners_mm.len(), 4);
}

#[tokio::test]
async fn answers_exactly_what_the_cli_estimate_prints() {
    // Arrange
    let app = spawn_app().await;
    let bytes = serde_json::to_vec(&valid_request()).expect("serialisable");
    let expected = parse_json::<CornersRequest>(&bytes)
        .and_then(|r| estimate_corners(&r, None))
        .expect("a pose");

    // Act
    let mut http: Value = app
        .post_corners_raw(bytes, Some("application/json"))
        .await
        .json()
        .await
        .expect("JSON");

    // Assert: everything but the timing is equal, field for field.
    // Both sides go through JSON text, as the CLI's output does.
    let cli_text = serde_json::to_vec(&expected).expect("serialisable");
    let mut cli: Value = serde_json::from_slice(&cli_text).expect("JSON");
    for v in [&mut http, &mut cli] {
        v["diagnostics"]["elapsed_us"] = Value::Null;
    }
    assert_eq!(http, cli);
}

#[tokio::test]
async fn every_method_and_input_form_is_accepted() {
    // Arrange
    let app = spawn_app().await;
    let mut paper = valid_request();
    paper["solver"] = json!({"method": "paper", "trace": true});
    let mut newton = valid_request();
    newton["solver"] = json!({"method": "depth-newton"});
    let mut paper_order = valid_request();
    paper_order["corner_order"] = json!("paper");
    paper_order["corners_px"] = json!([
        [688.1, 411.6],
        [689.9, 311.4],
        [589.2, 309.8],
        [588.0, 409.5]
    ]);
    let mut sensor = valid_request();
    sensor["camera"] =
        json!({"focal_length_mm": 4.0, "pixel_size_um": 4.0, "cx_px": 639.5, "cy_px": 359.5});
    let mut image_plane = valid_request();
    image_plane
        .as_object_mut()
        .expect("object")
        .remove("corners_px");
    image_plane["corners_mm"] = json!([
        [-0.2012, -0.1988],
        [0.2016, -0.1924],
        [0.1944, 0.2084],
        [-0.206, 0.2]
    ]);
    image_plane["camera"] = json!({"focal_length_mm": 4.0});
    let cases = [
        ("paper with trace", paper, "paper"),
        ("depth-newton", newton, "depth-newton"),
        ("paper corner order", paper_order, "reprojection"),
        ("sensor camera", sensor, "reprojection"),
        ("image-plane mm corners", image_plane, "reprojection"),
    ];

    for (name, body, method) in cases {
        // Act
        let response = app.post_corners(&body).await;

        // Assert
        assert_eq!(response.status(), StatusCode::OK, "{name}");
        let pose: Value = response.json().await.expect("JSON");
        assert_eq!(pose["diagnostics"]["method"], method, "{name}");
        let z = pose["position_mm"]["z"].as_f64().expect("a depth");
        assert!((z - 498.0).abs() < 5.0, "{name}: depth {z} mm");
    }
}

#[tokio::test]
async fn paper_method_trace_lists_every_iteration() {
    // Arrange
    let app = spawn_app().await;
    let mut body = valid_request();
    body["solver"] = json!({"method": "paper", "trace": true});

    // Act
    let pose: Value = app.post_corners(&body).await.json().await.expect("JSON");

    // Assert
    let iterations = pose["diagnostics"]["iterations"]
        .as_u64()
        .expect("iterations");
    let trace = pose["diagnostics"]["trace"].as_array().expect("a trace");
    assert_eq!(trace.len() as u64, iterations);
}

#[tokio::test]
async fn non_convergence_is_a_200_with_converged_false() {
    // Arrange
    let app = spawn_app().await;
    let mut body = valid_request();
    body["solver"] = json!({"method": "paper", "max_iterations": 1});

    // Act
    let response = app.post_corners(&body).await;

    // Assert
    assert_eq!(response.status(), StatusCode::OK);
    let pose: Value = response.json().await.expect("JSON");
    assert_eq!(pose["diagnostics"]["converged"], false);
    assert_eq!(pose["diagnostics"]["iterations"], 1);
    assert!(
        pose["diagnostics"]["warnings"]
            .as_array()
            .expect("warnings")
            .contains(&json!("not_converged"))
    );
}

#[tokio::test]
async fn accepts_json_media_types_with_parameters() {
    // Arrange
    let app = spawn_app().await;
    let body = serde_json::to_vec(&valid_request()).expect("serialisable");

    for content_type in ["application/json; charset=utf-8", "APPLICATION/JSON"] {
        // Act
        let response = app.post_corners_raw(body.clone(), Some(content_type)).await;

        // Assert
        assert_eq!(response.status(), StatusCode::OK, "{content_type}");
    }
}
