//! Picking (`docs/site.md`, Picking): from a product's code seen by a camera to its box and
//! its grasps in the robot's frame, each with the probability that it lies within its
//! tolerance, and whether to grasp.
//!
//! The chain, in [`crate::transform`]'s convention (a pose's 6×6 covariance over
//! (δθ rad, δt mm) in its output frame's axes, carried to first order through every step):
//! - object in camera: T_camera←object = T_camera←marker · T_object←marker⁻¹ (exact right
//!   factor: the code's rotation error becomes position error at the lever arm from the
//!   code's centre to the box's);
//! - grasp in camera: T_camera←grasp = T_camera←marker · (T_object←marker⁻¹ · T_object←grasp);
//! - camera in robot: the mount ([`crate::mount::CameraMount::camera_in_robot`]: itself, or
//!   T_robot←flange · T_flange←camera), with the mount's own covariance when it has a
//!   standard deviation;
//! - in robot: T_robot←x = T_robot←camera · T_camera←x, both uncertain
//!   ([`crate::transform::compose`]);
//! - pre-grasp: T_robot←grasp · Trans(0, 0, −approach_mm).
//!
//! Each grasp's probability is [`probability::within_tolerance_probability`] of its pose in
//! the robot frame (the tolerance is the robot's), or in the camera frame when there is none,
//! times the probability that the code's pose is not the planar ambiguity's mirror
//! ([`PickOptions::alternative_probability`]): a pose the estimate cannot tell from its
//! mirror is never graspable, however small its covariance.
//! A grasp is graspable only when that probability reaches the minimum and no
//! [`PickReason`] applies.

pub mod probability;

use crate::mount::CameraMount;
use crate::objects::{GraspKind, ObjectRule};
use crate::transform::{PoseWithCovariance, Rigid, compose, then_fixed};
use nalgebra::{Rotation3, Vector3};
use thiserror::Error;

pub use probability::within_tolerance_probability;

/// The default least probability of being within tolerance for a grasp to be graspable.
pub const DEFAULT_MIN_GRASP_PROBABILITY: f64 = 0.95;

/// Why a grasp is not graspable; `as_str` is the stable wire code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PickReason {
    /// The camera's pose in the robot frame is unknown: no mount, or a flange mount without
    /// the flange's pose.
    NoRobotPose,
    /// The code's pose was ambiguous (the planar flip was not resolved).
    PoseAmbiguous,
    /// The probability of being within tolerance is below the minimum, or unknown (the
    /// estimate has no covariance).
    BelowProbability,
    /// The code's pose estimate did not converge.
    NotConverged,
    /// The code's pose fits its corners worse than their stated noise allows (a corner
    /// measured wrong): the covariance, and so the probability, cannot be trusted.
    HighReprojectionError,
}

impl PickReason {
    /// `no_robot_pose`, `pose_ambiguous`, `below_probability`, `not_converged`,
    /// `high_reprojection_error`.
    pub const fn as_str(self) -> &'static str {
        match self {
            PickReason::NoRobotPose => "no_robot_pose",
            PickReason::PoseAmbiguous => "pose_ambiguous",
            PickReason::BelowProbability => "below_probability",
            PickReason::NotConverged => "not_converged",
            PickReason::HighReprojectionError => "high_reprojection_error",
        }
    }
}

/// What the caller knows about the code's estimate, and the bar a grasp must clear.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PickOptions {
    /// Least probability of being within tolerance, in [0, 1].
    pub min_grasp_probability: f64,
    /// The estimate could not tell the code's pose from its mirror.
    pub pose_ambiguous: bool,
    /// The estimate did not converge.
    pub not_converged: bool,
    /// The estimate fits its corners worse than their stated noise allows.
    pub high_reprojection_error: bool,
    /// The probability that the code's true pose is the planar ambiguity's other one (the
    /// mirror, tens of degrees away: no grasp planned from this pose lands within tolerance
    /// then), in [0, 1]; 0 when there is none.
    pub alternative_probability: f64,
}

impl Default for PickOptions {
    fn default() -> Self {
        Self {
            min_grasp_probability: DEFAULT_MIN_GRASP_PROBABILITY,
            pose_ambiguous: false,
            not_converged: false,
            high_reprojection_error: false,
            alternative_probability: 0.0,
        }
    }
}

/// Why no plan was made.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum PickError {
    /// `min_grasp_probability` outside [0, 1] (or NaN).
    #[error("min_grasp_probability must be between 0 and 1, got {value}")]
    MinGraspProbability {
        /// The value given.
        value: f64,
    },
    /// `alternative_probability` outside [0, 1] (or NaN).
    #[error("alternative_probability must be between 0 and 1, got {value}")]
    AlternativeProbability {
        /// The value given.
        value: f64,
    },
}

/// One grasp of the object, planned.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspPlan {
    /// The grasp's name.
    pub name: String,
    /// Its gripper.
    pub kind: GraspKind,
    /// T_camera←grasp.
    pub pose: PoseWithCovariance,
    /// T_robot←grasp, when the camera's pose in the robot frame is known.
    pub pose_in_robot: Option<PoseWithCovariance>,
    /// T_robot←pre-grasp: `approach_mm` back along the grasp's −z; `None` without
    /// `approach_mm` or without the robot frame.
    pub pre_grasp_in_robot: Option<PoseWithCovariance>,
    /// The opening of a parallel gripper, mm.
    pub width_mm: Option<f64>,
    /// P(within tolerance), in the robot frame when known, else the camera frame; `None`
    /// without a covariance.
    pub within_tolerance_probability: Option<f64>,
    /// Whether to grasp: the probability reaches the minimum and `reasons` is empty.
    pub graspable: bool,
    /// What forbids the grasp, in [`PickReason`]'s order.
    pub reasons: Vec<PickReason>,
}

/// An object seen through its code, planned.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectPlan {
    /// The rule that matched (`prefix:SKU-`).
    pub rule: String,
    /// The box's extents, mm.
    pub box_mm: Vector3<f64>,
    /// T_camera←object.
    pub pose: PoseWithCovariance,
    /// T_robot←object, when the camera's pose in the robot frame is known.
    pub pose_in_robot: Option<PoseWithCovariance>,
    /// Every grasp of the rule, in its order.
    pub grasps: Vec<GraspPlan>,
}

/// T_robot←camera for a camera with `mount` (none: `None`) and the flange's pose when the
/// photo was taken (needed by a flange mount only).
pub fn camera_in_robot(
    mount: Option<&CameraMount>,
    flange_in_robot: Option<&Rigid>,
) -> Option<PoseWithCovariance> {
    mount.and_then(|m| m.camera_in_robot(flange_in_robot))
}

/// T_grasp←pre-grasp: `approach_mm` back along the grasp's −z.
fn pre_grasp_offset(approach_mm: f64) -> Rigid {
    Rigid {
        rotation: Rotation3::identity(),
        translation_mm: Vector3::new(0.0, 0.0, -approach_mm),
    }
}

/// The reasons that forbid a grasp, in [`PickReason`]'s order.
fn reasons_for(
    has_robot_pose: bool,
    probability: Option<f64>,
    options: &PickOptions,
) -> Vec<PickReason> {
    let below = probability.is_none_or(|p| p < options.min_grasp_probability);
    [
        (!has_robot_pose, PickReason::NoRobotPose),
        (options.pose_ambiguous, PickReason::PoseAmbiguous),
        (below, PickReason::BelowProbability),
        (options.not_converged, PickReason::NotConverged),
        (
            options.high_reprojection_error,
            PickReason::HighReprojectionError,
        ),
    ]
    .into_iter()
    .filter_map(|(applies, reason)| applies.then_some(reason))
    .collect()
}

/// The object's pose and every grasp of `rule` for a code seen at `marker_in_camera`
/// (T_camera←marker, marker origin at the symbol's centre, with the estimate's covariance)
/// by a camera at `camera_in_robot` (T_robot←camera with its covariance, see
/// [`camera_in_robot`]; `None`: unknown).
///
/// # Errors
/// [`PickError::MinGraspProbability`] for a minimum outside [0, 1].
pub fn plan_pick(
    marker_in_camera: &PoseWithCovariance,
    rule: &ObjectRule,
    camera_in_robot: Option<&PoseWithCovariance>,
    options: &PickOptions,
) -> Result<ObjectPlan, PickError> {
    let min = options.min_grasp_probability;
    if !(0.0..=1.0).contains(&min) {
        return Err(PickError::MinGraspProbability { value: min });
    }
    let mirror = options.alternative_probability;
    if !(0.0..=1.0).contains(&mirror) {
        return Err(PickError::AlternativeProbability { value: mirror });
    }
    let object_in_marker = rule.marker_in_object.inverse();
    let pose = then_fixed(marker_in_camera, &object_in_marker);
    let pose_in_robot = camera_in_robot.map(|c| compose(c, &pose));
    let grasps = rule
        .grasps
        .iter()
        .map(|grasp| {
            let grasp_in_marker = object_in_marker.then(&grasp.grasp_in_object);
            let in_camera = then_fixed(marker_in_camera, &grasp_in_marker);
            let in_robot = camera_in_robot.map(|c| compose(c, &in_camera));
            let pre_grasp_in_robot = in_robot.as_ref().and_then(|g| {
                grasp
                    .approach_mm
                    .map(|a| then_fixed(g, &pre_grasp_offset(a)))
            });
            let judged = in_robot.as_ref().unwrap_or(&in_camera);
            // A mixture: the Gaussian about this pose with weight 1 − p(mirror); the mirror
            // pose, tens of degrees off, is never within a gripper's tolerance.
            let probability = judged
                .covariance
                .and_then(|c| within_tolerance_probability(&c, &grasp.tolerance))
                .map(|p| p * (1.0 - mirror));
            let reasons = reasons_for(in_robot.is_some(), probability, options);
            GraspPlan {
                name: grasp.name.clone(),
                kind: grasp.kind,
                pose: in_camera,
                pose_in_robot: in_robot,
                pre_grasp_in_robot,
                width_mm: grasp.kind.width_mm(),
                within_tolerance_probability: probability,
                graspable: reasons.is_empty(),
                reasons,
            }
        })
        .collect();
    Ok(ObjectPlan {
        rule: rule.label.clone(),
        box_mm: rule.box_mm,
        pose,
        pose_in_robot,
        grasps,
    })
}
