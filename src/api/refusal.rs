//! Refusals of the core and the detector as problem documents: the one place where an
//! [`EstimateError`], [`QuadError`], [`CameraError`], [`DecodeError`] or a marker's
//! [`MarkerError`] becomes a [`Problem`] with its stable code and the field at fault.
//!
//! Fields are JSON pointers into the request body (`/camera/fx_px`); the image query form
//! renames them to its parameters (`image::query`).

use super::context::unknown_marker_size;
use super::problem::{ErrorCode, Problem};
use crate::app::{CalibrateError, CornersError, HandEyeRequestError, ImageError, PhotoError};
use crate::detect::{
    DetectError,
    decode::DecodeError,
    pipeline::{MarkerError, Points},
};
use crate::estimate::EstimateError;
use crate::geometry::{
    camera::{CameraError, CameraParam},
    quad::QuadError,
};
use qrpose_calib::handeye::HandEyeError;
use qrpose_site::Site;

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

/// The problem for a corners request the application refused; `corners_pointer` names the
/// corner list.
pub fn problem_from_corners_error(
    err: CornersError,
    corners_pointer: &str,
    site: Option<&Site>,
    payload: Option<&str>,
) -> Problem {
    match err {
        CornersError::UnknownMarkerSize => {
            unknown_marker_size(site, payload).with_field("/payload")
        }
        CornersError::Estimate(e) => problem_from_estimate_error(e, corners_pointer),
    }
}

/// The problem for a photo the application could not read at all.
pub fn problem_from_image_error(err: &ImageError) -> Problem {
    match err {
        ImageError::Decode(e) => problem_from_decode_error(e),
        ImageError::Detect(e) => problem_from_detect_error(e),
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
/// `field` points at the marker's corners or finder corners in the response, or at its
/// payload for a code the site cannot size.
pub fn problem_from_marker_error(
    err: MarkerError,
    index: usize,
    site: Option<&Site>,
    payload: Option<&str>,
) -> Problem {
    match err {
        MarkerError::UnknownSize => {
            unknown_marker_size(site, payload).with_field(format!("/markers/{index}/payload"))
        }
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

/// The multipart part (and `qrpose calibrate` argument) of a calibration's photos.
const PHOTOS_PART: &str = "image";

/// The problem of a photo that could not be read (`image/K`), or of a calibration cancelled
/// while they were read.
fn problem_from_photo_error(err: &PhotoError) -> Problem {
    let photo = |index: usize| format!("{PHOTOS_PART}/{index}");
    match err {
        PhotoError::Decode { index, source } => {
            let problem = problem_from_decode_error(source);
            Problem::new(problem.code, err.to_string()).with_field(photo(*index))
        }
        PhotoError::MixedSizes { index, .. } => {
            Problem::new(ErrorCode::MixedImageSizes, err.to_string()).with_field(photo(*index))
        }
        PhotoError::Cancelled => Problem::new(ErrorCode::Timeout, err.to_string()),
    }
}

/// The problem for photos the application could not calibrate from; `field` names the part
/// `image` (the photos), with the photo's index where one photo is at fault.
pub fn problem_from_calibrate_error(err: &CalibrateError) -> Problem {
    match err {
        CalibrateError::TooFewPhotos { .. } | CalibrateError::TooFewViews { .. } => {
            Problem::new(ErrorCode::TooFewViews, err.to_string()).with_field(PHOTOS_PART)
        }
        CalibrateError::TooManyPhotos { .. } => {
            Problem::new(ErrorCode::TooManyImages, err.to_string()).with_field(PHOTOS_PART)
        }
        CalibrateError::Photo(e) => problem_from_photo_error(e),
        CalibrateError::NoCodeFound { .. } => {
            Problem::new(ErrorCode::NoCodeFound, err.to_string()).with_field(PHOTOS_PART)
        }
        CalibrateError::Calibration(e) => match e {
            qrpose_calib::CalibrationError::TooFewViews { .. } => {
                Problem::new(ErrorCode::TooFewViews, err.to_string()).with_field(PHOTOS_PART)
            }
            _ => Problem::new(ErrorCode::CalibrationFailed, err.to_string()),
        },
    }
}

/// The problem document of a hand-eye calibration that gave no answer; `field` names the
/// photo (`image/K`), the photos (`image`) or the flange poses.
pub fn problem_from_hand_eye_error(err: &HandEyeRequestError) -> Problem {
    match err {
        HandEyeRequestError::FlangePosesMismatch { .. } => {
            Problem::new(ErrorCode::FlangePosesMismatch, err.to_string())
                .with_field("/flange_poses")
        }
        HandEyeRequestError::TooFewPhotos { .. } => {
            Problem::new(ErrorCode::TooFewViews, err.to_string()).with_field(PHOTOS_PART)
        }
        HandEyeRequestError::TooManyPhotos { .. } => {
            Problem::new(ErrorCode::TooManyImages, err.to_string()).with_field(PHOTOS_PART)
        }
        HandEyeRequestError::Photo(e) => problem_from_photo_error(e),
        HandEyeRequestError::NoCodeFound { .. } => {
            Problem::new(ErrorCode::NoCodeFound, err.to_string()).with_field(PHOTOS_PART)
        }
        HandEyeRequestError::Solve(e) => match e {
            HandEyeError::TooFewViews { .. } => {
                Problem::new(ErrorCode::TooFewViews, err.to_string()).with_field(PHOTOS_PART)
            }
            HandEyeError::DegenerateMotion { .. } => {
                Problem::new(ErrorCode::DegenerateMotion, err.to_string())
                    .with_field("/flange_poses")
            }
            HandEyeError::NonFinite { .. } | HandEyeError::InvalidOption { .. } => {
                Problem::new(ErrorCode::NumericallyDegenerate, err.to_string())
            }
            HandEyeError::InvalidCamera => {
                Problem::new(ErrorCode::IncompleteCamera, err.to_string()).with_field("/camera")
            }
            HandEyeError::SolveFailed(_) => {
                Problem::new(ErrorCode::CalibrationFailed, err.to_string())
            }
        },
    }
}
