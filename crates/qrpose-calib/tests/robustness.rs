//! Bad data in a good set: a view whose points are corrupted is dropped and named; scattered
//! outlying points are down-weighted and the fit stays within the round trip's tolerances;
//! a view that admits no homography is dropped for it.

mod support;

use qrpose_calib::compare::distortion_field_difference_px;
use qrpose_calib::{CameraCalibration, Correspondence, DropReason, Options, calibrate};
use qrpose_core::geometry::camera::Camera;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use support::{IMAGE, barrel_camera, gaussian, good_set};

/// As in the round trips: focal fraction, principal point px, field px.
const FOCAL_TOL: f64 = 0.0015;
const PRINCIPAL_POINT_TOL_PX: f64 = 2.0;
const FIELD_TOL_PX: f64 = 1.0;

fn assert_within_tolerance(truth: &Camera, r: &CameraCalibration, case: &str) {
    let c = &r.camera;
    let focal = ((c.fx() / truth.fx() - 1.0).abs()).max((c.fy() / truth.fy() - 1.0).abs());
    let pp = (c.cx() - truth.cx()).hypot(c.cy() - truth.cy());
    let field = distortion_field_difference_px(truth, c, IMAGE, 0.9, 0.95).expect("invertible");
    assert!(
        focal < FOCAL_TOL && pp < PRINCIPAL_POINT_TOL_PX && field < FIELD_TOL_PX,
        "{case}: focal {:.3} %, pp {pp:.2} px, field {field:.2} px",
        100.0 * focal
    );
}

#[test]
fn a_view_of_corrupted_points_is_dropped_and_named() {
    let truth = barrel_camera();
    let mut rng = StdRng::seed_from_u64(42);
    let mut set = good_set(&truth, 0.1, 3);
    // View 6: every point displaced by 3-6 px in a random direction (a mismatched or moved
    // target).
    for c in &mut set.views[6].points {
        let (length, angle): (f64, f64) = (rng.gen_range(3.0..6.0), rng.gen_range(0.0..6.3));
        c.pixel_px.0.x += length * angle.cos();
        c.pixel_px.0.y += length * angle.sin();
    }
    let r = calibrate(&set.views, IMAGE, &Options::default()).expect("calibrates");
    let dropped: Vec<usize> = r.dropped_views().map(|v| v.index).collect();
    assert_eq!(dropped, vec![6]);
    let report = &r.views[6];
    match report.drop_reason() {
        Some(DropReason::PoorFit {
            median_px,
            limit_px,
            ..
        }) => {
            assert!(
                median_px > limit_px && limit_px >= 1.0,
                "{median_px} vs {limit_px}"
            );
        }
        other => panic!("view 6 dropped for {other:?}"),
    }
    assert_eq!(report.drop_reason().map(|d| d.name()), Some("poor_fit"));
    assert!(report.fit().is_some(), "the fit that dropped it is kept");
    assert_eq!(r.used_views().count(), 14);
    assert_within_tolerance(&truth, &r, "without view 6");
}

#[test]
fn outlier_points_are_down_weighted_and_the_fit_stays_within_tolerance() {
    let truth = barrel_camera();
    let mut rng = StdRng::seed_from_u64(7);
    let mut set = good_set(&truth, 0.1, 4);
    // 5 % of all points moved by 4-20 px: mismatched corners.
    let mut moved = Vec::new();
    for (v, view) in set.views.iter_mut().enumerate() {
        for (p, c) in view.points.iter_mut().enumerate() {
            if rng.gen_bool(0.05) {
                let (length, angle): (f64, f64) =
                    (rng.gen_range(4.0..20.0), rng.gen_range(0.0..6.3));
                c.pixel_px.0.x += length * angle.cos();
                c.pixel_px.0.y += length * angle.sin();
                moved.push((v, p));
            }
        }
    }
    assert!(moved.len() > 100, "{} outliers", moved.len());
    let r = calibrate(&set.views, IMAGE, &Options::default()).expect("calibrates");
    assert_eq!(
        r.dropped_views().count(),
        0,
        "no view is dropped for a few bad points"
    );
    for &(v, p) in &moved {
        let weight = r.views[v].fit().expect("used").weights[p];
        assert!(weight < 0.2, "view {v}, point {p}: weight {weight}");
    }
    let inliers_full = r
        .views
        .iter()
        .flat_map(|v| v.fit().expect("used").weights.iter())
        .filter(|w| **w == 1.0)
        .count();
    let total: usize = r.views.iter().map(|v| v.points).sum();
    assert!(
        inliers_full as f64 > 0.9 * total as f64,
        "{inliers_full} of {total} fully weighted"
    );
    assert!(
        (r.robust_sigma_px - 0.1).abs() < 0.02,
        "σ̂ {} px",
        r.robust_sigma_px
    );
    assert_within_tolerance(&truth, &r, "5 % outliers");
}

#[test]
fn a_view_whose_points_are_collinear_is_dropped_for_its_homography() {
    let truth = barrel_camera();
    let mut set = good_set(&truth, 0.1, 5);
    let mut rng = StdRng::seed_from_u64(1);
    // View 2 sees only one edge of the code: every target point on the line y = −60 mm.
    set.views[2].points = (0..20)
        .map(|i| {
            let x = -60.0 + 6.0 * f64::from(i);
            Correspondence::new(
                x,
                -60.0,
                300.0 + 5.0 * x + gaussian(&mut rng),
                200.0 + 0.5 * x,
            )
        })
        .collect();
    let r = calibrate(&set.views, IMAGE, &Options::default()).expect("calibrates");
    assert_eq!(r.views[2].drop_reason(), Some(DropReason::HomographyFailed));
    assert!(r.views[2].fit().is_none());
    assert_eq!(r.used_views().count(), 14);
    assert_within_tolerance(&truth, &r, "without view 2");
}
