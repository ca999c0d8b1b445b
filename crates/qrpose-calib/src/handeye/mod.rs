//! Hand-eye calibration: where a camera sits on a robot, from photos of one printed code
//! and the flange poses the robot's controller reported for them (`docs/hand-eye.md`).
//!
//! Two setups ([`HandEyeSetup`]): **eye-in-hand**, the camera on the flange and the code
//! still in the robot's frame; **eye-to-hand**, the camera still and the code held by the
//! flange. Frames: `robot` (the controller's base frame), `flange`, `camera` (x right,
//! y down, z forward) and `marker` (the symbol's centre, axes as `docs/conventions.md`).
//! Transforms are T_parent←child, p_parent = R·p_child + t, mm. The answer
//! ([`HandEyeCalibration`]) gives the camera's pose (T_flange←camera or T_robot←camera),
//! the code's (T_robot←marker or T_flange←marker), the camera pose's covariance and
//! standard deviations, per-view residuals and warnings; [`site_mount_yaml`] writes the
//! site file's `mount:` block.
//!
//! | module | owns |
//! |---|---|
//! | `input` | the setup, the views, the options and their defaults |
//! | `rigid` | transforms, their compositions and the Jacobians of the compositions |
//! | `closed_form` | each view's pose of the code; Park and Martin's mount; the target from it |
//! | `motion` | the two-axes check (`degenerate_motion`), the rotation spread |
//! | `joint` | the robust Levenberg-Marquardt over mount, target and flange corrections; the covariance |
//! | `calibrate` | checks, rounds of outlier views, warnings, assembly ([`calibrate_hand_eye`]) |
//! | `outliers` | each view's residuals, the outlier test, the code's share of the image |
//! | `report` | the answer, warnings, errors, the `mount:` YAML |
//!
//! The method: each view's pose of the code from its points (homography, then the
//! reprojection through the camera's lens); the mount from the relative motions in closed
//! form (Park and Martin 1994) and the target from the mount; then one robust (Huber)
//! Levenberg-Marquardt over the mount, the target and every view's true flange pose, whose
//! residuals are every point's reprojection error (px, through the lens, whitened by the
//! estimated pixel noise) and each flange pose's difference from the reported one
//! (whitened by the flange noise of [`FlangeNoise`]). The mount's covariance is the
//! Gauss-Newton inverse at the solution, marginalised over the rest.

mod calibrate;
mod closed_form;
mod input;
mod joint;
mod motion;
mod outliers;
mod report;
mod rigid;

pub use calibrate::{MIN_ROTATION_SPREAD_RAD, RECOMMENDED_HAND_EYE_VIEWS, calibrate_hand_eye};
pub use input::{
    DEFAULT_FLANGE_ROTATION_STD_RAD, DEFAULT_FLANGE_TRANSLATION_STD_MM,
    DEFAULT_HAND_EYE_MAX_ITERATIONS, FlangeNoise, HandEyeOptions, HandEyeSetup, HandEyeView,
    MIN_HAND_EYE_POINTS, MIN_HAND_EYE_VIEWS,
};
pub use motion::{MIN_AXIS_ROTATION_RAD, MIN_AXIS_SPREAD_RAD};
pub use outliers::{
    MAX_OUTLIER_FRACTION, MIN_CODE_AREA_FRACTION, OUTLIER_FLANGE_SIGMAS, OUTLIER_RMS_FLOOR_PX,
    OUTLIER_RMS_RATIO,
};
pub use report::{
    HandEyeCalibration, HandEyeError, HandEyeViewReport, HandEyeWarning, site_mount_yaml,
};
