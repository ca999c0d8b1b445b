//! The problem codes each operation refuses a request with (422): the one list the served
//! document's 422 responses are written from (`crate::http::openapi`, `x-problem-codes`)
//! and that the API tests check every refusal they see against.

use super::ErrorCode::{self, *};

/// An operation that refuses requests with 422.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operation {
    /// `POST /v1/pose/corners`.
    Corners,
    /// `POST /v1/pose/image`.
    Image,
    /// `POST /v1/pose/image/annotated`.
    Annotated,
    /// `POST /v1/calibrate`.
    Calibrate,
    /// `POST /v1/calibrate/hand-eye`.
    HandEye,
    /// `POST /v1/site/reload`.
    SiteReload,
}

/// Every operation.
pub const OPERATIONS: [Operation; 6] = [
    Operation::Corners,
    Operation::Image,
    Operation::Annotated,
    Operation::Calibrate,
    Operation::HandEye,
    Operation::SiteReload,
];

/// A JSON document that does not fit its types (`ShapeKind`).
const SHAPE: [ErrorCode; 5] = [
    MissingField,
    UnknownField,
    InvalidType,
    UnknownVariant,
    NonFiniteNumber,
];
/// A camera that is not one, or not the site's.
const CAMERA: [ErrorCode; 3] = [IncompleteCamera, InvalidCameraParameter, UnknownCamera];
/// The solver's parameters and the picking fields of a pose request.
const POSE: [ErrorCode; 6] = [
    InvalidMarkerSize,
    SolverParameterOutOfRange,
    InvalidPrior,
    InvalidRobotPose,
    InvalidGraspProbability,
    NumericallyDegenerate,
];
/// What an image request adds.
const IMAGE: [ErrorCode; 4] = [
    UndecodableImage,
    DetectorUnavailable,
    PointsNeedReprojection,
    InvalidDetectionBudget,
];
/// What a set of photos of a printed code may be refused for.
const PHOTOS: [ErrorCode; 5] = [
    UndecodableImage,
    TooFewViews,
    TooManyImages,
    MixedImageSizes,
    NoCodeFound,
];

impl Operation {
    /// The route, as the document names it.
    pub const fn path(self) -> &'static str {
        match self {
            Self::Corners => "/v1/pose/corners",
            Self::Image => "/v1/pose/image",
            Self::Annotated => "/v1/pose/image/annotated",
            Self::Calibrate => "/v1/calibrate",
            Self::HandEye => "/v1/calibrate/hand-eye",
            Self::SiteReload => "/v1/site/reload",
        }
    }

    /// The operation of the route `path`, if it has one here.
    pub fn of_path(path: &str) -> Option<Self> {
        OPERATIONS.into_iter().find(|o| o.path() == path)
    }

    /// The codes of its 422 answers, in a fixed order.
    pub fn unprocessable(self) -> Vec<ErrorCode> {
        let mut codes = Vec::new();
        match self {
            Self::Corners => {
                codes.extend(SHAPE);
                codes.extend([
                    CornersMissingOrConflicting,
                    CornerCount,
                    DuplicateCorners,
                    CollinearCorners,
                    SelfIntersectingCorners,
                    NonConvexCorners,
                    MirroredCorners,
                    UndistortionFailed,
                    NoSolution,
                    UnknownMarkerSize,
                ]);
                codes.extend(CAMERA);
                codes.extend(POSE);
            }
            Self::Image | Self::Annotated => {
                codes.extend(SHAPE);
                codes.extend(IMAGE);
                codes.extend(CAMERA);
                codes.extend(POSE);
            }
            Self::Calibrate => {
                codes.extend(SHAPE);
                codes.extend(PHOTOS);
                codes.extend([InvalidMarkerSize, CalibrationFailed]);
            }
            Self::HandEye => {
                codes.extend(SHAPE);
                codes.extend(PHOTOS);
                codes.extend(CAMERA);
                codes.extend([
                    InvalidMarkerSize,
                    UnknownMarkerSize,
                    FlangePosesMismatch,
                    DegenerateMotion,
                    InvalidRobotPose,
                    SolverParameterOutOfRange,
                    NumericallyDegenerate,
                    CalibrationFailed,
                ]);
            }
            Self::SiteReload => codes.push(InvalidSite),
        }
        codes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_code_is_a_422_listed_once_and_every_path_is_found() {
        for operation in OPERATIONS {
            let codes = operation.unprocessable();
            for (k, code) in codes.iter().enumerate() {
                assert_eq!(code.status(), 422, "{operation:?}: {code:?}");
                assert!(!codes[..k].contains(code), "{operation:?}: {code:?} twice");
            }
            assert_eq!(Operation::of_path(operation.path()), Some(operation));
        }
        assert_eq!(Operation::of_path("/v1/site"), None);
    }
}
