//! What a hand-eye calibration is given: the setup, the views (each the points read in one
//! photo and the flange pose the controller reported for it) and the options.

use super::report::HandEyeError;
use crate::input::Correspondence;
use nalgebra::Isometry3;

/// Fewest views with the code read that a hand-eye calibration is attempted with: the
/// mount's rotation needs two relative motions about distinct axes (three views), and a
/// fourth leaves the closed form over-determined so that one poor view shows.
pub const MIN_HAND_EYE_VIEWS: usize = 4;

/// Fewest correspondences a view needs to be used: twice the four a homography needs, so
/// that the view's own pose is over-determined. Views with fewer count as not read.
pub const MIN_HAND_EYE_POINTS: usize = 8;

/// Default standard deviation of each coordinate of a reported flange position, mm
/// (a repeatable industrial arm of 0.02-0.05 mm repeatability reports its pose within
/// about this, its absolute accuracy dominating).
pub const DEFAULT_FLANGE_TRANSLATION_STD_MM: f64 = 0.2;

/// Default standard deviation of a reported flange orientation about each axis, rad (0.02°).
pub const DEFAULT_FLANGE_ROTATION_STD_RAD: f64 = 0.02 * std::f64::consts::PI / 180.0;

/// Levenberg-Marquardt iterations allowed in each robust round by default; a good session
/// converges in 3-10.
pub const DEFAULT_HAND_EYE_MAX_ITERATIONS: usize = 100;

/// Where the camera is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HandEyeSetup {
    /// The camera rides on the flange; the code lies still in the robot's frame.
    EyeInHand,
    /// The camera stands still in the robot's frame; the flange holds the code.
    EyeToHand,
}

impl HandEyeSetup {
    /// The stable snake_case name (`eye_in_hand`, `eye_to_hand`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::EyeInHand => "eye_in_hand",
            Self::EyeToHand => "eye_to_hand",
        }
    }

    /// The frame the camera's pose is given in: `flange` (eye-in-hand) or `robot`.
    #[must_use]
    pub const fn camera_parent(self) -> &'static str {
        match self {
            Self::EyeInHand => "flange",
            Self::EyeToHand => "robot",
        }
    }

    /// The frame the target's pose is given in: `robot` (eye-in-hand) or `flange`.
    #[must_use]
    pub const fn target_parent(self) -> &'static str {
        match self {
            Self::EyeInHand => "robot",
            Self::EyeToHand => "flange",
        }
    }
}

/// One photo: the points of the code read in it, and where the flange was.
#[derive(Debug, Clone, PartialEq)]
pub struct HandEyeView {
    /// The code's points: target points in mm in qrpose-detect's marker frame (the paper's,
    /// origin at corner P2, `TargetPoint::marker` x and y, the code's plane z = 0) and their
    /// measured pixels. Empty (or fewer than [`MIN_HAND_EYE_POINTS`]) when the code was not
    /// read: the view is then reported but not used.
    pub correspondences: Vec<Correspondence>,
    /// T_robot←flange as the controller reported it, mm: p_robot = R·p_flange + t.
    pub flange_pose: Isometry3<f64>,
}

/// The standard deviations of a reported flange pose, per axis (the prior of the joint
/// fit: each reported pose is taken as the true one plus independent Gaussian errors of
/// these standard deviations, rotation about and translation along each robot axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlangeNoise {
    /// Standard deviation of each position coordinate, mm.
    pub translation_std_mm: f64,
    /// Standard deviation of the rotation about each axis, rad.
    pub rotation_std_rad: f64,
}

impl Default for FlangeNoise {
    fn default() -> Self {
        Self {
            translation_std_mm: DEFAULT_FLANGE_TRANSLATION_STD_MM,
            rotation_std_rad: DEFAULT_FLANGE_ROTATION_STD_RAD,
        }
    }
}

/// How to calibrate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandEyeOptions {
    /// The flange poses' noise ([`FlangeNoise::default`]: 0.2 mm and 0.02° per axis).
    pub flange_noise: FlangeNoise,
    /// The pixel noise scale of Huber's loss, px per axis; `None` (default): estimated from
    /// the residuals (median-based, re-estimated until it settles, as the camera
    /// calibration does).
    pub loss_scale_px: Option<f64>,
    /// Levenberg-Marquardt iterations allowed in each robust round
    /// ([`DEFAULT_HAND_EYE_MAX_ITERATIONS`]).
    pub max_iterations: usize,
}

impl Default for HandEyeOptions {
    fn default() -> Self {
        Self {
            flange_noise: FlangeNoise::default(),
            loss_scale_px: None,
            max_iterations: DEFAULT_HAND_EYE_MAX_ITERATIONS,
        }
    }
}

pub(super) fn check_options(options: &HandEyeOptions) -> Result<(), HandEyeError> {
    let checks = [
        (
            "translation_std_mm",
            options.flange_noise.translation_std_mm,
        ),
        ("rotation_std_rad", options.flange_noise.rotation_std_rad),
        ("loss_scale_px", options.loss_scale_px.unwrap_or(1.0)),
    ];
    for (name, value) in checks {
        if !(value.is_finite() && value > 0.0) {
            return Err(HandEyeError::InvalidOption { name, value });
        }
    }
    if options.max_iterations == 0 {
        return Err(HandEyeError::InvalidOption {
            name: "max_iterations",
            value: 0.0,
        });
    }
    Ok(())
}

pub(super) fn check_finite(views: &[HandEyeView]) -> Result<(), HandEyeError> {
    for (view, v) in views.iter().enumerate() {
        let pose_ok = v
            .flange_pose
            .translation
            .vector
            .iter()
            .all(|x| x.is_finite())
            && v.flange_pose.rotation.coords.iter().all(|x| x.is_finite());
        let points_ok = v.correspondences.iter().all(|c| {
            [c.target_mm.x, c.target_mm.y, c.pixel_px.u(), c.pixel_px.v()]
                .iter()
                .all(|x| x.is_finite())
        });
        if !(pose_ok && points_ok) {
            return Err(HandEyeError::NonFinite { view });
        }
    }
    Ok(())
}
