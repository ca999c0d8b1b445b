//! [`CalibrationError`]: why no calibration was returned. Problems that still leave a
//! calibration (a poorly constrained set, a view dropped, an iteration budget spent) are not
//! errors but data: [`crate::Warning`] and [`crate::DropReason`].

use thiserror::Error;

/// Why the solve could not produce a camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum SolveFailure {
    /// The closed form found no positive focal length, even with the principal point at the
    /// image centre and fx = fy: the homographies carry no perspective (every view is
    /// fronto-parallel), so focal length and distance cannot be told apart.
    #[error(
        "the views determine no focal length: every view faces the camera squarely (tilt the code between photos)"
    )]
    FocalLengthUndetermined,
    /// A point of the initial estimate lies behind the camera, or its residual is not a
    /// finite number.
    #[error("the initial estimate does not project every point into the image")]
    NonFiniteStart,
    /// The normal equations could not be factored at any damping.
    #[error("the normal equations are singular at every damping")]
    SingularSystem,
    /// The fit ended with a focal length that is not positive, or a parameter that is not
    /// finite.
    #[error("the fit ended with an invalid camera")]
    InvalidCamera,
}

/// Why a calibration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum CalibrationError {
    /// The image width or height is zero.
    #[error("image size {width_px} x {height_px} px: both must be positive")]
    InvalidImageSize {
        /// Width given, px.
        width_px: u32,
        /// Height given, px.
        height_px: u32,
    },
    /// A target or pixel coordinate is NaN or infinite.
    #[error("view {view}, point {point}: a coordinate is not a finite number")]
    NonFinite {
        /// The view, 0-based, in the order given.
        view: usize,
        /// The point within it, 0-based.
        point: usize,
    },
    /// A view has fewer correspondences than [`crate::MIN_POINTS_PER_VIEW`].
    #[error("view {view} has {points} points; a view needs at least {required}")]
    TooFewPoints {
        /// The view, 0-based.
        view: usize,
        /// How many points it has.
        points: usize,
        /// How many it needs.
        required: usize,
    },
    /// Fewer than [`crate::MIN_VIEWS`] views were given, or remain once the views whose
    /// homography fails or which do not fit are dropped.
    #[error(
        "{usable} usable views of {given} given; a calibration needs at least {required} (take more photos, tilted differently)"
    )]
    TooFewViews {
        /// Views given.
        given: usize,
        /// Views left to calibrate with.
        usable: usize,
        /// Views needed.
        required: usize,
    },
    /// The numerical solve failed.
    #[error("calibration failed: {reason}")]
    SolveFailed {
        /// What failed.
        reason: SolveFailure,
    },
}

impl From<SolveFailure> for CalibrationError {
    fn from(reason: SolveFailure) -> Self {
        Self::SolveFailed { reason }
    }
}
