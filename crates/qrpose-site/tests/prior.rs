//! The planar ambiguity resolved by a prior: a small, distant, nearly frontal code whose
//! noisy corners make the fit pick the mirrored pose now and then; an expected rotation
//! with a 10° uncertainty must pick the true one every time, and the swapped pose must carry
//! its own covariance.

use nalgebra::Vector3;
use qrpose_core::estimate::{PoseEstimate, ValidSolver, estimate_pose};
use qrpose_core::geometry::{
    camera::Camera,
    euler::{EulerXyz, angle_between},
    frames::{MarkerToCamera, PixelPoint},
    marker::{CornerOrder, Marker},
    quad::ImageQuad,
};
use qrpose_site::prior::{Observation, RotationPrior, apply_prior, covariance_at};
use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::StandardNormal;

const SIGMA_PX: f64 = 0.5;
/// A reported pose this much farther from the truth than its alternative is the mirror,
/// degrees.
const FLIPPED_DEG: f64 = 5.0;

struct Case {
    camera: Camera,
    marker: Marker,
    truth: MarkerToCamera,
}

fn case() -> Case {
    let marker = Marker::try_new(50.0).expect("size");
    let r = EulerXyz::from_degrees(12.0, -6.0, 3.0).to_rotation();
    Case {
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("camera"),
        marker,
        truth: marker.pose_centred_at(r, Vector3::new(40.0, -20.0, 1500.0)),
    }
}

fn noisy_corners(c: &Case, rng: &mut StdRng) -> [PixelPoint; 4] {
    c.marker.object_points().map(|m| {
        let p = c.camera.project(&c.truth.transform(&m)).expect("in front");
        let mut n = || SIGMA_PX * rng.sample::<f64, _>(StandardNormal);
        PixelPoint::new(p.u() + n(), p.v() + n())
    })
}

fn estimate(c: &Case, corners: &[PixelPoint; 4]) -> PoseEstimate {
    let quad = ImageQuad::try_new(*corners, CornerOrder::Paper).expect("quad");
    estimate_pose(&quad, &c.camera, &c.marker, &ValidSolver::default()).expect("pose")
}

/// The angle of the reported pose and of its alternative to the truth, degrees.
fn errors_deg(c: &Case, e: &PoseEstimate) -> (f64, f64) {
    let other = e.diagnostics.ambiguity.expect("ambiguity").alternative;
    let to_truth = |r| angle_between(&r, &c.truth.rotation()).to_degrees();
    (to_truth(e.pose.rotation()), to_truth(other.rotation()))
}

#[test]
fn a_prior_picks_the_true_pose_where_the_fit_picked_its_mirror() {
    let c = case();
    let mut rng = StdRng::seed_from_u64(7);
    let prior = RotationPrior {
        expected: c.truth.rotation(),
        sigma_rad: 10f64.to_radians(),
    };
    let (mut fit_wrong, mut prior_wrong, mut trials) = (0, 0, 0);
    for _ in 0..400 {
        let corners = noisy_corners(&c, &mut rng);
        let fit = estimate(&c, &corners);
        let model = c.marker.object_points();
        let obs = Observation {
            model: &model,
            image: &corners,
            camera: &c.camera,
            marker: &c.marker,
            corner_sigma_px: SIGMA_PX,
        };
        let (resolved, swapped) = apply_prior(&fit, &obs, &prior).expect("reprojection");
        trials += 1;
        // A report is the mirror when it is clearly the candidate farther from the truth.
        let mirror = |e: &PoseEstimate| {
            let (deg, other_deg) = errors_deg(&c, e);
            deg > other_deg + FLIPPED_DEG
        };
        fit_wrong += usize::from(mirror(&fit));
        prior_wrong += usize::from(mirror(&resolved));
        if swapped {
            let a = resolved.diagnostics.ambiguity.expect("ambiguity");
            assert_eq!(
                a.alternative, fit.pose,
                "the fit's pose becomes the alternative"
            );
            assert!(resolved.diagnostics.covariance.is_some());
        }
    }
    println!(
        "mirrored reports in {trials} trials: fit alone {fit_wrong}, with a 10° prior {prior_wrong}"
    );
    assert!(
        fit_wrong >= 10,
        "the case must be ambiguous: {fit_wrong} mirrors"
    );
    assert!(
        prior_wrong * 5 <= fit_wrong,
        "the prior must remove most mirrors: {prior_wrong} of {fit_wrong} remain"
    );
}

#[test]
fn a_prior_on_the_mirror_picks_the_mirror() {
    let c = case();
    let mut rng = StdRng::seed_from_u64(8);
    let corners = noisy_corners(&c, &mut rng);
    let fit = estimate(&c, &corners);
    let other = fit.diagnostics.ambiguity.expect("ambiguity").alternative;
    let model = c.marker.object_points();
    let obs = Observation {
        model: &model,
        image: &corners,
        camera: &c.camera,
        marker: &c.marker,
        corner_sigma_px: SIGMA_PX,
    };
    let prior = RotationPrior {
        expected: other.rotation(),
        sigma_rad: 5f64.to_radians(),
    };
    let (resolved, swapped) = apply_prior(&fit, &obs, &prior).expect("reprojection");
    assert!(swapped);
    assert_eq!(resolved.pose, other);
    let p = resolved
        .diagnostics
        .ambiguity
        .and_then(|a| a.alternative_probability)
        .expect("a probability");
    assert!(p < 0.5, "the pose not reported is the less likely one: {p}");
}

#[test]
fn the_covariance_at_a_pose_is_the_estimators_own() {
    // covariance_at must reproduce the core's σ²(JᵀJ)⁻¹ at the pose it reports.
    let c = case();
    let mut rng = StdRng::seed_from_u64(9);
    let corners = noisy_corners(&c, &mut rng);
    let fit = estimate(&c, &corners);
    let model = c.marker.object_points();
    let obs = Observation {
        model: &model,
        image: &corners,
        camera: &c.camera,
        marker: &c.marker,
        corner_sigma_px: SIGMA_PX,
    };
    let ours = covariance_at(&fit.pose, &obs).expect("a covariance");
    let core = fit.diagnostics.covariance.expect("the core's");
    assert!(
        (ours - core).amax() < 1e-3 * core.amax(),
        "ours {ours} vs the core's {core}"
    );
}
