//! `POST /v1/pose/corners` and `qrpose estimate REQUEST.json` with a site: the camera by id,
//! the marker size by payload, the prior, and the pose in the robot's and the warehouse's
//! frame (`docs/site.md`).

use super::check_arithmetic_range;
use super::frames::{FramePoseDto, SiteView};
use super::problem::Problem;
use super::refusal::problem_from_estimate_error;
use super::request::{CornersRequest, ValidCornersRequest};
use super::response::PoseResponse;
use crate::estimate::{PoseEstimate, estimate_pose};
use qrpose_site::Site;
use qrpose_site::prior::{Observation, apply_prior};
use std::time::Instant;

/// Validates a corners request against `site` (none: intrinsics and size in the request)
/// and estimates the pose.
///
/// # Errors
/// As [`super::estimate_corners`], and 422 `unknown_camera`, `unknown_marker_size` or
/// `invalid_prior` for what the site cannot resolve.
pub fn estimate_corners_in(
    request: &CornersRequest,
    site: Option<&Site>,
) -> Result<PoseResponse, Problem> {
    let started = Instant::now();
    let (valid, site_camera) = request.validate_in(site)?;
    check_arithmetic_range(&valid)?;
    let s = &valid.setup;
    let estimate = estimate_pose(&valid.quad, &s.camera, &s.marker, &s.solver)
        .map_err(|e| problem_from_estimate_error(e, valid.corners_pointer))?;
    let view = SiteView {
        site,
        camera: site_camera,
    };
    let payload = request.payload.as_deref();
    let (estimate, by_prior) = with_prior(estimate, &valid, &view, payload);
    let elapsed_us = started.elapsed().as_secs_f64() * 1e6;
    let response = PoseResponse::try_new(
        &estimate,
        &s.camera,
        &s.marker,
        elapsed_us,
        valid.corners_pointer,
    )?;
    let (in_robot, in_world) = view.frames(&estimate, payload);
    response.with_site(
        valid.size_source.into(),
        (
            in_robot.as_ref().map(FramePoseDto::from),
            in_world.as_ref().map(FramePoseDto::from),
        ),
        by_prior,
        valid.corners_pointer,
    )
}

/// The estimate after the request's prior, and whether the prior decided.
fn with_prior(
    estimate: PoseEstimate,
    valid: &ValidCornersRequest,
    view: &SiteView<'_>,
    payload: Option<&str>,
) -> (PoseEstimate, bool) {
    let Some(prior) = valid
        .prior
        .as_ref()
        .and_then(|p| view.rotation_prior(p, payload))
    else {
        return (estimate, false);
    };
    let s = &valid.setup;
    let model = s.marker.object_points();
    let obs = Observation {
        model: &model,
        image: valid.quad.paper_order(),
        camera: &s.camera,
        marker: &s.marker,
        corner_sigma_px: s.solver.as_reprojection().corner_sigma_px,
    };
    match apply_prior(&estimate, &obs, &prior) {
        Some((with_prior, _)) => (with_prior, true),
        None => (estimate, false),
    }
}
