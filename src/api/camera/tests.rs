//! The camera shape: distortion models and coefficients, the answer form read back, ranges.

use super::*;
use serde_json::json;

fn distortion(body: serde_json::Value) -> Result<Distortion, Problem> {
    let dto: DistortionDto = serde_json::from_value(body).expect("a distortion object");
    dto.to_distortion("/camera")
}

#[test]
fn a_distortion_without_a_model_is_plumb_bob_as_before() {
    let d = distortion(json!({"k1": -0.1, "p2": 0.001})).expect("valid");
    assert_eq!(d.model(), DistortionModel::PlumbBob);
    assert_eq!(d.coefficients(), vec![-0.1, 0.0, 0.0, 0.001, 0.0]);
}

#[test]
fn each_model_takes_its_coefficients_in_opencv_order() {
    let rational = distortion(json!({
        "model": "rational_polynomial", "k1": 1.0, "k2": 2.0, "p1": 3.0, "p2": 4.0,
        "k3": 5.0, "k4": 6.0, "k5": 7.0, "k6": 8.0}))
    .expect("valid");
    assert_eq!(
        rational.coefficients(),
        vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
    );
    let fisheye =
        distortion(json!({"model": "equidistant", "k1": 0.1, "k2": 0.2, "k3": 0.3, "k4": 0.4}))
            .expect("valid");
    assert_eq!(fisheye.model(), DistortionModel::Equidistant);
    assert_eq!(fisheye.coefficients(), vec![0.1, 0.2, 0.3, 0.4]);
}

#[test]
fn refuses_a_coefficient_the_model_does_not_have_naming_it() {
    let cases = [
        (json!({"model": "equidistant", "k1": 0.1, "p1": 0.01}), "p1"),
        (json!({"model": "equidistant", "k6": 0.2}), "k6"),
        (json!({"k1": -0.2, "k4": 0.5}), "k4"),
        (json!({"model": "plumb_bob", "k5": 0.5}), "k5"),
    ];
    for (body, param) in cases {
        let problem = distortion(body.clone()).expect_err("refused");
        assert_eq!(problem.code, ErrorCode::InvalidCameraParameter, "{body}");
        let pointer = format!("/camera/distortion/{param}");
        assert_eq!(problem.field.as_deref(), Some(pointer.as_str()), "{body}");
        assert!(
            problem.detail.contains("not a coefficient"),
            "{}",
            problem.detail
        );
    }
}

#[test]
fn refuses_a_non_finite_coefficient_naming_it() {
    let dto = DistortionDto {
        model: Some(DistortionModelDto::RationalPolynomial),
        k5: f64::NAN,
        ..DistortionDto::default()
    };
    let problem = dto.to_distortion("/camera").expect_err("NaN");
    assert_eq!(problem.code, ErrorCode::NonFiniteNumber);
    assert_eq!(problem.field.as_deref(), Some("/camera/distortion/k5"));
}

#[test]
fn a_camera_written_as_an_answer_reads_back_as_the_same_camera() {
    let lenses = [
        Distortion::from_coefficients(DistortionModel::PlumbBob, &[-0.1, 0.02, 1e-3, -2e-3, 0.005]),
        Distortion::from_coefficients(
            DistortionModel::RationalPolynomial,
            &[0.1, 0.2, 0.003, 0.004, 0.5, 0.6, 0.7, 0.8],
        ),
        Distortion::from_coefficients(DistortionModel::Equidistant, &[0.1, -0.02, 0.003, -4e-4]),
    ];
    for lens in lenses {
        let lens = lens.expect("valid coefficients");
        let camera = Camera::from_pixels(900.0, 905.0, 640.5, 360.25)
            .expect("valid intrinsics")
            .with_distortion(lens);
        let wire = serde_json::to_value(CameraDto::from(&camera)).expect("serialises");
        let back: CameraDto = serde_json::from_value(wire.clone()).expect("a request camera");
        let (read, scale) = back.to_camera(CornersUnit::Px).expect("valid");
        assert_eq!(scale, None);
        assert_eq!(read.distortion(), &lens, "{wire}");
        assert_eq!(
            [read.fx(), read.fy(), read.cx(), read.cy()],
            [900.0, 905.0, 640.5, 360.25]
        );
        assert!(
            wire.get("id").is_none() && wire.get("focal_length_mm").is_none(),
            "{wire}"
        );
    }
}

#[test]
fn focal_lengths_and_pitches_outside_the_stated_ranges_are_refused_naming_them() {
    let pixel = |fx: f64| CameraDto {
        fx_px: Some(fx),
        fy_px: Some(1000.0),
        cx_px: Some(640.0),
        cy_px: Some(360.0),
        ..CameraDto::default()
    };
    for fx in [5e-324, 1e-4, 2e9] {
        let problem = pixel(fx)
            .to_camera(CornersUnit::Px)
            .expect_err("out of range");
        assert_eq!(problem.code, ErrorCode::InvalidCameraParameter, "{fx}");
        assert_eq!(problem.field.as_deref(), Some("/camera/fx_px"));
    }
    for fx in [FOCAL_RANGE_PX.0, 1000.0, FOCAL_RANGE_PX.1] {
        assert!(pixel(fx).to_camera(CornersUnit::Px).is_ok(), "{fx}");
    }
    let sensor = CameraDto {
        focal_length_mm: Some(8.0),
        pixel_size_um: Some(1e6),
        cx_px: Some(640.0),
        cy_px: Some(360.0),
        ..CameraDto::default()
    };
    let problem = sensor.to_camera(CornersUnit::Px).expect_err("out of range");
    assert_eq!(problem.field.as_deref(), Some("/camera/pixel_size_um"));
}

#[test]
fn refuses_an_unknown_model_name() {
    let err = serde_json::from_value::<DistortionDto>(json!({"model": "fisheye"}))
        .expect_err("not a model name of the API");
    assert!(err.to_string().contains("unknown variant"), "{err}");
}
