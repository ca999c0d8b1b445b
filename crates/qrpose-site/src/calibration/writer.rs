//! Calibration files written from a camera, in the two formats this module reads, laid out
//! as their tools write them, and read back by [`super::parse_calibration`] as they are:
//!
//! - [`opencv_yaml`]: OpenCV `FileStorage` YAML (`%YAML:1.0` header, `!!opencv-matrix`
//!   with `dt: d`), as `cv2.FileStorage` and OpenCV's calibration sample write it;
//! - [`ros_camera_info_yaml`]: ROS `camera_info` YAML, as ROS `camera_calibration` writes
//!   it (`ost.yaml`), with the identity as `rectification_matrix` and [K | 0] as
//!   `projection_matrix` (a monocular camera whose rectified image is the raw one).
//!
//! Both name the lens in `distortion_model` with qrpose's (and ROS's) model names,
//! `plumb_bob`, `rational_polynomial` or `equidistant`: a fisheye file must name its model,
//! since four coefficients alone read as `plumb_bob` with k3 = 0. Numbers are written in
//! Rust's shortest form that reads back to the same `f64` (`1000.0`, `-0.25`, `1e-5`), so
//! a camera survives the round trip bit for bit.

use qrpose_core::geometry::camera::Camera;
use std::fmt::Write;

/// `x` in the shortest form that reads back to the same `f64`, always with a `.` or an
/// exponent so that every YAML reader takes it for a float.
fn number(x: f64) -> String {
    format!("{x:?}")
}

/// `values` as a YAML flow sequence.
fn flow(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|v| number(*v)).collect();
    format!("[ {} ]", items.join(", "))
}

/// The camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], row-major.
fn camera_matrix(camera: &Camera) -> [f64; 9] {
    [
        camera.fx(),
        0.0,
        camera.cx(),
        0.0,
        camera.fy(),
        camera.cy(),
        0.0,
        0.0,
        1.0,
    ]
}

/// `s` as a YAML double-quoted scalar: `\` and `"` escaped, control characters as `\uXXXX`.
fn quoted(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            c if c.is_control() => {
                // Writing to a String cannot fail.
                let _ = write!(out, "\\u{:04x}", u32::from(c));
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// One `!!opencv-matrix` entry of `rows` × `cols` doubles.
fn opencv_matrix(out: &mut String, key: &str, rows: usize, cols: usize, data: &[f64]) {
    let _ = write!(
        out,
        "{key}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: {}\n",
        flow(data)
    );
}

/// One ROS `{rows, cols, data}` entry.
fn ros_matrix(out: &mut String, key: &str, rows: usize, cols: usize, data: &[f64]) {
    let _ = write!(
        out,
        "{key}:\n  rows: {rows}\n  cols: {cols}\n  data: {}\n",
        flow(data)
    );
}

/// The camera as an OpenCV `FileStorage` YAML file: `image_width` and `image_height` when
/// `image_size_px` is given, `camera_matrix`, `distortion_model`,
/// `distortion_coefficients` (one row, OpenCV's order) and, when given,
/// `avg_reprojection_error` (px; the reader ignores it). The camera's unit is taken to be
/// pixels.
#[must_use]
pub fn opencv_yaml(
    camera: &Camera,
    image_size_px: Option<(u32, u32)>,
    avg_reprojection_error_px: Option<f64>,
) -> String {
    let mut out = String::from("%YAML:1.0\n---\n");
    if let Some((w, h)) = image_size_px {
        let _ = write!(out, "image_width: {w}\nimage_height: {h}\n");
    }
    opencv_matrix(&mut out, "camera_matrix", 3, 3, &camera_matrix(camera));
    let lens = camera.distortion();
    let coefficients = lens.coefficients();
    let _ = writeln!(out, "distortion_model: {}", lens.model().name());
    opencv_matrix(
        &mut out,
        "distortion_coefficients",
        1,
        coefficients.len(),
        &coefficients,
    );
    if let Some(error) = avg_reprojection_error_px {
        let _ = writeln!(out, "avg_reprojection_error: {}", number(error));
    }
    out
}

/// The camera as a ROS `camera_info` YAML file of the image size `image_size_px`, named
/// `camera_name` (any text; written as a quoted YAML string). The camera's unit is taken to
/// be pixels.
#[must_use]
pub fn ros_camera_info_yaml(
    camera: &Camera,
    image_size_px: (u32, u32),
    camera_name: &str,
) -> String {
    let (w, h) = image_size_px;
    let mut out = format!(
        "image_width: {w}\nimage_height: {h}\ncamera_name: {}\n",
        quoted(camera_name)
    );
    let k = camera_matrix(camera);
    ros_matrix(&mut out, "camera_matrix", 3, 3, &k);
    let lens = camera.distortion();
    let coefficients = lens.coefficients();
    let _ = writeln!(out, "distortion_model: {}", lens.model().name());
    ros_matrix(
        &mut out,
        "distortion_coefficients",
        1,
        coefficients.len(),
        &coefficients,
    );
    #[rustfmt::skip]
    let identity = [
        1.0, 0.0, 0.0,
        0.0, 1.0, 0.0,
        0.0, 0.0, 1.0,
    ];
    ros_matrix(&mut out, "rectification_matrix", 3, 3, &identity);
    #[rustfmt::skip]
    let projection = [
        k[0], k[1], k[2], 0.0,
        k[3], k[4], k[5], 0.0,
        k[6], k[7], k[8], 0.0,
    ];
    ros_matrix(&mut out, "projection_matrix", 3, 4, &projection);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_keep_a_point_or_an_exponent_and_names_are_escaped() {
        assert_eq!(number(1000.0), "1000.0");
        assert_eq!(number(0.0), "0.0");
        assert_eq!(number(-0.25), "-0.25");
        assert_eq!(number(1e-5), "1e-5");
        assert_eq!(
            quoted("front \"left\"\\1\n"),
            "\"front \\\"left\\\"\\\\1\\u000a\""
        );
    }
}
