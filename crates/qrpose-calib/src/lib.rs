//! qrpose-calib: camera calibration from views of one planar target with known points, such
//! as a printed QR code (finder-pattern corners, alignment centres, module edges).
//!
//! [`calibrate`] takes views (each a list of [`Correspondence`]s: a target point in mm on
//! the plane z = 0 and its measured pixel), the image size and [`Options`] (the lens model:
//! `plumb_bob`, `rational_polynomial` or `equidistant`, exactly as qrpose-core implements
//! them), and returns a [`CameraCalibration`]: qrpose-core's [`Camera`] (fx, fy, cx, cy and
//! the lens), one standard deviation per parameter, every view's pose and every point's
//! measurement, residual and robust weight ([`PointFit`]; or why the view was dropped),
//! the reprojection RMS and [`Warning`]s. The method is Zhang's (Z. Zhang, "A flexible
//! new technique for camera calibration", IEEE TPAMI 22(11), 2000):
//!
//! | module | owns |
//! |---|---|
//! | qrpose-core's [`fit_homography_dlt`] | each view's plane-to-image homography (Zhang Eq. 2), lens ignored: a start only, `lm` refines all views at once (not Zhang's per-view ML, Appendix A) |
//! | `zhang` | closed-form intrinsics (Eqs. 3-9, Appendix B), poses (Sec. 3.1, Appendix C), fallbacks |
//! | `distortion_init` | the linear radial estimate (Sec. 3.3, Eq. 13) |
//! | `fisheye_init` | the closed form iterated on pinhole-equivalent pixels for the fisheye model |
//! | `model`, `lens` | the projection fitted (Eq. 14 with qrpose-core's lens) and its analytic Jacobian |
//! | `lm` | one Levenberg-Marquardt over intrinsics and poses, Schur complement on the poses |
//! | `robust` | Huber's loss, its scale, IRLS weights |
//! | `fit` | closed form → radial estimate → robust rounds |
//! | `covariance` | the intrinsics' covariance, cluster-robust over patches of the target (CR2 sandwich) |
//! | `calibrate` | input checks, dropping views that do not fit, standard deviations, assembly |
//! | [`warnings`] | the warnings, their thresholds, the image coverage |
//! | [`compare`] | the distortion-field difference of two cameras, px |
//! | [`handeye`] | hand-eye calibration: a camera's mount on a robot from photos of a code and the flange poses (`docs/hand-eye.md`) |
//!
//! Conventions: pixels as in `docs/conventions.md` (u right, v down, integer coordinates at
//! pixel centres); camera frame x right, y down, z forward; poses `p_cam = R·p_target + t`,
//! mm; angles in radians. No skew: qrpose's camera has none (Zhang's γ is dropped after the
//! closed form). Nothing here is asynchronous or does I/O.
//!
//! [`Camera`]: qrpose_core::geometry::camera::Camera
//! [`fit_homography_dlt`]: qrpose_core::geometry::homography::fit_homography_dlt

#![warn(missing_docs)]

mod calibrate;
pub mod compare;
mod covariance;
mod distortion_init;
mod error;
mod fisheye_init;
mod fit;
pub mod handeye;
mod input;
mod lens;
mod lm;
mod model;
mod result;
mod robust;
pub mod warnings;
mod zhang;

pub use calibrate::{DROP_FLOOR_PX, DROP_RATIO, calibrate};
pub use covariance::BLOCKS_PER_SIDE;
pub use error::{CalibrationError, SolveFailure};
pub use fit::{MAX_ROBUST_ROUNDS, SCALE_SETTLED};
pub use input::{
    Correspondence, DEFAULT_MAX_ITERATIONS, ImageSize, MIN_POINTS_PER_VIEW, MIN_VIEWS, Options,
    View,
};
pub use result::{
    CameraCalibration, DropReason, ParameterStd, PointFit, ViewFit, ViewOutcome, ViewReport,
};
pub use robust::{HUBER_K, SCALE_FLOOR_PX};
pub use warnings::{Coverage, ImageCorner, Warning};
pub use zhang::ClosedFormAssumption;

/// The README example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
