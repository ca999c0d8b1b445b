//! Synthetic round trips with a known camera: 15 views of a 120 mm QR-code-like
//! target (236 points each) at 0.3-0.7 m, tilted 10-40°, spread over a 1280 × 720 image,
//! with Gaussian noise from a seeded `StdRng`.

mod support;

use qrpose_calib::compare::{distortion_field_difference_px, projection_difference_px};
use qrpose_calib::{CameraCalibration, Options, View, calibrate};
use qrpose_core::geometry::camera::{Camera, DistortionModel};
use support::{IMAGE, barrel_camera, fisheye_camera, good_set, wide_angle_camera};

/// Largest focal length error, fraction.
const FOCAL_TOL: f64 = 0.0015;
/// Largest principal point error, px.
const PRINCIPAL_POINT_TOL_PX: f64 = 2.0;
/// Largest distortion field error (95th percentile over the inner 90 %), px.
const FIELD_TOL_PX: f64 = 1.0;
/// Errors of the other lens models are checked against their reported standard deviation:
/// within this many.
const MAX_SIGMAS: f64 = 3.5;

fn solve(views: &[View], model: DistortionModel) -> CameraCalibration {
    let options = Options {
        model,
        ..Options::default()
    };
    calibrate(views, IMAGE, &options).expect("a good set calibrates")
}

fn field_error_px(truth: &Camera, fitted: &Camera) -> f64 {
    distortion_field_difference_px(truth, fitted, IMAGE, 0.9, 0.95).expect("invertible lenses")
}

/// (estimate − truth, std) of fx, fy, cx, cy.
fn intrinsic_errors(truth: &Camera, r: &CameraCalibration) -> [(f64, f64); 4] {
    let c = &r.camera;
    [
        (c.fx() - truth.fx(), r.std.fx_px),
        (c.fy() - truth.fy(), r.std.fy_px),
        (c.cx() - truth.cx(), r.std.cx_px),
        (c.cy() - truth.cy(), r.std.cy_px),
    ]
}

#[test]
fn recovers_a_barrel_plumb_bob_camera_from_fifteen_views_with_a_tenth_of_a_pixel_of_noise() {
    let truth = barrel_camera();
    for seed in 0..5 {
        let set = good_set(&truth, 0.1, seed);
        let r = solve(&set.views, DistortionModel::PlumbBob);
        let c = &r.camera;
        let focal = ((c.fx() / truth.fx() - 1.0).abs()).max((c.fy() / truth.fy() - 1.0).abs());
        let pp = (c.cx() - truth.cx()).hypot(c.cy() - truth.cy());
        let field = field_error_px(&truth, c);
        let case = format!(
            "seed {seed}: focal {:.3} %, pp {pp:.2} px, field {field:.2} px",
            100.0 * focal
        );
        assert!(focal < FOCAL_TOL, "{case}");
        assert!(pp < PRINCIPAL_POINT_TOL_PX, "{case}");
        assert!(field < FIELD_TOL_PX, "{case}");
        assert!(r.warnings.is_empty(), "{case}: {:?}", r.warnings);
        assert_eq!(r.used_views().count(), 15, "{case}");
        // The residuals are the noise: per axis 0.1 px, so an RMS length of 0.1·√2.
        assert!(
            (r.reprojection_rms_px - 0.1 * 2f64.sqrt()).abs() < 0.01,
            "{case}: {}",
            r.reprojection_rms_px
        );
        assert!(
            (r.robust_sigma_px - 0.1).abs() < 0.01,
            "{case}: {}",
            r.robust_sigma_px
        );
        for (report, pose) in r.views.iter().zip(&set.poses) {
            let fit = report.fit().expect("used");
            assert_eq!(fit.residuals_px.len(), report.points);
            assert_eq!(fit.weights.len(), report.points);
            let angle = fit.pose.rotation().angle_to(&pose.rotation());
            let shift = (fit.translation_mm() - pose.translation_mm()).norm();
            assert!(
                angle < 0.5f64.to_radians() && shift < 3.0,
                "{case}, view {}: {:.3}°, {shift:.2} mm",
                report.index,
                angle.to_degrees()
            );
        }
    }
}

#[test]
fn reported_standard_deviations_match_the_errors_over_twenty_sets() {
    let truth = barrel_camera();
    let true_k = truth.distortion().coefficients();
    // Sum of squared normalised errors: fx, fy, cx, cy, then k1 k2 p1 p2 k3.
    let mut z2 = [0.0; 9];
    for seed in 0..20 {
        let set = good_set(&truth, 0.2, 100 + seed);
        let r = solve(&set.views, DistortionModel::PlumbBob);
        let k = r.camera.distortion().coefficients();
        for (i, (error, std)) in intrinsic_errors(&truth, &r).into_iter().enumerate() {
            z2[i] += (error / std).powi(2);
        }
        for j in 0..5 {
            z2[4 + j] += ((k[j] - true_k[j]) / r.std.coefficients[j]).powi(2);
        }
    }
    let names = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];
    for (name, sum) in names.iter().zip(z2) {
        let rms = (sum / 20.0).sqrt();
        assert!(
            (0.5..=2.0).contains(&rms),
            "{name}: RMS of (estimate − truth) / std = {rms:.2}"
        );
    }
}

#[test]
fn recovers_a_wide_angle_rational_polynomial_camera() {
    let truth = wide_angle_camera();
    for seed in 0..3 {
        let set = good_set(&truth, 0.1, seed);
        let r = solve(&set.views, DistortionModel::RationalPolynomial);
        let field = field_error_px(&truth, &r.camera);
        assert!(field < FIELD_TOL_PX, "seed {seed}: field {field:.2} px");
        for (i, (error, std)) in intrinsic_errors(&truth, &r).into_iter().enumerate() {
            assert!(
                error.abs() < MAX_SIGMAS * std,
                "seed {seed}, intrinsic {i}: error {error:.3}, std {std:.3}"
            );
        }
        assert!(
            r.std.fx_px / r.camera.fx() < 0.0015,
            "seed {seed}: {:?}",
            r.std
        );
        assert_eq!(
            r.camera.distortion().model(),
            DistortionModel::RationalPolynomial
        );
        assert!(r.warnings.is_empty(), "seed {seed}: {:?}", r.warnings);
    }
}

/// A fisheye's displacement field runs to hundreds of pixels near the rim (tan θ against θ),
/// so the field difference magnifies a focal error there; the projection difference (where
/// the fitted camera sees the true camera's rays) is the measure that matters for poses.
#[test]
fn recovers_an_equidistant_fisheye_camera() {
    let truth = fisheye_camera();
    for seed in 0..6 {
        let set = good_set(&truth, 0.1, seed);
        let r = solve(&set.views, DistortionModel::Equidistant);
        let moved =
            projection_difference_px(&truth, &r.camera, IMAGE, 0.9, 0.95).expect("invertible");
        assert!(
            moved < 2.5,
            "seed {seed}: rays moved {moved:.2} px (95th percentile)"
        );
        for (i, (error, std)) in intrinsic_errors(&truth, &r).into_iter().enumerate() {
            assert!(
                error.abs() < MAX_SIGMAS * std,
                "seed {seed}, intrinsic {i}: error {error:.3}, std {std:.3}"
            );
        }
        assert!(
            r.std.fx_px / r.camera.fx() < 0.0015,
            "seed {seed}: {:?}",
            r.std
        );
        assert_eq!(r.camera.distortion().model(), DistortionModel::Equidistant);
        assert!(r.warnings.is_empty(), "seed {seed}: {:?}", r.warnings);
    }
}
