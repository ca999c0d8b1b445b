//! The `objects:` section as written (`docs/site.md`, Objects): products matched by payload
//! like `markers.sizes` (exactly one of `payload`, `prefix`, `pattern`; first match wins),
//! each with its box, where its code sits on it and how to grasp it.
//!
//! Every check happens while the file is read, so that the YAML parser reports the field's
//! path and line (`objects[0].grasps[1]: …`): values in their own types, the rules that
//! tie several keys of one rule or one grasp together in [`ObjectRuleError`].

use super::{CheckedNumbers, Finite3, Matcher, Pattern};
use nalgebra::{Quaternion, UnitQuaternion};
use serde::de::{self, Deserializer};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// How far a quaternion's norm may be from 1 before it is refused rather than normalised
/// (the robot poses' rule, `docs/site.md`, Objects).
pub const UNIT_QUATERNION_TOLERANCE: f64 = 1e-3;

/// Why an object rule or one of its grasps is refused: the parts that tie several keys
/// together. The YAML parser prefixes the path of the rule or grasp and adds the line.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ObjectRuleError {
    /// A length or angle that must be positive is not (or is not finite).
    #[error("{key} must be a positive number, got {value}")]
    NotPositive {
        /// The key, from the grasp: `width_mm`, `tolerance.position_mm`, ….
        key: &'static str,
        /// The value.
        value: f64,
    },
    /// A length that must be ≥ 0 is not (or is not finite).
    #[error("{key} must be a number >= 0, got {value}")]
    Negative {
        /// The key: `approach_mm`.
        key: &'static str,
        /// The value.
        value: f64,
    },
    /// A required key is missing.
    #[error("missing field `{key}`")]
    MissingKey {
        /// The key.
        key: &'static str,
    },
    /// Two of `payload`, `prefix`, `pattern`: which one was meant?
    #[error("an object rule has exactly one of payload, prefix and pattern")]
    TwoMatchers,
    /// None of `payload`, `prefix`, `pattern`: the rule would match nothing.
    #[error("an object rule needs one of payload, prefix and pattern")]
    NoMatcher,
    /// `grasps: []`: an object that cannot be picked has no business in `objects`.
    #[error("grasps: an object rule needs at least one grasp")]
    NoGrasps,
    /// Two grasps of one object with the same name: answers name grasps.
    #[error("grasps: the name {name:?} is used twice")]
    DuplicateGraspName {
        /// The name.
        name: String,
    },
    /// A `parallel` grasp without `width_mm`: the gripper's opening is unknown.
    #[error("grasp {name:?}: width_mm is required for a parallel grasp")]
    MissingWidth {
        /// The grasp's name.
        name: String,
    },
    /// A `suction` grasp with `width_mm`: a suction cup has no opening.
    #[error("grasp {name:?}: width_mm is only for a parallel grasp, not for suction")]
    WidthForSuction {
        /// The grasp's name.
        name: String,
    },
}

/// A rotation from a quaternion (w, x, y, z) whose norm is within
/// [`UNIT_QUATERNION_TOLERANCE`] of 1 (then normalised); any other is refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrictUnitQuaternionWxyz(pub UnitQuaternion<f64>);

impl<'de> Deserialize<'de> for StrictUnitQuaternionWxyz {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let check = |&[w, x, y, z]: &[f64; 4]| {
            let norm = Quaternion::new(w, x, y, z).norm();
            if norm.is_finite() && (norm - 1.0).abs() <= UNIT_QUATERNION_TOLERANCE {
                Ok(())
            } else {
                Err(format!(
                    "quaternion_wxyz [{w}, {x}, {y}, {z}] is not a unit quaternion: its norm \
                     is {norm}, it must be within {UNIT_QUATERNION_TOLERANCE} of 1"
                ))
            }
        };
        let [w, x, y, z] = d.deserialize_seq(CheckedNumbers::<4> { check })?;
        Ok(Self(UnitQuaternion::from_quaternion(Quaternion::new(
            w, x, y, z,
        ))))
    }
}

/// A rigid transform of an object (p_to = R·p_from + t) with a unit quaternion.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectRigidEntry {
    /// t, mm.
    pub translation_mm: Finite3,
    /// R as (w, x, y, z).
    pub quaternion_wxyz: StrictUnitQuaternionWxyz,
}

/// Three positive finite numbers (a box's extents, mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Positive3(pub [f64; 3]);

impl<'de> Deserialize<'de> for Positive3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_seq(CheckedNumbers::<3> {
            check: |v| {
                if v.iter().all(|x| x.is_finite() && *x > 0.0) {
                    Ok(())
                } else {
                    Err(format!("box_mm must be three positive numbers, got {v:?}"))
                }
            },
        })
        .map(Self)
    }
}

/// A grasp's kind as written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GraspKindName {
    /// A suction cup.
    Suction,
    /// A parallel-jaw gripper.
    Parallel,
}

/// A grasp's gripper, checked: a parallel one has an opening, a suction cup none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GripperEntry {
    /// `kind: suction`.
    Suction,
    /// `kind: parallel` with `width_mm`.
    Parallel {
        /// The opening, mm, > 0.
        width_mm: f64,
    },
}

/// How close to its nominal pose a grasp must be.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ToleranceEntry {
    /// Largest distance of the tool centre point from the nominal, mm, > 0.
    pub position_mm: f64,
    /// Largest rotation angle from the nominal, degrees, > 0.
    pub rotation_deg: f64,
}

/// The keys of a grasp as read, before the checks that tie them together.
#[derive(Debug, Default)]
struct GraspKeys {
    name: Option<String>,
    kind: Option<GraspKindName>,
    translation_mm: Option<Finite3>,
    quaternion_wxyz: Option<StrictUnitQuaternionWxyz>,
    width_mm: Option<f64>,
    tolerance: Option<ToleranceEntry>,
    approach_mm: Option<f64>,
}

/// `value` when it is finite and positive.
fn positive(value: f64, key: &'static str) -> Result<f64, ObjectRuleError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ObjectRuleError::NotPositive { key, value })
    }
}

/// The value of a required key, or the parser's `missing field` error.
fn required<T>(value: Option<T>, key: &'static str) -> Result<T, ObjectRuleError> {
    value.ok_or(ObjectRuleError::MissingKey { key })
}

/// Stores a key's value, refusing the key a second time (the YAML parser allows no
/// duplicate keys, so this only guards the contract).
fn set_once<T, E: de::Error>(slot: &mut Option<T>, value: T, key: &'static str) -> Result<(), E> {
    if slot.replace(value).is_some() {
        return Err(E::duplicate_field(key));
    }
    Ok(())
}

/// The keys of a grasp.
const GRASP_KEYS: [&str; 7] = [
    "name",
    "kind",
    "translation_mm",
    "quaternion_wxyz",
    "width_mm",
    "tolerance",
    "approach_mm",
];

/// Reads a grasp key by key (each value through the parser, which keeps its path and line)
/// and checks the keys together before the mapping ends, so that the refusal names the
/// grasp's own path (`objects[0].grasps[1]`).
struct GraspVisitor;

impl<'de> de::Visitor<'de> for GraspVisitor {
    type Value = GraspEntry;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a grasp")
    }

    fn visit_map<A: de::MapAccess<'de>>(self, mut map: A) -> Result<GraspEntry, A::Error> {
        let mut f = GraspKeys::default();
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "name" => set_once(&mut f.name, map.next_value()?, "name")?,
                "kind" => set_once(&mut f.kind, map.next_value()?, "kind")?,
                "translation_mm" => {
                    set_once(&mut f.translation_mm, map.next_value()?, "translation_mm")?
                }
                "quaternion_wxyz" => {
                    set_once(&mut f.quaternion_wxyz, map.next_value()?, "quaternion_wxyz")?
                }
                "width_mm" => set_once(&mut f.width_mm, map.next_value()?, "width_mm")?,
                "tolerance" => set_once(&mut f.tolerance, map.next_value()?, "tolerance")?,
                "approach_mm" => set_once(&mut f.approach_mm, map.next_value()?, "approach_mm")?,
                other => return Err(de::Error::unknown_field(other, &GRASP_KEYS)),
            }
        }
        GraspEntry::try_from(f).map_err(de::Error::custom)
    }
}

impl<'de> Deserialize<'de> for GraspEntry {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(GraspVisitor)
    }
}

/// The keys of an object rule.
const OBJECT_KEYS: [&str; 6] = ["payload", "prefix", "pattern", "box_mm", "code", "grasps"];

/// Reads an object rule key by key, as [`GraspVisitor`] a grasp.
struct ObjectVisitor;

impl<'de> de::Visitor<'de> for ObjectVisitor {
    type Value = ObjectEntry;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("an object rule")
    }

    fn visit_map<A: de::MapAccess<'de>>(self, mut map: A) -> Result<ObjectEntry, A::Error> {
        let mut f = ObjectKeys::default();
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "payload" => f.matchers.push(Matcher::Exact(map.next_value()?)),
                "prefix" => f.matchers.push(Matcher::Prefix(map.next_value()?)),
                "pattern" => f
                    .matchers
                    .push(Matcher::Pattern(map.next_value::<Pattern>()?.0)),
                "box_mm" => set_once(&mut f.box_mm, map.next_value()?, "box_mm")?,
                "code" => set_once(&mut f.code, map.next_value()?, "code")?,
                "grasps" => set_once(&mut f.grasps, map.next_value()?, "grasps")?,
                other => return Err(de::Error::unknown_field(other, &OBJECT_KEYS)),
            }
        }
        ObjectEntry::try_from(f).map_err(de::Error::custom)
    }
}

impl<'de> Deserialize<'de> for ObjectEntry {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(ObjectVisitor)
    }
}

/// One grasp of an object, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspEntry {
    /// Its name, unique within the object.
    pub name: String,
    /// Its gripper (`kind`, and `width_mm` for a parallel one).
    pub gripper: GripperEntry,
    /// T_object←grasp; the tool approaches along the grasp frame's +z.
    pub pose: ObjectRigidEntry,
    /// Its tolerance.
    pub tolerance: ToleranceEntry,
    /// The pre-grasp's distance back along the grasp's −z, mm.
    pub approach_mm: Option<f64>,
}

impl TryFrom<GraspKeys> for GraspEntry {
    type Error = ObjectRuleError;

    fn try_from(f: GraspKeys) -> Result<Self, ObjectRuleError> {
        let name = required(f.name, "name")?;
        let kind = required(f.kind, "kind")?;
        let translation_mm = required(f.translation_mm, "translation_mm")?;
        let quaternion_wxyz = required(f.quaternion_wxyz, "quaternion_wxyz")?;
        let tolerance = required(f.tolerance, "tolerance")?;
        positive(tolerance.position_mm, "tolerance.position_mm")?;
        positive(tolerance.rotation_deg, "tolerance.rotation_deg")?;
        let approach_mm = match f.approach_mm {
            Some(a) if !(a.is_finite() && a >= 0.0) => {
                return Err(ObjectRuleError::Negative {
                    key: "approach_mm",
                    value: a,
                });
            }
            a => a,
        };
        let gripper = match (kind, f.width_mm) {
            (GraspKindName::Parallel, Some(w)) => GripperEntry::Parallel {
                width_mm: positive(w, "width_mm")?,
            },
            (GraspKindName::Suction, None) => GripperEntry::Suction,
            (GraspKindName::Parallel, None) => {
                return Err(ObjectRuleError::MissingWidth { name });
            }
            (GraspKindName::Suction, Some(_)) => {
                return Err(ObjectRuleError::WidthForSuction { name });
            }
        };
        Ok(Self {
            name,
            gripper,
            pose: ObjectRigidEntry {
                translation_mm,
                quaternion_wxyz,
            },
            tolerance,
            approach_mm,
        })
    }
}

/// The keys of an object rule as read, before the checks that tie them together.
#[derive(Debug, Default)]
struct ObjectKeys {
    matchers: Vec<Matcher>,
    box_mm: Option<Positive3>,
    code: Option<ObjectRigidEntry>,
    grasps: Option<Vec<GraspEntry>>,
}

/// One object rule, checked.
#[derive(Debug, Clone)]
pub struct ObjectEntry {
    /// What payloads it matches.
    pub matcher: Matcher,
    /// The box's extents along the object frame's x, y, z, mm; the object frame's origin is
    /// the box's centre.
    pub box_mm: [f64; 3],
    /// T_object←marker: where the code sits on the box (marker origin at the symbol's
    /// centre).
    pub code: ObjectRigidEntry,
    /// The grasps, at least one, names unique.
    pub grasps: Vec<GraspEntry>,
}

impl TryFrom<ObjectKeys> for ObjectEntry {
    type Error = ObjectRuleError;

    fn try_from(f: ObjectKeys) -> Result<Self, ObjectRuleError> {
        let matcher = match <[Matcher; 1]>::try_from(f.matchers) {
            Ok([m]) => m,
            Err(v) if v.is_empty() => return Err(ObjectRuleError::NoMatcher),
            Err(_) => return Err(ObjectRuleError::TwoMatchers),
        };
        let box_mm = required(f.box_mm, "box_mm")?;
        let code = required(f.code, "code")?;
        let grasps = required(f.grasps, "grasps")?;
        if grasps.is_empty() {
            return Err(ObjectRuleError::NoGrasps);
        }
        let mut names = std::collections::HashSet::new();
        if let Some(g) = grasps.iter().find(|g| !names.insert(g.name.as_str())) {
            return Err(ObjectRuleError::DuplicateGraspName {
                name: g.name.clone(),
            });
        }
        Ok(Self {
            matcher,
            box_mm: box_mm.0,
            code,
            grasps,
        })
    }
}

/// The object rules, in the file's order (duplicate keys are refused by [`crate::site`]).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(transparent)]
pub struct ObjectEntries(pub Vec<ObjectEntry>);
