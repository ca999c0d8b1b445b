//! `POST /v1/pose/image/annotated` and `qrpose estimate --annotate` against the real binary,
//! checked pixel by pixel on the PNG variant: the corner marks sit within 1 px of the
//! refined corners of the JSON in `X-Qrpose-Result`, and each axis ends where the pose
//! projects it. The JPEG variant decodes at the photo's size. Errors are the problems of
//! `POST /v1/pose/image`.

use crate::support::{MARKER_SIZE_MM, PHOTO_QUERY, Server, client, render_photo, scratch_dir};
use base64::Engine;
use image::RgbImage;
use nalgebra::{Point3, Vector3};
use qrpose::api::image::ImageResponse;
use qrpose::geometry::camera::Camera;
use qrpose::geometry::frames::CameraPoint;
use reqwest::blocking::Response;
use reqwest::{StatusCode, header};
use serde_json::Value;
use std::path::Path;

/// How far a drawn feature may sit from where the JSON puts it, px (the bound).
const TOLERANCE_PX: f64 = 1.0;
/// Half the window searched for a corner's mark, px (marks are at most 11 px across at
/// 720 p, corners over 100 px apart).
const MARK_WINDOW_PX: i64 = 9;
const CORNER_MARK: [u8; 3] = [255, 0, 255];
const AXIS_COLOURS: [[u8; 3]; 3] = [[255, 0, 0], [0, 255, 0], [0, 0, 255]];

fn camera() -> Camera {
    Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a camera")
}

/// A tilted code 400 mm away (every axis visibly long), as `qrpose render` draws it.
fn photo(name: &str) -> (Vec<u8>, Value) {
    let dir = scratch_dir("annotated");
    let (path, truth) = render_photo(
        &dir,
        name,
        &[
            "--x-mm",
            "15",
            "--z-mm",
            "400",
            "--alpha-deg",
            "25",
            "--beta-deg",
            "-20",
        ],
    );
    (std::fs::read(path).expect("the photo"), truth)
}

fn post_annotated(server: &Server, photo: &[u8], query: &str, accept: Option<&str>) -> Response {
    let mut request = client()
        .post(server.url(&format!("/v1/pose/image/annotated?{query}")))
        .header(header::CONTENT_TYPE, "image/jpeg")
        .body(photo.to_vec());
    if let Some(accept) = accept {
        request = request.header(header::ACCEPT, accept);
    }
    request.send().expect("the server answers")
}

/// The JSON of the result header.
fn result_of(response: &Response) -> ImageResponse {
    let header = response
        .headers()
        .get("x-qrpose-result")
        .expect("an X-Qrpose-Result header");
    let json = base64::engine::general_purpose::URL_SAFE_NO_PAD
        .decode(header.as_bytes())
        .expect("base64url without padding");
    serde_json::from_slice(&json).expect("an image response")
}

fn decode(bytes: &[u8]) -> RgbImage {
    image::load_from_memory(bytes)
        .expect("an image")
        .into_rgb8()
}

/// Pixels of exactly `colour`, as (x, y).
fn pixels_of(image: &RgbImage, colour: [u8; 3]) -> Vec<[f64; 2]> {
    image
        .enumerate_pixels()
        .filter(|(_, _, p)| p.0 == colour)
        .map(|(x, y, _)| [f64::from(x), f64::from(y)])
        .collect()
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn assert_corner_marks_on_corners(image: &RgbImage, result: &ImageResponse) {
    let marks = pixels_of(image, CORNER_MARK);
    assert!(!marks.is_empty(), "no corner mark drawn");
    assert_marks_centred_on(&marks, &result.markers[0].corners_px, 1);
}

/// Every corner has at least `min_pixels` of `marks` within the mark's window, centred
/// within [`TOLERANCE_PX`] of it, and no mark pixel lies away from every corner.
fn assert_marks_centred_on(marks: &[[f64; 2]], corners: &[[f64; 2]], min_pixels: usize) {
    let window = MARK_WINDOW_PX as f64;
    for (k, corner) in corners.iter().enumerate() {
        let near: Vec<_> = marks
            .iter()
            .filter(|m| (m[0] - corner[0]).abs() <= window && (m[1] - corner[1]).abs() <= window)
            .collect();
        assert!(
            near.len() >= min_pixels,
            "corner {k}: {} mark pixels near {corner:?}",
            near.len()
        );
        let n = near.len() as f64;
        let centre = [
            near.iter().map(|m| m[0]).sum::<f64>() / n,
            near.iter().map(|m| m[1]).sum::<f64>() / n,
        ];
        let error_px = distance(centre, *corner);
        assert!(
            error_px <= TOLERANCE_PX,
            "corner {k}: mark centred at {centre:?}, {error_px:.2} px from {corner:?}"
        );
    }
    let stray = marks.iter().filter(|m| {
        corners
            .iter()
            .all(|c| (m[0] - c[0]).abs() > window || (m[1] - c[1]).abs() > window)
    });
    assert_eq!(
        stray.count(),
        0,
        "corner-mark pixels away from every corner"
    );
}

/// The pose's axes projected independently of the service: from `position_mm` along the
/// columns of R, each the known marker side long.
fn expected_axes(result: &ImageResponse) -> ([f64; 2], [[f64; 2]; 3]) {
    let pose = result.markers[0].pose.as_ref().expect("a pose");
    let p = &pose.position_mm;
    let centre = Point3::new(p.x, p.y, p.z);
    let r = pose.rotation.matrix;
    let project = |q: Point3<f64>| {
        let px = camera().project(&CameraPoint(q)).expect("in front");
        [px.u(), px.v()]
    };
    let ends = [0, 1, 2].map(|axis| {
        let direction = Vector3::new(r[0][axis], r[1][axis], r[2][axis]);
        project(centre + direction * MARKER_SIZE_MM)
    });
    (project(centre), ends)
}

fn assert_axes_end_where_the_pose_says(image: &RgbImage, result: &ImageResponse) {
    let (origin, ends) = expected_axes(result);
    for (axis, (colour, end)) in AXIS_COLOURS.iter().zip(ends).enumerate() {
        let pixels = pixels_of(image, *colour);
        assert!(!pixels.is_empty(), "axis {axis}: nothing drawn");
        let length = distance(origin, end);
        let direction = [(end[0] - origin[0]) / length, (end[1] - origin[1]) / length];
        let along =
            |p: &[f64; 2]| (p[0] - origin[0]) * direction[0] + (p[1] - origin[1]) * direction[1];
        let across = |p: &[f64; 2]| {
            ((p[0] - origin[0]) * direction[1] - (p[1] - origin[1]) * direction[0]).abs()
        };
        let reach = pixels.iter().map(along).fold(f64::NEG_INFINITY, f64::max);
        assert!(
            (reach - length).abs() <= TOLERANCE_PX,
            "axis {axis}: drawn to {reach:.2} px from the centre, the pose says {length:.2} px"
        );
        let widest = pixels.iter().map(across).fold(0.0, f64::max);
        assert!(
            widest <= 3.0,
            "axis {axis}: a pixel {widest:.2} px off its line"
        );
    }
}

#[test]
fn the_png_variant_draws_corner_marks_and_axes_where_the_json_says() {
    let server = Server::start();
    let (photo, truth) = photo("tilted.jpg");

    let response = post_annotated(&server, &photo, PHOTO_QUERY, Some("image/png"));

    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()[header::CONTENT_TYPE], "image/png");
    assert_eq!(response.headers()["x-qrpose-markers"], "1");
    let result = result_of(&response);
    assert_eq!(result.markers.len(), 1, "{result:?}");
    assert_eq!(
        result.markers[0].payload.as_deref(),
        Some(crate::support::PAYLOAD)
    );
    let truth_corners = truth["truth"]["corners_px"].as_array().expect("corners");
    for (found, truth) in result.markers[0].corners_px.iter().zip(truth_corners) {
        let truth = [truth[0].as_f64().expect("u"), truth[1].as_f64().expect("v")];
        assert!(distance(*found, truth) < 0.5, "{found:?} against {truth:?}");
    }
    let image = decode(&response.bytes().expect("a body"));
    assert_eq!(image.dimensions(), (1280, 720));
    assert_corner_marks_on_corners(&image, &result);
    assert_axes_end_where_the_pose_says(&image, &result);
}

#[test]
fn the_default_is_a_jpeg_of_the_photos_size_with_the_same_json_as_the_plain_route() {
    let server = Server::start();
    let (photo, _) = photo("default.jpg");

    let annotated = post_annotated(&server, &photo, PHOTO_QUERY, None);
    let plain: ImageResponse = client()
        .post(server.url(&format!("/v1/pose/image?{PHOTO_QUERY}")))
        .header(header::CONTENT_TYPE, "image/jpeg")
        .body(photo.clone())
        .send()
        .expect("the server answers")
        .json()
        .expect("JSON");

    assert_eq!(annotated.status(), StatusCode::OK);
    assert_eq!(annotated.headers()[header::CONTENT_TYPE], "image/jpeg");
    let result = result_of(&annotated);
    assert_eq!(result.markers.len(), plain.markers.len());
    assert_eq!(result.markers[0].corners_px, plain.markers[0].corners_px);
    assert_eq!(
        result.markers[0].pose.as_ref().map(|p| &p.rotation),
        plain.markers[0].pose.as_ref().map(|p| &p.rotation)
    );
    let body = annotated.bytes().expect("a body");
    assert_eq!(&body[..2], &[0xFF, 0xD8], "a JPEG");
    assert_eq!(decode(&body).dimensions(), (1280, 720));
}

#[test]
fn the_multipart_form_is_annotated_too() {
    let server = Server::start();
    let (photo, _) = photo("multipart.jpg");
    let request = serde_json::json!({
        "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5},
        "marker": {"size_mm": 50}
    });
    let form = reqwest::blocking::multipart::Form::new()
        .part(
            "image",
            reqwest::blocking::multipart::Part::bytes(photo)
                .file_name("photo.jpg")
                .mime_str("image/jpeg")
                .expect("a media type"),
        )
        .part(
            "request",
            reqwest::blocking::multipart::Part::text(request.to_string())
                .mime_str("application/json")
                .expect("a media type"),
        );

    let response = client()
        .post(server.url("/v1/pose/image/annotated"))
        .header(header::ACCEPT, "image/png")
        .multipart(form)
        .send()
        .expect("the server answers");

    assert_eq!(response.status(), StatusCode::OK);
    let result = result_of(&response);
    let image = decode(&response.bytes().expect("a body"));
    assert_corner_marks_on_corners(&image, &result);
    assert_axes_end_where_the_pose_says(&image, &result);
}

fn assert_problem(response: Response, status: StatusCode, code: &str, field: Option<&str>) {
    assert_eq!(response.status(), status);
    assert_eq!(
        response.headers()[header::CONTENT_TYPE],
        "application/problem+json"
    );
    let problem: Value = response.json().expect("a problem");
    assert_eq!(problem["code"], code, "{problem}");
    assert_eq!(problem["field"].as_str(), field, "{problem}");
    assert!(problem["title"].is_string() && problem["detail"].is_string());
}

#[test]
fn errors_are_the_problems_of_the_plain_route() {
    let server = Server::start();
    let (photo, _) = photo("errors.jpg");

    let not_an_image = post_annotated(&server, b"this is not an image", PHOTO_QUERY, None);
    let no_size = post_annotated(
        &server,
        &photo,
        "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5",
        Some("image/png"),
    );
    let bad_focal = post_annotated(
        &server,
        &photo,
        "fx_px=abc&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50",
        None,
    );

    assert_problem(
        not_an_image,
        StatusCode::UNPROCESSABLE_ENTITY,
        "undecodable_image",
        None,
    );
    assert_problem(
        no_size,
        StatusCode::UNPROCESSABLE_ENTITY,
        "missing_field",
        Some("marker_size_mm"),
    );
    assert_problem(
        bad_focal,
        StatusCode::BAD_REQUEST,
        "malformed_query",
        Some("fx_px"),
    );
}

#[test]
fn a_result_too_long_for_a_header_is_left_out_and_its_size_given() {
    let server = Server::start();
    let (photo, _) = photo("long.jpg");
    // The paper's iteration, slowed down and traced: thousands of trace steps.
    let query = format!(
        "{PHOTO_QUERY}&method=paper&gain=0.01&tolerance_mm=1e-9&max_iterations=2000&trace=true"
    );

    let response = post_annotated(&server, &photo, &query, None);

    assert_eq!(response.status(), StatusCode::OK);
    assert!(response.headers().get("x-qrpose-result").is_none());
    let omitted: usize = response.headers()["x-qrpose-result-omitted"]
        .to_str()
        .expect("ASCII")
        .parse()
        .expect("a size in bytes");
    assert!(omitted > 16 * 1024, "{omitted}");
    assert_eq!(response.headers()["x-qrpose-markers"], "1");
}

#[test]
fn estimate_annotate_writes_the_same_picture_as_the_route() {
    let server = Server::start();
    let dir = scratch_dir("annotated");
    let (photo, _) = photo("cli.jpg");
    let input = dir.join("cli.jpg");
    let out = dir.join("cli-annotated.png");
    let _ = std::fs::remove_file(&out);

    let output = std::process::Command::new(crate::support::BIN)
        .args(["estimate", "--image"])
        .arg(&input)
        .args([
            "--fx-px", "1000", "--fy-px", "1000", "--cx-px", "639.5", "--cy-px", "359.5",
        ])
        .args(["--marker-size-mm", "50", "--annotate"])
        .arg(&out)
        .output()
        .expect("qrpose estimate runs");
    let route = post_annotated(&server, &photo, PHOTO_QUERY, Some("image/png"));

    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let printed: ImageResponse = serde_json::from_slice(&output.stdout).expect("the JSON");
    let written = decode(&std::fs::read(&out).expect("the annotated file"));
    assert_corner_marks_on_corners(&written, &printed);
    assert_axes_end_where_the_pose_says(&written, &printed);
    let from_route = decode(&route.bytes().expect("a body"));
    assert!(
        written == from_route,
        "the CLI and the route drew different pictures"
    );
    assert!(Path::new(&out).exists());
}

/// The sampling factors of a JPEG's components (SOF0/SOF1), as `h << 4 | v` bytes.
fn jpeg_sampling(jpeg: &[u8]) -> Vec<u8> {
    let mut at = 2;
    while at + 4 <= jpeg.len() {
        let (code, length) = (
            jpeg[at + 1],
            usize::from(u16::from_be_bytes([jpeg[at + 2], jpeg[at + 3]])),
        );
        if code == 0xC0 || code == 0xC1 {
            let count = usize::from(jpeg[at + 9]);
            return (0..count).map(|k| jpeg[at + 11 + 3 * k]).collect();
        }
        at += 2 + length;
    }
    panic!("no SOF0 or SOF1");
}

/// Pixels within `tolerance` of `colour` in every channel, as (x, y).
fn pixels_near(image: &RgbImage, colour: [u8; 3], tolerance: u8) -> Vec<[f64; 2]> {
    image
        .enumerate_pixels()
        .filter(|(_, _, p)| {
            p.0.iter()
                .zip(&colour)
                .all(|(a, b)| a.abs_diff(*b) <= tolerance)
        })
        .map(|(x, y, _)| [f64::from(x), f64::from(y)])
        .collect()
}

/// How far a spliced JPEG's corner-mark pixel may be from magenta in any channel: twice the
/// worst measured (28, over the 288 pixels of the four marks: the splice gives the grey
/// photo 4:4:4 chroma, and the photo is at quality 90). Nothing else gets near: the grey
/// photo has no channel near 0 while another is near 255, and every other overlay colour is
/// 255 off magenta in some channel.
const SPLICED_MARK_TOLERANCE: u8 = 56;

#[test]
fn the_jpeg_variant_splices_the_photo_and_its_corner_marks_are_on_the_corners() {
    let server = Server::start();
    let (photo, _) = photo("spliced.jpg");

    let response = post_annotated(&server, &photo, PHOTO_QUERY, Some("image/jpeg"));

    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()[header::CONTENT_TYPE], "image/jpeg");
    let result = result_of(&response);
    assert_eq!(result.markers.len(), 1, "{result:?}");
    let body = response.bytes().expect("a body");
    // The grey photo was spliced (made YCbCr 4:4:4), not re-encoded whole (4:2:0).
    assert_eq!(jpeg_sampling(&photo), vec![0x11]);
    assert_eq!(jpeg_sampling(&body), vec![0x11, 0x11, 0x11]);
    let image = decode(&body);
    assert_eq!(image.dimensions(), (1280, 720));
    let marks = pixels_near(&image, CORNER_MARK, SPLICED_MARK_TOLERANCE);
    assert_marks_centred_on(&marks, &result.markers[0].corners_px, 20);
}
