//! One code of a photo, the site's way (`docs/site.md`): its size by payload (the code is
//! solved again with it), the prior, the pose in the robot's and the warehouse's frame. A
//! code the site cannot size keeps its payload and corners, with `pose: null` and the
//! problem `unknown_marker_size`.

use super::ValidImageRequest;
use crate::api::context::unknown_marker_size;
use crate::api::frames::{FramePoseDto, MarkerSizeSourceDto, SiteView};
use crate::api::problem::{ErrorCode, Problem};
use crate::api::refusal::marker_pose_or_problem;
use crate::api::response::PoseResponse;
use crate::detect::finders::finder_marker_points;
use crate::detect::pipeline::{LocatedMarker, MarkerError, Points, Setup, solve};
use crate::estimate::PoseEstimate;
use crate::geometry::frames::{MarkerPoint, PixelPoint};
use crate::geometry::marker::{CornerOrder, Marker};
use crate::geometry::quad::ImageQuad;
use qrpose_site::SizeSource;
use qrpose_site::prior::{Observation, apply_prior};
use qrpose_site::transform::PoseWithCovariance;
use std::time::Instant;

/// What every code of one photo is solved with.
#[derive(Debug, Clone, Copy)]
pub struct MarkerContext<'a> {
    /// The validated request.
    pub valid: &'a ValidImageRequest,
    /// The site and the request's site camera.
    pub view: SiteView<'a>,
}

/// One code's pose, or why there is none, and the robot's pose in the world from it.
#[derive(Debug, Clone)]
pub struct MarkerPose {
    /// The points the pose was solved from.
    pub points_used: Points,
    /// The wire pose.
    pub pose: Option<PoseResponse>,
    /// Why `pose` is null.
    pub problem: Option<Problem>,
    /// T_world←robot from this code, for the localisation.
    pub robot_in_world: Option<PoseWithCovariance>,
}

/// The marker of code `index` and where its size came from, or its problem.
fn marker_of(
    payload: Option<&str>,
    context: &MarkerContext<'_>,
    index: usize,
) -> Result<(Marker, SizeSource), Problem> {
    let setup = &context.valid.setup;
    if context.valid.size_from_request {
        return Ok((setup.marker, SizeSource::Request));
    }
    let pointer = format!("/markers/{index}/payload");
    let site = context.view.site.ok_or_else(|| {
        Problem::new(ErrorCode::UnknownMarkerSize, "no site is loaded").with_field(&pointer)
    })?;
    let lookup = site
        .sizes()
        .lookup(payload)
        .ok_or_else(|| unknown_marker_size(site, payload).with_field(&pointer))?;
    let marker = Marker::try_new(lookup.size_mm).map_err(|e| {
        Problem::new(ErrorCode::InvalidMarkerSize, e.to_string()).with_field(&pointer)
    })?;
    Ok((marker, lookup.source))
}

/// The model and image points a pose of `located` was solved from.
fn observed_points(
    located: &LocatedMarker,
    points_used: Points,
    marker: &Marker,
) -> Option<(Vec<MarkerPoint>, Vec<PixelPoint>)> {
    let r = &located.code.refinement;
    match points_used {
        Points::Finders => {
            let image = r.finder_corners_px?;
            let model = finder_marker_points(marker, r.module_count?);
            Some((model, image.to_vec()))
        }
        Points::Corners => {
            let quad = ImageQuad::try_new(*located.code.corners_px(), CornerOrder::Qr).ok()?;
            Some((marker.object_points().to_vec(), quad.paper_order().to_vec()))
        }
    }
}

/// The estimate after the request's prior, and whether the prior decided.
fn with_prior(
    estimate: PoseEstimate,
    located: &LocatedMarker,
    points_used: Points,
    setup: &Setup,
    context: &MarkerContext<'_>,
    payload: Option<&str>,
) -> (PoseEstimate, bool) {
    let prior = context
        .valid
        .prior
        .as_ref()
        .and_then(|p| context.view.rotation_prior(p, payload));
    let (Some(prior), Some((model, image))) =
        (prior, observed_points(located, points_used, &setup.marker))
    else {
        return (estimate, false);
    };
    let obs = Observation {
        model: &model,
        image: &image,
        camera: &setup.camera,
        marker: &setup.marker,
        corner_sigma_px: setup.solver.as_reprojection().corner_sigma_px,
    };
    match apply_prior(&estimate, &obs, &prior) {
        Some((with_prior, _)) => (with_prior, true),
        None => (estimate, false),
    }
}

/// Code `index` of a photo, sized, solved and carried into the site's frames.
pub fn marker_pose(
    located: &LocatedMarker,
    index: usize,
    context: &MarkerContext<'_>,
) -> MarkerPose {
    let payload = located.code.candidate.text.as_deref();
    let (marker, source) = match marker_of(payload, context, index) {
        Ok(m) => m,
        Err(problem) => {
            return MarkerPose {
                points_used: located.points_used,
                pose: None,
                problem: Some(problem),
                robot_in_world: None,
            };
        }
    };
    let setup = Setup {
        marker,
        ..context.valid.setup
    };
    let (points_used, solved, estimate_us) = if context.valid.size_from_request {
        (
            located.points_used,
            located.pose.clone(),
            located.estimate_us,
        )
    } else {
        let started = Instant::now();
        let (points_used, pose) = solve(&located.code, &setup, context.valid.options.points);
        (points_used, pose, started.elapsed().as_secs_f64() * 1e6)
    };
    let (solved, by_prior): (Result<PoseEstimate, MarkerError>, bool) = match solved {
        Ok(e) => {
            let (e, by_prior) = with_prior(e, located, points_used, &setup, context, payload);
            (Ok(e), by_prior)
        }
        Err(e) => (Err(e), false),
    };
    let (pose, problem) = marker_pose_or_problem(
        &solved,
        points_used,
        &setup.camera,
        &marker,
        estimate_us,
        index,
    );
    let Some((pose, Ok(estimate))) = pose.zip(Some(solved)) else {
        return MarkerPose {
            points_used,
            pose: None,
            problem,
            robot_in_world: None,
        };
    };
    let (in_robot, in_world) = context.view.frames(&estimate, payload);
    let list = match points_used {
        Points::Corners => "corners_px",
        Points::Finders => "finder_corners_px",
    };
    let frames = (
        in_robot.as_ref().map(FramePoseDto::from),
        in_world.as_ref().map(FramePoseDto::from),
    );
    match pose.with_site(
        MarkerSizeSourceDto::from(source),
        frames,
        by_prior,
        &format!("/markers/{index}/{list}"),
    ) {
        Ok(pose) => MarkerPose {
            points_used,
            pose: Some(pose),
            problem: None,
            robot_in_world: in_world,
        },
        Err(problem) => MarkerPose {
            points_used,
            pose: None,
            problem: Some(problem),
            robot_in_world: None,
        },
    }
}
