//! The calibration writers: every lens model written in both formats reads back, through
//! the module's own reader, as the same camera to the bit, with its image size and format;
//! and the written files keep the layout their tools write.

use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose_site::calibration::{
    CalibrationFormat, opencv_yaml, parse_calibration, ros_camera_info_yaml,
};

/// A camera with awkward numbers (no short decimal form, an integer, a tiny coefficient).
fn cameras() -> Vec<Camera> {
    let cases: [(DistortionModel, &[f64]); 4] = [
        (
            DistortionModel::PlumbBob,
            &[-0.2512345678901234, 0.0801, 1e-5, -4.4e-4, 0.0],
        ),
        (
            DistortionModel::RationalPolynomial,
            &[
                0.3521, -0.0472, 3.7e-4, -2.9e-4, 1.3e-3, 0.6893, 0.0104, -3.1e-3,
            ],
        ),
        (
            DistortionModel::Equidistant,
            &[-0.00566, 0.04186, -0.03869, 0.00673],
        ),
        (DistortionModel::PlumbBob, &[0.0; 5]),
    ];
    cases
        .iter()
        .map(|(model, k)| {
            Camera::from_pixels(1000.0, 1005.123456789012, 650.5 + 1.0 / 3.0, 350.0)
                .expect("valid")
                .with_distortion(Distortion::from_coefficients(*model, k).expect("valid lens"))
        })
        .collect()
}

#[test]
fn every_model_round_trips_through_opencv_yaml_to_the_bit() {
    for camera in cameras() {
        let model = camera.distortion().model();
        let text = opencv_yaml(&camera, Some((1280, 720)), Some(0.2834));
        let back = parse_calibration(&text).unwrap_or_else(|e| panic!("{model}: {e}\n{text}"));
        assert_eq!(back.camera, camera, "{model}\n{text}");
        assert_eq!(back.image_size_px, Some((1280, 720)));
        assert_eq!(back.format, CalibrationFormat::OpenCv);
        assert!(text.starts_with("%YAML:1.0\n---\n"), "{text}");
        assert!(
            text.contains(&format!("distortion_model: {}\n", model.name())),
            "{text}"
        );
        assert!(
            text.contains("camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n")
        );
        assert!(text.contains("avg_reprojection_error: 0.2834\n"));
    }
    let without_size = opencv_yaml(&cameras()[0], None, None);
    let back = parse_calibration(&without_size).expect("reads");
    assert_eq!(back.image_size_px, None);
    assert!(!without_size.contains("avg_reprojection_error"));
}

#[test]
fn every_model_round_trips_through_ros_camera_info_to_the_bit() {
    for camera in cameras() {
        let model = camera.distortion().model();
        let text = ros_camera_info_yaml(&camera, (848, 800), "front: \"left\" #1\\");
        let back = parse_calibration(&text).unwrap_or_else(|e| panic!("{model}: {e}\n{text}"));
        assert_eq!(back.camera, camera, "{model}\n{text}");
        assert_eq!(back.image_size_px, Some((848, 800)));
        assert_eq!(back.format, CalibrationFormat::RosCameraInfo);
        let yaml: serde_json::Value = serde_norway_value(&text);
        assert_eq!(yaml["camera_name"], "front: \"left\" #1\\");
        assert_eq!(yaml["distortion_model"], model.name());
        let p = yaml["projection_matrix"]["data"]
            .as_array()
            .expect("a list")
            .clone();
        let k = yaml["camera_matrix"]["data"]
            .as_array()
            .expect("a list")
            .clone();
        assert_eq!(p.len(), 12);
        for row in 0..3 {
            for col in 0..3 {
                assert_eq!(p[4 * row + col], k[3 * row + col], "P = [K | 0]");
            }
            assert_eq!(p[4 * row + 3], 0.0, "P = [K | 0]");
        }
    }
}

/// The text as JSON values, through the same YAML parser the reader uses.
fn serde_norway_value(text: &str) -> serde_json::Value {
    serde_norway::from_str(text).expect("valid YAML")
}
