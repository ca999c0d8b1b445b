//! `POST /v1/pose/corners` and `qrpose estimate REQUEST.json`: the request validated into a
//! [`crate::app::Setup`], [`crate::app::estimate_corners`], and its answer as a
//! [`PoseResponse`] (with a site: the camera by id, the marker size by payload, the prior,
//! and the pose in the robot's and the warehouse's frame, `docs/site.md`).

use super::problem::Problem;
use super::refusal::problem_from_corners_error;
use super::request::{CornersRequest, ValidCorners};
use super::response::PoseResponse;
use crate::app::{self, CornersAnswer};
use qrpose_site::Site;
use std::sync::Arc;

/// Validates a corners request against `site` (none: intrinsics and size in the request),
/// estimates the pose and maps the answer.
///
/// # Errors
/// A [`Problem`] (4xx) for anything wrong with the request, including 422
/// `numerically_degenerate` when a number of the result is not finite (inputs at magnitudes
/// such as 1e150 px), and `unknown_camera`, `unknown_marker_size` or `invalid_prior` for
/// what the site cannot resolve. Non-convergence is not an error: the response says
/// `converged: false`.
pub fn estimate_corners(
    request: &CornersRequest,
    site: Option<Arc<Site>>,
) -> Result<PoseResponse, Problem> {
    let valid = request.validate(site)?;
    let answer = app::estimate_corners(
        &valid.setup,
        &valid.quad,
        valid.payload.as_deref(),
        valid.started,
    )
    .map_err(|e| {
        problem_from_corners_error(
            e,
            valid.corners_pointer,
            valid.setup.site.as_deref(),
            valid.payload.as_deref(),
        )
    })?;
    pose_response(&answer, &valid)
}

/// The wire form of a corners answer.
///
/// # Errors
/// 422 `numerically_degenerate` (naming the corner list) when a number is not finite.
pub fn pose_response(
    answer: &CornersAnswer,
    valid: &ValidCorners,
) -> Result<PoseResponse, Problem> {
    let response = PoseResponse::try_new(
        &answer.estimate,
        &valid.setup.camera,
        &answer.marker,
        answer.elapsed_us,
        valid.corners_pointer,
    )?;
    response.with_site(
        answer.size_source.into(),
        &answer.frames,
        answer.resolved_by_prior,
        valid.corners_pointer,
    )
}
