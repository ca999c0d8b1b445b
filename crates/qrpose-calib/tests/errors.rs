//! Each error variant, from the input that causes it.

mod support;

use nalgebra::{Rotation3, Vector3};
use qrpose_calib::{
    CalibrationError, Correspondence, ImageSize, MIN_POINTS_PER_VIEW, MIN_VIEWS, Options,
    SolveFailure, View, calibrate,
};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::{MarkerToCamera, PixelPoint};
use support::{IMAGE, barrel_camera, good_set, project_all, qr_target_mm};

fn refusal(views: &[View], image: ImageSize) -> CalibrationError {
    calibrate(views, image, &Options::default()).expect_err("refused")
}

#[test]
fn an_empty_image_size_is_refused() {
    let set = good_set(&barrel_camera(), 0.2, 0);
    let err = refusal(&set.views, ImageSize::new(1280, 0));
    assert_eq!(
        err,
        CalibrationError::InvalidImageSize {
            width_px: 1280,
            height_px: 0
        }
    );
}

#[test]
fn a_non_finite_coordinate_is_refused_with_its_view_and_point() {
    let mut set = good_set(&barrel_camera(), 0.2, 0);
    set.views[3].points[17].pixel_px = PixelPoint::new(412.0, f64::INFINITY);
    assert_eq!(
        refusal(&set.views, IMAGE),
        CalibrationError::NonFinite { view: 3, point: 17 }
    );
    set.views[3].points[17].pixel_px = PixelPoint::new(412.0, 300.0);
    set.views[5].points[0].target_mm.x = f64::NAN;
    assert_eq!(
        refusal(&set.views, IMAGE),
        CalibrationError::NonFinite { view: 5, point: 0 }
    );
}

#[test]
fn a_view_with_too_few_points_is_refused() {
    let mut set = good_set(&barrel_camera(), 0.2, 0);
    set.views[9].points.truncate(5);
    assert_eq!(
        refusal(&set.views, IMAGE),
        CalibrationError::TooFewPoints {
            view: 9,
            points: 5,
            required: MIN_POINTS_PER_VIEW
        }
    );
}

#[test]
fn two_views_are_too_few() {
    let set = good_set(&barrel_camera(), 0.2, 0);
    assert_eq!(
        refusal(&set.views[..2], IMAGE),
        CalibrationError::TooFewViews {
            given: 2,
            usable: 2,
            required: MIN_VIEWS
        }
    );
}

#[test]
fn views_left_too_few_by_failed_homographies_are_refused_with_the_counts() {
    let mut views = good_set(&barrel_camera(), 0.2, 0).views[..4].to_vec();
    for view in &mut views[1..3] {
        // Every target point on one line: no homography.
        for (i, c) in view.points.iter_mut().enumerate() {
            *c = Correspondence::new(i as f64, 0.0, 100.0 + 3.0 * i as f64, 50.0);
        }
    }
    let err = refusal(&views, IMAGE);
    assert_eq!(
        err,
        CalibrationError::TooFewViews {
            given: 4,
            usable: 2,
            required: MIN_VIEWS
        }
    );
    assert!(err.to_string().contains("2 usable views of 4"), "{err}");
}

#[test]
fn fronto_parallel_views_determine_no_focal_length() {
    // A distortion-free camera; every view faces it squarely, only spun and moved.
    let camera = Camera::from_pixels(1000.0, 1000.0, 640.0, 360.0).expect("valid");
    let target = qr_target_mm();
    let views: Vec<View> = [
        (0.0, -80.0, 500.0),
        (0.8, 60.0, 450.0),
        (2.1, 10.0, 600.0),
        (3.0, -30.0, 550.0),
    ]
    .iter()
    .map(|&(spin, x, z)| {
        let pose = MarkerToCamera::new(
            Rotation3::from_axis_angle(&Vector3::z_axis(), spin),
            Vector3::new(x, 20.0, z),
        );
        let pixels = project_all(&camera, &pose, &target, 2.0).expect("inside the image");
        View {
            points: target
                .iter()
                .zip(pixels)
                .map(|(m, p)| Correspondence::new(m.x, m.y, p.u(), p.v()))
                .collect(),
        }
    })
    .collect();
    let err = refusal(&views, IMAGE);
    assert_eq!(
        err,
        CalibrationError::SolveFailed {
            reason: SolveFailure::FocalLengthUndetermined
        }
    );
    assert!(err.to_string().contains("tilt the code"), "{err}");
}
