//! Products by payload (`docs/site.md`, Objects): the site's `objects:` rules resolved into
//! [`ObjectRule`]s: the box, where the code sits on it (T_object←marker) and the grasps
//! (T_object←grasp), in the core's units (mm, radians). Rules match payloads as the marker
//! size rules do ([`crate::sizes`]): in the file's order, first match wins.

use crate::file::{GripperEntry, Matcher, ObjectEntry, ObjectRigidEntry};
use crate::transform::Rigid;
use nalgebra::Vector3;

/// A grasp's gripper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GraspKind {
    /// A suction cup.
    Suction,
    /// A parallel-jaw gripper opened to `width_mm`.
    Parallel {
        /// The opening, mm.
        width_mm: f64,
    },
}

impl GraspKind {
    /// The wire name: `suction`, `parallel`.
    pub const fn as_str(self) -> &'static str {
        match self {
            GraspKind::Suction => "suction",
            GraspKind::Parallel { .. } => "parallel",
        }
    }

    /// The opening of a parallel gripper, mm; `None` for suction.
    pub const fn width_mm(self) -> Option<f64> {
        match self {
            GraspKind::Suction => None,
            GraspKind::Parallel { width_mm } => Some(width_mm),
        }
    }
}

/// How far from its nominal pose a grasp still succeeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Largest distance of the tool centre point from the nominal, mm.
    pub position_mm: f64,
    /// Largest rotation angle from the nominal, rad.
    pub rotation_rad: f64,
}

/// One grasp of an object.
#[derive(Debug, Clone, PartialEq)]
pub struct Grasp {
    /// Its name, unique within the object.
    pub name: String,
    /// Its gripper.
    pub kind: GraspKind,
    /// T_object←grasp: the tool centre point at the grasp; the tool approaches along the
    /// grasp frame's +z.
    pub grasp_in_object: Rigid,
    /// Its tolerance.
    pub tolerance: Tolerance,
    /// The pre-grasp's distance back along the grasp frame's −z, mm.
    pub approach_mm: Option<f64>,
}

/// One product rule.
#[derive(Debug, Clone)]
pub struct ObjectRule {
    /// `payload:…`, `prefix:…` or `pattern:…`: the rule as answers name it.
    pub label: String,
    /// What payloads it matches.
    pub matcher: Matcher,
    /// The box's extents along the object frame's x, y, z, mm (origin at its centre).
    pub box_mm: Vector3<f64>,
    /// T_object←marker, marker origin at the symbol's centre.
    pub marker_in_object: Rigid,
    /// The grasps, at least one.
    pub grasps: Vec<Grasp>,
}

fn rigid_from_object_entry(e: &ObjectRigidEntry) -> Rigid {
    Rigid {
        rotation: e.quaternion_wxyz.0.to_rotation_matrix(),
        translation_mm: Vector3::from(e.translation_mm.0),
    }
}

impl From<&ObjectEntry> for ObjectRule {
    fn from(e: &ObjectEntry) -> Self {
        let (kind, text) = e.matcher.key();
        Self {
            label: format!("{kind}:{text}"),
            matcher: e.matcher.clone(),
            box_mm: Vector3::from(e.box_mm),
            marker_in_object: rigid_from_object_entry(&e.code),
            grasps: e
                .grasps
                .iter()
                .map(|g| Grasp {
                    name: g.name.clone(),
                    kind: match g.gripper {
                        GripperEntry::Suction => GraspKind::Suction,
                        GripperEntry::Parallel { width_mm } => GraspKind::Parallel { width_mm },
                    },
                    grasp_in_object: rigid_from_object_entry(&g.pose),
                    tolerance: Tolerance {
                        position_mm: g.tolerance.position_mm,
                        rotation_rad: g.tolerance.rotation_deg.to_radians(),
                    },
                    approach_mm: g.approach_mm,
                })
                .collect(),
        }
    }
}

/// The first rule of `rules` that matches `payload`.
pub fn object_for<'a>(rules: &'a [ObjectRule], payload: &str) -> Option<&'a ObjectRule> {
    rules.iter().find(|r| r.matcher.matches(payload))
}
