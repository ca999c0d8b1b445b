//! Refusals of the core and the detector as problem documents: the one place where an
//! [`EstimateError`], [`QuadError`], [`CameraError`], [`DecodeError`] or a marker's
//! [`MarkerError`] becomes a [`Problem`] with its stable code and the field at fault.
//!
//! Fields are JSON pointers into the request body (`/camera/fx_px`); the image query form
//! renames them to its parameters (`image::query`).

use super::problem::{ErrorCode, Problem};
use super::response::PoseResponse;
use crate::detect::{
    DetectError,
    decode::DecodeError,
    pipeline::{MarkerError, Points},
};
use crate::estimate::{EstimateError, PoseEstimate};
use crate::geometry::{
    camera::{Camera, CameraError, CameraParam},
    marker::Marker,
    quad::QuadError,
};

/// The JSON pointer of a camera parameter below the camera object.
fn camera_param_name(param: CameraParam) -> String {
    if param.is_distortion() {
        format!("distortion/{param}")
    } else {
        param.name().to_owned()
    }
}

/// The problem for a refused camera parameter, under the JSON pointer `camera_pointer`.
pub fn problem_from_camera_error(err: CameraError, camera_pointer: &str) -> Problem {
    match err {
        CameraError::NonFinite { param } => {
            Problem::new(ErrorCode::NonFiniteNumber, err.to_string())
                .with_field(format!("{camera_pointer}/{}", camera_param_name(param)))
        }
        CameraError::NonPositive { param, value } => Problem::new(
            ErrorCode::InvalidCameraParameter,
            format!("{} must be positive, got {value}", camera_param_name(param)),
        )
        .with_field(format!("{camera_pointer}/{}", camera_param_name(param))),
        CameraError::UndistortionFailed { .. } => {
            Problem::new(ErrorCode::UndistortionFailed, err.to_string())
        }
    }
}

/// The problem for an estimator refusal; `corners_pointer` names the corner list.
pub fn problem_from_estimate_error(err: EstimateError, corners_pointer: &str) -> Problem {
    match err {
        EstimateError::ParamOutOfRange {
            param,
            value,
            min_exclusive,
            max,
        } => {
            let name = param.name();
            Problem::new(
                ErrorCode::SolverParameterOutOfRange,
                format!(
                    "{name} must be greater than {min_exclusive} and at most {max}, got {value}"
                ),
            )
            .with_field(format!("/solver/{name}"))
        }
        EstimateError::Undistortion { index, source } => {
            Problem::new(ErrorCode::UndistortionFailed, source.to_string())
                .with_field(format!("{corners_pointer}/{index}"))
        }
        EstimateError::PointCount { .. } => {
            Problem::new(ErrorCode::CornerCount, err.to_string()).with_field(corners_pointer)
        }
        EstimateError::NoSolution { .. } => {
            Problem::new(ErrorCode::NoSolution, err.to_string()).with_field(corners_pointer)
        }
    }
}

/// The problem for a refused quadrilateral; `corners_pointer` names the corner list.
pub fn problem_from_quad_error(err: QuadError, corners_pointer: &str) -> Problem {
    let (code, index) = match err {
        QuadError::NonFinite { index } => (ErrorCode::NonFiniteNumber, Some(index)),
        QuadError::Duplicate { second, .. } => (ErrorCode::DuplicateCorners, Some(second)),
        QuadError::Collinear { indices } => (ErrorCode::CollinearCorners, Some(indices[2])),
        QuadError::SelfIntersecting => (ErrorCode::SelfIntersectingCorners, None),
        QuadError::NonConvex { index } => (ErrorCode::NonConvexCorners, Some(index)),
        QuadError::Mirrored => (ErrorCode::MirroredCorners, None),
    };
    let field = match index {
        Some(i) => format!("{corners_pointer}/{i}"),
        None => corners_pointer.to_owned(),
    };
    Problem::new(code, err.to_string()).with_field(field)
}

/// The problem for an image that could not be decoded.
pub fn problem_from_decode_error(err: &DecodeError) -> Problem {
    let code = match err {
        DecodeError::EncodedTooLarge { .. } => ErrorCode::PayloadTooLarge,
        DecodeError::TooManyPixels { .. } => ErrorCode::ImageTooLarge,
        DecodeError::Empty
        | DecodeError::ZeroSize { .. }
        | DecodeError::UnsupportedFormat
        | DecodeError::Corrupt { .. } => ErrorCode::UndecodableImage,
    };
    Problem::new(code, err.to_string())
}

/// The problem for a detector that cannot run (not in this build).
pub fn problem_from_detect_error(err: &DetectError) -> Problem {
    Problem::new(ErrorCode::DetectorUnavailable, err.to_string()).with_field("/detector")
}

/// The problem of marker `index` of an image response, whose pose could not be solved; its
/// `field` points at the marker's corners or finder corners in the response.
pub fn problem_from_marker_error(err: MarkerError, index: usize) -> Problem {
    match err {
        MarkerError::Corners(e) => {
            problem_from_quad_error(e, &format!("/markers/{index}/corners_px"))
        }
        MarkerError::Estimate { points, source } => {
            let list = match points {
                Points::Corners => "corners_px",
                Points::Finders => "finder_corners_px",
            };
            problem_from_estimate_error(source, &format!("/markers/{index}/{list}"))
        }
    }
}

/// The `pose` and `problem` of marker `index` of an image response, solved from
/// `points_used`: the wire pose when it was solved and every number of it is finite;
/// otherwise `pose: null` and the marker's own problem (its [`MarkerError`], or 422
/// `numerically_degenerate` naming its corners when a number came out NaN or infinite).
pub fn marker_pose_or_problem(
    pose: &Result<PoseEstimate, MarkerError>,
    points_used: Points,
    camera: &Camera,
    marker: &Marker,
    elapsed_us: f64,
    index: usize,
) -> (Option<PoseResponse>, Option<Problem>) {
    let list = match points_used {
        Points::Corners => "corners_px",
        Points::Finders => "finder_corners_px",
    };
    match pose {
        Ok(estimate) => {
            let pointer = format!("/markers/{index}/{list}");
            match PoseResponse::try_new(estimate, camera, marker, elapsed_us, &pointer) {
                Ok(pose) => (Some(pose), None),
                Err(problem) => (None, Some(problem)),
            }
        }
        Err(err) => (None, Some(problem_from_marker_error(*err, index))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::{ValidSolver, estimate_pose};
    use crate::geometry::{frames::PixelPoint, marker::CornerOrder, quad::ImageQuad};

    #[test]
    fn a_marker_pose_with_a_non_finite_number_is_null_with_its_problem() {
        let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("camera");
        let marker = Marker::try_new(50.0).expect("marker");
        let corners = [
            (589.2, 309.8),
            (689.9, 311.4),
            (688.1, 411.6),
            (588.0, 409.5),
        ]
        .map(|(u, v)| PixelPoint::new(u, v));
        let quad = ImageQuad::try_new(corners, CornerOrder::Qr).expect("quad");
        let good: Result<PoseEstimate, MarkerError> =
            Ok(estimate_pose(&quad, &camera, &marker, &ValidSolver::default()).expect("a pose"));
        let (pose, problem) =
            marker_pose_or_problem(&good, Points::Corners, &camera, &marker, 1.0, 0);
        assert!(pose.is_some() && problem.is_none());

        let mut spoiled = good.clone();
        if let Ok(estimate) = spoiled.as_mut() {
            estimate.centre_mm.z = f64::NAN;
        }
        let (pose, problem) =
            marker_pose_or_problem(&spoiled, Points::Finders, &camera, &marker, 1.0, 3);
        assert!(pose.is_none());
        let problem = problem.expect("a problem");
        assert_eq!(problem.code, ErrorCode::NumericallyDegenerate);
        assert_eq!(
            problem.field.as_deref(),
            Some("/markers/3/finder_corners_px")
        );
        assert!(
            problem.detail.contains("/position_mm/z"),
            "{}",
            problem.detail
        );
    }
}
