//! The pose of one code from its four corners: `POST /v1/pose/corners` and
//! `qrpose estimate REQUEST.json`.

use super::frames::{InFrames, SiteFrames};
use super::prior::{Observed, with_prior};
use super::setup::Setup;
use qrpose_core::estimate::{EstimateError, PoseEstimate, estimate_pose};
use qrpose_core::geometry::{marker::Marker, quad::ImageQuad};
use qrpose_detect::pipeline::MarkerSizes;
use qrpose_site::SizeSource;
use std::time::Instant;

/// The pose of one code, with what the site adds to it.
#[derive(Debug, Clone)]
pub struct CornersAnswer {
    /// The pose, after the prior.
    pub estimate: PoseEstimate,
    /// The code's size.
    pub marker: Marker,
    /// Where the size came from.
    pub size_source: SizeSource,
    /// The prior decided the planar ambiguity.
    pub resolved_by_prior: bool,
    /// The pose in the robot's and the world's frames.
    pub frames: InFrames,
    /// Time spent estimating, from the validated request to the answer, µs.
    pub elapsed_us: f64,
}

/// Why a corners request has no pose.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CornersError {
    /// The setup sizes codes by the site, and the site has no size for this payload.
    #[error("no marker size for this code")]
    UnknownMarkerSize,
    /// The solver refused the corners.
    #[error(transparent)]
    Estimate(#[from] EstimateError),
}

/// Estimates the pose of the code whose corners are `quad` (in the camera's image unit),
/// with payload `payload`, as `setup` says. `started` is when the request's work began
/// (its validation), for the answer's `elapsed_us`.
///
/// # Errors
/// [`CornersError::UnknownMarkerSize`] for a setup sized by the site that has no size for
/// `payload` (a request validated by `api::` is sized already); [`CornersError::Estimate`]
/// when the corners cannot be undistorted or no pose fits them. Non-convergence is not an
/// error: the estimate says `converged: false`.
pub fn estimate_corners(
    setup: &Setup,
    quad: &ImageQuad,
    payload: Option<&str>,
    started: Instant,
) -> Result<CornersAnswer, CornersError> {
    let (marker, size_source) = setup
        .sizes()
        .marker_for(payload)
        .ok_or(CornersError::UnknownMarkerSize)?;
    let estimate = estimate_pose(quad, &setup.camera, &marker, &setup.solver)?;
    let frames = SiteFrames {
        site: setup.site.as_deref(),
        camera: setup.site_camera.as_ref(),
        pick: setup.pick,
    };
    let prior = setup.prior.and_then(|p| p.for_code(&frames, payload));
    let model = marker.object_points();
    let observed = Observed {
        model: &model,
        image: quad.paper_order(),
        camera: &setup.camera,
        marker: &marker,
        corner_sigma_px: setup.solver.as_reprojection().corner_sigma_px,
    };
    let (estimate, resolved_by_prior) = with_prior(estimate, prior, &observed);
    let elapsed_us = started.elapsed().as_secs_f64() * 1e6;
    let frames = frames.of(&estimate, payload);
    Ok(CornersAnswer {
        estimate,
        marker,
        size_source,
        resolved_by_prior,
        frames,
        elapsed_us,
    })
}
