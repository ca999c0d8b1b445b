//! Tests of the branch hypotheses: the re-opened pose and the reported mean.

use super::*;
use crate::measurement::{Alternative, Corners};
use crate::so3::angle_between;
use nalgebra::{Rotation3, Vector2};
use qrpose_core::geometry::marker::Marker;

/// A pose turned by `ry` rad about y, 1 m ahead, with rotation σ `rotation_sigma` rad and
/// position σ 1 mm.
fn candidate(ry: f64, rotation_sigma: f64) -> PoseCandidate {
    let mut covariance = Matrix6::identity();
    for i in 0..3 {
        covariance[(i, i)] = rotation_sigma * rotation_sigma;
    }
    PoseCandidate {
        rotation: Rotation3::new(Vector3::new(0.0, ry, 0.0)),
        centre_mm: Vector3::new(0.0, 0.0, 1000.0),
        covariance,
    }
}

fn hypothesis(pose: &PoseCandidate, log_weight: f64) -> Hypothesis {
    let params = TrackerParams::default();
    Hypothesis::new(start_imm(pose, Vector3::zeros(), &params), log_weight)
}

fn angle(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    angle_between(a, b)
}

#[test]
fn overlapping_hypotheses_are_reported_as_their_mean_and_distinct_ones_as_the_heavier() {
    // 0.1 rad apart with σ 0.05 rad each: squared separation 2, one uncertain pose.
    let (a, b) = (candidate(0.05, 0.05), candidate(-0.05, 0.05));
    let near = Branches {
        hyps: vec![hypothesis(&a, 0.0), hypothesis(&b, 0.0)],
        contested: true,
    };
    let (mean, p) = near.reported_pose();
    assert!(angle(&mean.rotation, &Rotation3::identity()) < 1e-6);
    // The spread about the mean: σ² + 0.05² about y.
    assert!(
        (p[(1, 1)] - 2.0 * 0.05 * 0.05).abs() < 1e-6,
        "{}",
        p[(1, 1)]
    );
    // σ 0.01 rad: squared separation 50, two poses; the heavier is reported as it is.
    let (a, b) = (candidate(0.05, 0.01), candidate(-0.05, 0.01));
    let far = Branches {
        hyps: vec![hypothesis(&a, 0.0), hypothesis(&b, -1.0)],
        contested: true,
    };
    let (reported, p) = far.reported_pose();
    assert!(angle(&reported.rotation, &a.rotation) < 1e-12);
    assert_eq!(p, far.mixture_pose_covariance());
}

fn measurement(best: PoseCandidate, alternative: PoseCandidate, p_alt: f64) -> Measurement {
    Measurement {
        payload: None,
        marker: Marker::try_new(50.0).expect("a marker"),
        corners: Corners {
            ideal_px: [Vector2::zeros(); 4],
            fx: 1000.0,
            fy: 1000.0,
            variance_px2: 0.01,
        },
        best,
        alternative: Some(Alternative {
            pose: alternative,
            probability: p_alt,
        }),
        ambiguous: true,
        best_at_corner_sigma: best.covariance,
    }
}

fn updated(pose: &PoseCandidate) -> Child {
    Child {
        hyp: hypothesis(pose, 0.0),
        fused: true,
        cost: Some(1.0),
    }
}

#[test]
fn a_branch_no_child_reaches_is_reopened_on_the_image_odds_until_the_track_was_contested() {
    let params = TrackerParams::default();
    let (best, alternative) = (candidate(0.05, 0.05), candidate(-0.05, 0.05));
    let m = measurement(best, alternative, 0.4);
    let odds = (0.4_f64 / 0.6).ln();
    // Never contested: the alternative joins on the image's odds alone.
    let mut children = vec![updated(&best)];
    Branches::reopen_unreached(&mut children, &m, &params, false);
    assert_eq!(children.len(), 2);
    assert!(angle(&children[1].hyp.estimate.rotation, &alternative.rotation) < 1e-12);
    assert!((children[1].hyp.log_weight - odds).abs() < 1e-9);
    // Contested: the re-open prior too.
    let mut children = vec![updated(&best)];
    Branches::reopen_unreached(&mut children, &m, &params, true);
    assert!((children[1].hyp.log_weight - (odds + REOPEN_PRIOR.ln())).abs() < 1e-9);
    // Both branches reached: nothing re-opened.
    let mut children = vec![updated(&best), updated(&alternative)];
    Branches::reopen_unreached(&mut children, &m, &params, false);
    assert_eq!(children.len(), 2);
}
