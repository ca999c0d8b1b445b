//! The planar ambiguity resolved by a prior (`docs/site.md`, Priors): an expected rotation
//! of the code in the camera frame, with an uncertainty, picks between the two poses that
//! `reprojection` refined.
//!
//! The prior is an isotropic Gaussian on the rotation angle θ between a candidate and the
//! expected rotation, with standard deviation σ. The fit alone gives the alternative the
//! probability p (`ambiguity.alternative_probability`, equal priors); with the prior its
//! log-odds become
//!
//! ```text
//! ln(p / (1 − p)) + (θ_best² − θ_alt²) / (2σ²),
//! ```
//!
//! and the alternative is reported when they are positive. A swapped estimate gets the
//! alternative's pose, its own covariance (σ_px²·(JᵀJ)⁻¹ of the reprojection residuals at
//! that pose, [`covariance_at`]), the other pose as its alternative, and warnings for its
//! own fit.

use nalgebra::{Matrix6, Rotation3, SMatrix};
use qrpose_core::estimate::{
    AMBIGUITY_PROBABILITY_THRESHOLD, HIGH_RMS_SIGMAS, PoseEstimate, Warning,
};
use qrpose_core::geometry::{
    camera::{Camera, ImageUnit},
    euler::angle_between,
    frames::{MarkerPoint, MarkerToCamera, PixelPoint},
    marker::Marker,
};

/// An expected rotation of the code in the camera frame (R of p_cam = R·p_marker + t) and
/// its standard deviation, rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationPrior {
    /// The expected R.
    pub expected: Rotation3<f64>,
    /// σ of the angle between R and the expected rotation, rad (> 0).
    pub sigma_rad: f64,
}

/// The prior's verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PriorDecision {
    /// Report the alternative instead of the best-fitting pose.
    pub take_alternative: bool,
    /// The posterior probability that the pose *not* reported is the true one.
    pub probability_of_other: f64,
}

/// Decides between `best` and `alternative` given the fit's probability of the alternative
/// (`None` without a pixel scale: then 0.5 if the fit called the two ambiguous, else 0).
pub fn decide(
    best: &Rotation3<f64>,
    alternative: &Rotation3<f64>,
    fit_alternative_probability: Option<f64>,
    ambiguous: bool,
    prior: &RotationPrior,
) -> PriorDecision {
    let p = fit_alternative_probability.unwrap_or(if ambiguous { 0.5 } else { 0.0 });
    if p <= 0.0 {
        return PriorDecision {
            take_alternative: false,
            probability_of_other: 0.0,
        };
    }
    let theta_best = angle_between(best, &prior.expected);
    let theta_alt = angle_between(alternative, &prior.expected);
    let log_odds = (p / (1.0 - p)).ln()
        + (theta_best.powi(2) - theta_alt.powi(2)) / (2.0 * prior.sigma_rad.powi(2));
    let probability_alt = 1.0 / (1.0 + (-log_odds).exp());
    let take_alternative = log_odds > 0.0;
    PriorDecision {
        take_alternative,
        probability_of_other: if take_alternative {
            1.0 - probability_alt
        } else {
            probability_alt
        },
    }
}

/// The points a pose was solved from: marker-frame model points (origin P2) and where they
/// were seen, in the same order, with the camera, the marker and the corner noise.
#[derive(Debug, Clone, Copy)]
pub struct Observation<'a> {
    /// Model points, marker frame, mm.
    pub model: &'a [MarkerPoint],
    /// Image points, px.
    pub image: &'a [PixelPoint],
    /// The camera.
    pub camera: &'a Camera,
    /// The marker.
    pub marker: &'a Marker,
    /// Corner noise σ, px per coordinate.
    pub corner_sigma_px: f64,
}

/// σ²·(JᵀJ)⁻¹ at `pose`: the covariance of (δθ rad, centre mm), camera axes, of the pose
/// fitted to `obs` (the core's convention), from the Jacobian of the reprojection residuals
/// (px, in the ideal undistorted image). `None` when a point is behind the camera or JᵀJ is
/// singular.
pub fn covariance_at(pose: &MarkerToCamera, obs: &Observation<'_>) -> Option<Matrix6<f64>> {
    let r = pose.rotation();
    let centre = obs.marker.centre().0.coords;
    let mut jtj = Matrix6::zeros();
    for m in obs.model {
        let arm = r * (m.0.coords - centre);
        let p = pose.transform(m).0.coords;
        if p.z <= 0.0 {
            return None;
        }
        let (fx, fy) = (obs.camera.fx(), obs.camera.fy());
        #[rustfmt::skip]
        let d_proj = SMatrix::<f64, 2, 3>::new(
            fx / p.z, 0.0,      -fx * p.x / (p.z * p.z),
            0.0,      fy / p.z, -fy * p.y / (p.z * p.z),
        );
        let mut d_point = SMatrix::<f64, 3, 6>::zeros();
        d_point
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(-arm.cross_matrix()));
        d_point
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&nalgebra::Matrix3::identity());
        let j = d_proj * d_point;
        jtj += j.transpose() * j;
    }
    jtj.try_inverse()
        .map(|inv| inv * obs.corner_sigma_px.powi(2))
}

/// The estimate with the prior applied: unchanged (but for the alternative's probability)
/// when the best fit stays, else the alternative in its place. `None` for an estimate
/// without an ambiguity block (methods other than `reprojection`).
pub fn apply_prior(
    estimate: &PoseEstimate,
    obs: &Observation<'_>,
    prior: &RotationPrior,
) -> Option<(PoseEstimate, bool)> {
    let ambiguity = estimate.diagnostics.ambiguity?;
    let decision = decide(
        &estimate.pose.rotation(),
        &ambiguity.alternative.rotation(),
        ambiguity.alternative_probability,
        ambiguity.ambiguous,
        prior,
    );
    let mut out = estimate.clone();
    let distinct = ambiguity.rotation_difference_rad.to_degrees()
        > qrpose_core::estimate::DISTINCT_ROTATION_DEG;
    let ambiguous = distinct && decision.probability_of_other >= AMBIGUITY_PROBABILITY_THRESHOLD;
    if decision.take_alternative {
        let best_rms = estimate.diagnostics.reprojection_rms.unwrap_or(f64::NAN);
        let pose = ambiguity.alternative;
        out.pose = pose;
        out.centre_mm = pose.transform(&obs.marker.centre()).0.coords;
        out.corners_cam = obs.marker.object_points().map(|m| pose.transform(&m));
        let d = &mut out.diagnostics;
        d.reprojection_rms = Some(ambiguity.alternative_rms);
        d.covariance = estimate
            .diagnostics
            .covariance
            .and_then(|_| covariance_at(&pose, obs));
        d.trace = None;
        if let Some(a) = d.ambiguity.as_mut() {
            a.alternative = estimate.pose;
            a.alternative_rms = best_rms;
            a.ratio = if best_rms > 0.0 {
                (ambiguity.alternative_rms / best_rms).clamp(0.0, 1.0)
            } else {
                1.0
            };
        }
    }
    if let Some(a) = out.diagnostics.ambiguity.as_mut() {
        a.alternative_probability = ambiguity
            .alternative_probability
            .map(|_| decision.probability_of_other);
        a.ambiguous = ambiguous;
    }
    refresh_warnings(&mut out, obs);
    Some((out, decision.take_alternative))
}

/// The warnings that depend on which pose is reported.
fn refresh_warnings(estimate: &mut PoseEstimate, obs: &Observation<'_>) {
    let pixels = obs.camera.unit() == ImageUnit::Pixel;
    let behind = estimate.corners_cam.iter().any(|p| p.0.z <= 0.0);
    let d = &mut estimate.diagnostics;
    let ambiguous = d.ambiguity.is_some_and(|a| a.ambiguous);
    let high = d
        .reprojection_rms
        .is_some_and(|rms| pixels && rms > HIGH_RMS_SIGMAS * obs.corner_sigma_px);
    let converged = !d.warnings.contains(&Warning::NotConverged);
    d.warnings.clear();
    for (on, w) in [
        (!converged, Warning::NotConverged),
        (ambiguous, Warning::PoseAmbiguous),
        (behind, Warning::BehindCamera),
        (high, Warning::HighReprojectionError),
    ] {
        if on {
            d.warnings.push(w);
        }
    }
}

/// The expected rotation of a mapped code in the camera frame from the robot's rotation in
/// the world (odometry), the camera mount and the code's rotation in the map:
/// R_cam←marker = R_mountᵀ · R_world←robotᵀ · R_world←marker.
pub fn expected_marker_rotation(
    robot_in_world: &Rotation3<f64>,
    mount: &Rotation3<f64>,
    marker_in_world: &Rotation3<f64>,
) -> Rotation3<f64> {
    mount.inverse() * robot_in_world.inverse() * marker_in_world
}
