//! A product seen through its code, on the wire (`docs/pick.md`): each marker whose payload
//! matches one of the site's `objects` carries [`ObjectDto`] — the box, its pose in the
//! camera and the robot frames, and each grasp with its pose, pre-grasp, the probability of
//! landing within its tolerance and whether to grasp. The math is the site crate's
//! (`qrpose_site::pick`).

use super::frames::FramePoseDto;
use qrpose_site::objects::GraspKind;
use qrpose_site::pick::{GraspPlan, ObjectPlan, PickReason};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// The gripper of a grasp.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum GraspKindDto {
    /// A suction cup.
    Suction,
    /// A parallel-jaw gripper (`width_mm` its opening).
    Parallel,
}

/// What forbids a grasp.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum PickReasonDto {
    /// The camera's pose in the robot frame is unknown: no mount, or a camera on the flange
    /// and no `flange_pose` in the request.
    NoRobotPose,
    /// The code's pose cannot be told from its mirror (the planar ambiguity).
    PoseAmbiguous,
    /// The probability of landing within tolerance is below `min_grasp_probability`, or
    /// unknown (an estimate without covariance: methods other than `reprojection`).
    BelowProbability,
    /// The code's pose estimate did not converge.
    NotConverged,
    /// The code's pose fits its corners worse than their stated noise allows (a corner
    /// measured wrong, or `corner_sigma_px` too small): its covariance, and so the
    /// probability, cannot be trusted.
    HighReprojectionError,
}

impl From<PickReason> for PickReasonDto {
    fn from(r: PickReason) -> Self {
        match r {
            PickReason::NoRobotPose => Self::NoRobotPose,
            PickReason::PoseAmbiguous => Self::PoseAmbiguous,
            PickReason::BelowProbability => Self::BelowProbability,
            PickReason::NotConverged => Self::NotConverged,
            PickReason::HighReprojectionError => Self::HighReprojectionError,
        }
    }
}

/// One grasp of the product.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct GraspDto {
    /// Its name in the site file.
    pub name: String,
    /// `suction` or `parallel`.
    pub kind: GraspKindDto,
    /// T_camera←grasp: the tool centre point at the grasp; the tool approaches along the
    /// grasp frame's +z.
    pub pose: FramePoseDto,
    /// T_robot←grasp; null when the camera's pose in the robot frame is unknown.
    pub pose_in_robot: Option<FramePoseDto>,
    /// T_robot←pre-grasp, `approach_mm` back along the grasp's −z; null without
    /// `approach_mm` or without the robot frame.
    pub pre_grasp_in_robot: Option<FramePoseDto>,
    /// The opening of a parallel gripper, mm; null for suction.
    pub width_mm: Option<f64>,
    /// The probability that the grasp lies within its tolerance (position and rotation),
    /// from the propagated covariance, in the robot frame when known; null without a
    /// covariance.
    pub within_tolerance_probability: Option<f64>,
    /// Whether to send the arm: the probability reaches `min_grasp_probability` and no
    /// reason forbids it.
    pub graspable: bool,
    /// What forbids the grasp; empty when `graspable`.
    pub reasons: Vec<PickReasonDto>,
}

/// The product a code's payload names in the site's `objects`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ObjectDto {
    /// The rule that matched: `payload:…`, `prefix:…` or `pattern:…`.
    #[schema(example = "prefix:SKU-")]
    pub rule: String,
    /// The box's extents along the object frame's x, y, z, mm (origin at its centre).
    pub box_mm: [f64; 3],
    /// T_camera←object.
    pub pose: FramePoseDto,
    /// T_robot←object; null when the camera's pose in the robot frame is unknown.
    pub pose_in_robot: Option<FramePoseDto>,
    /// Every grasp of the rule, in the site file's order.
    pub grasps: Vec<GraspDto>,
}

impl From<&GraspPlan> for GraspDto {
    fn from(g: &GraspPlan) -> Self {
        Self {
            name: g.name.clone(),
            kind: match g.kind {
                GraspKind::Suction => GraspKindDto::Suction,
                GraspKind::Parallel { .. } => GraspKindDto::Parallel,
            },
            pose: FramePoseDto::from(&g.pose),
            pose_in_robot: g.pose_in_robot.as_ref().map(FramePoseDto::from),
            pre_grasp_in_robot: g.pre_grasp_in_robot.as_ref().map(FramePoseDto::from),
            width_mm: g.width_mm,
            within_tolerance_probability: g.within_tolerance_probability,
            graspable: g.graspable,
            reasons: g.reasons.iter().copied().map(PickReasonDto::from).collect(),
        }
    }
}

impl From<&ObjectPlan> for ObjectDto {
    fn from(o: &ObjectPlan) -> Self {
        Self {
            rule: o.rule.clone(),
            box_mm: o.box_mm.into(),
            pose: FramePoseDto::from(&o.pose),
            pose_in_robot: o.pose_in_robot.as_ref().map(FramePoseDto::from),
            grasps: o.grasps.iter().map(GraspDto::from).collect(),
        }
    }
}
