//! The three lens models against OpenCV itself, and their inverses over the image.
//!
//! `tests/fixtures/opencv_projections.json` holds, for a realistic camera of each model,
//! points in the camera frame and the pixels OpenCV 4.10 projects them to
//! (`cv2.projectPoints`, `cv2.fisheye.projectPoints`); `scripts/make_calibration_fixtures.py`
//! wrote it. The properties check undistort ∘ distort and distort ∘ undistort over the
//! image area of each camera.

use nalgebra::Point3;
use proptest::prelude::*;
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose_core::geometry::frames::{CameraPoint, NormalizedPoint, PixelPoint};
use serde::Deserialize;
use std::sync::LazyLock;

/// Largest difference from OpenCV's pixels allowed, px.
const MAX_OPENCV_DIFFERENCE_PX: f64 = 1e-6;
/// Largest round-trip error allowed, px.
const MAX_ROUND_TRIP_PX: f64 = 1e-6;
/// Largest error of a ray undistorted from OpenCV's pixels, px per unit of the ray's length:
/// the rays are exact to rounding (OpenCV's pixels carry about 5e-13 px of their own).
const MAX_RAY_ERROR_PX: f64 = 1e-10;

const FIXTURE: &str = include_str!("fixtures/opencv_projections.json");

#[derive(Debug, Deserialize)]
struct Fixture {
    opencv_version: String,
    cases: Vec<Case>,
}

#[derive(Debug, Deserialize)]
struct Case {
    name: String,
    model: String,
    image_size_px: [u32; 2],
    fx_px: f64,
    fy_px: f64,
    cx_px: f64,
    cy_px: f64,
    coefficients: Vec<f64>,
    points_mm: Vec<[f64; 3]>,
    pixels_px: Vec<[f64; 2]>,
}

impl Case {
    fn camera(&self) -> Camera {
        let model: DistortionModel = self.model.parse().expect("a known model");
        let distortion =
            Distortion::from_coefficients(model, &self.coefficients).expect("valid coefficients");
        Camera::from_pixels(self.fx_px, self.fy_px, self.cx_px, self.cy_px)
            .expect("valid intrinsics")
            .with_distortion(distortion)
    }
}

static PARSED: LazyLock<Fixture> =
    LazyLock::new(|| serde_json::from_str(FIXTURE).expect("the committed fixture parses"));

fn fixture() -> &'static Fixture {
    &PARSED
}

fn case(model: DistortionModel) -> &'static Case {
    fixture()
        .cases
        .iter()
        .find(|c| c.model == model.name())
        .expect("a case per model")
}

#[test]
fn the_fixture_covers_every_model_with_enough_points() {
    let fixture = fixture();
    assert!(fixture.opencv_version.starts_with("4."));
    for model in DistortionModel::ALL {
        let c = case(model);
        assert!(
            c.points_mm.len() >= 50,
            "{}: {} points",
            c.name,
            c.points_mm.len()
        );
        assert_eq!(c.points_mm.len(), c.pixels_px.len(), "{}", c.name);
    }
}

#[test]
fn every_model_projects_like_opencv_to_a_micropixel() {
    for c in &fixture().cases {
        let camera = c.camera();
        let mut worst_px: f64 = 0.0;
        for (p, want) in c.points_mm.iter().zip(&c.pixels_px) {
            let got = camera
                .project(&CameraPoint(Point3::new(p[0], p[1], p[2])))
                .expect("in front of the camera");
            worst_px = worst_px.max((got.u() - want[0]).hypot(got.v() - want[1]));
        }
        eprintln!(
            "{} ({}): max difference from OpenCV {worst_px:.2e} px",
            c.name, c.model
        );
        assert!(
            worst_px <= MAX_OPENCV_DIFFERENCE_PX,
            "{}: {worst_px} px from OpenCV",
            c.name
        );
    }
}

#[test]
fn every_model_undistorts_opencv_pixels_back_onto_their_rays() {
    for c in &fixture().cases {
        let camera = c.camera();
        let mut worst_px: f64 = 0.0;
        for (p, px) in c.points_mm.iter().zip(&c.pixels_px) {
            let ray = camera
                .normalize(&PixelPoint::new(px[0], px[1]))
                .expect("invertible inside the image");
            let (x, y) = (p[0] / p[2], p[1] / p[2]);
            // Compared in ideal pixels, where 1 normalised unit is fx px.
            let error_px = ((ray.x() - x) * c.fx_px).hypot((ray.y() - y) * c.fy_px);
            // Far off-axis fisheye rays are long (tan 88° = 29): compare relative to it.
            let scale = x.hypot(y).max(1.0);
            worst_px = worst_px.max(error_px / scale);
        }
        eprintln!("{} ({}): max ray error {worst_px:.2e} px", c.name, c.model);
        assert!(worst_px <= MAX_RAY_ERROR_PX, "{}: {worst_px} px", c.name);
    }
}

#[test]
fn plumb_bob_constructors_agree() {
    let c = case(DistortionModel::PlumbBob);
    let [k1, k2, p1, p2, k3] = c.coefficients[..] else {
        panic!("five coefficients")
    };
    let d = Distortion::try_new(k1, k2, p1, p2, k3).expect("finite");
    assert_eq!(
        Some(d),
        Distortion::from_coefficients(DistortionModel::PlumbBob, &c.coefficients).ok()
    );
}

/// Where a pixel of the image lands and comes back: pixel → ray → pixel.
fn pixel_round_trip_px(camera: &Camera, u: f64, v: f64) -> Option<f64> {
    let ray = camera.normalize(&PixelPoint::new(u, v)).ok()?;
    let back = camera.pixel_from_normalized(&ray);
    Some((back.u() - u).hypot(back.v() - v))
}

/// A point (u, v) anywhere in the image of `c`, pixel centres' convention.
fn in_image(c: &Case) -> impl Strategy<Value = (f64, f64)> {
    let [w, h] = c.image_size_px.map(f64::from);
    (-0.5..w - 0.5, -0.5..h - 0.5)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn every_pixel_of_a_radial_tangential_image_has_one_ray(
        (model, (u, v)) in prop_oneof![
            in_image(case(DistortionModel::PlumbBob))
                .prop_map(|p| (DistortionModel::PlumbBob, p)),
            in_image(case(DistortionModel::RationalPolynomial))
                .prop_map(|p| (DistortionModel::RationalPolynomial, p)),
        ]
    ) {
        let camera = case(model).camera();
        let error_px = pixel_round_trip_px(&camera, u, v);
        prop_assert!(error_px.is_some(), "{model}: ({u}, {v}) not undistorted");
        prop_assert!(error_px.unwrap_or(f64::INFINITY) <= MAX_ROUND_TRIP_PX);
    }

    /// A fisheye pixel has a ray exactly when it lies within θ_d(90°) of the centre.
    #[test]
    fn a_fisheye_pixel_has_a_ray_exactly_inside_the_ninety_degree_circle(
        (u, v) in in_image(case(DistortionModel::Equidistant))
    ) {
        let c = case(DistortionModel::Equidistant);
        let camera = c.camera();
        let (xd, yd) = ((u - c.cx_px) / c.fx_px, (v - c.cy_px) / c.fy_px);
        let theta_d = xd.hypot(yd);
        let [theta_d_89, theta_d_90] = [89.0f64, 90.0].map(|deg| {
            let on_axis = NormalizedPoint::new(deg.to_radians().tan(), 0.0);
            camera.distortion().distort(&on_axis).x()
        });
        let error_px = pixel_round_trip_px(&camera, u, v);
        if theta_d < theta_d_89 {
            prop_assert!(error_px.is_some(), "({u}, {v}) at θ_d {theta_d} not undistorted");
            prop_assert!(error_px.unwrap_or(f64::INFINITY) <= MAX_ROUND_TRIP_PX);
        } else if theta_d >= theta_d_90 {
            prop_assert!(error_px.is_none(), "({u}, {v}) beyond 90° got a ray");
        }
    }

    /// undistort(distort(p)) = p for ideal points out to where the image ends.
    #[test]
    fn undistortion_inverts_distortion_in_the_field_of_view(
        model_index in 0usize..3,
        (radius, angle_rad) in (0.0..1.0f64, 0.0..std::f64::consts::TAU),
    ) {
        let model = DistortionModel::ALL[model_index];
        let c = case(model);
        // The furthest ideal point of the fixture bounds the field of view.
        let r_max = c.points_mm.iter().map(|p| p[0].hypot(p[1]) / p[2]).fold(0.0, f64::max);
        let r = radius * r_max;
        let ideal = NormalizedPoint::new(r * angle_rad.cos(), r * angle_rad.sin());
        let d = c.camera().distortion().to_owned();
        let back = d.undistort(&d.distort(&ideal));
        prop_assert!(back.is_some(), "{model}: r = {r} not undistorted");
        let back = back.unwrap_or(ideal);
        let error_px = (back.x() - ideal.x()).hypot(back.y() - ideal.y()) * c.fx_px / r.max(1.0);
        prop_assert!(error_px <= MAX_ROUND_TRIP_PX, "{model}: r = {r}: {error_px} px");
    }
}
