//! The site file as written (YAML; format in `docs/site.md`): serde types that refuse
//! unknown keys, and value types that refuse a bad value while it is read, so that the YAML
//! parser reports the line of the culprit. What needs the file system (calibration files)
//! or several sections at once is checked later, in [`crate::site`].

use nalgebra::{Quaternion, UnitQuaternion};
use serde::de::{self, Deserializer};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

mod objects;

pub use objects::{
    GraspEntry, GraspKindName, GripperEntry, ObjectEntries, ObjectEntry, ObjectRigidEntry,
    ObjectRuleError, Positive3, StrictUnitQuaternionWxyz, ToleranceEntry,
    UNIT_QUATERNION_TOLERANCE,
};

/// Below this norm a quaternion has no direction: refused rather than normalised.
pub const MIN_QUATERNION_NORM: f64 = 1e-9;

/// The whole file.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteFile {
    /// Camera id → camera.
    #[serde(default)]
    pub cameras: BTreeMap<String, CameraEntry>,
    /// Marker sizes.
    #[serde(default)]
    pub markers: MarkersEntry,
    /// Codes' poses in the warehouse frame.
    #[serde(default)]
    pub map: MapEntries,
    /// Products by payload: box, code and grasps (`docs/site.md`, Objects).
    #[serde(default)]
    pub objects: ObjectEntries,
}

/// One camera: a calibration file, or inline intrinsics (and distortion); and its mount.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEntry {
    /// OpenCV `FileStorage` or ROS `camera_info` YAML, relative to the site file.
    pub calibration: Option<String>,
    /// Inline intrinsics.
    pub intrinsics: Option<IntrinsicsEntry>,
    /// Inline distortion (with `intrinsics` only).
    pub distortion: Option<DistortionEntry>,
    /// The camera's pose on the robot: p_parent = R·p_camera + t.
    pub mount: Option<MountEntry>,
}

/// What a camera is mounted on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MountParentName {
    /// Fixed in the robot's (base) frame: the mount is T_robot←camera.
    #[default]
    Robot,
    /// On the tool flange (eye-in-hand): the mount is T_flange←camera.
    Flange,
}

/// A camera's mount as written: T_parent←camera and, optionally, its uncertainty.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountEntry {
    /// `robot` (default) or `flange`.
    #[serde(default)]
    pub parent: MountParentName,
    /// t, mm: the camera's optical centre in the parent frame.
    pub translation_mm: Finite3,
    /// R as (w, x, y, z), normalised on reading.
    pub quaternion_wxyz: UnitQuaternionWxyz,
    /// One standard deviation of the mount about the camera's own axes.
    pub std: Option<MountStdEntry>,
}

/// One standard deviation of a mount, about and along the camera's own axes (x, y, z), as a
/// hand-eye calibration reports it.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MountStdEntry {
    /// Rotation about the camera's x, y, z, degrees, ≥ 0.
    pub rotation_deg: NonNegative3,
    /// Translation along the camera's x, y, z, mm, ≥ 0.
    pub translation_mm: NonNegative3,
}

/// Three finite numbers ≥ 0.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NonNegative3(pub [f64; 3]);

impl<'de> Deserialize<'de> for NonNegative3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_seq(CheckedNumbers::<3> {
            check: |v| {
                if v.iter().all(|x| x.is_finite() && *x >= 0.0) {
                    Ok(())
                } else {
                    Err(format!(
                        "a standard deviation must be three finite numbers >= 0, got {v:?}"
                    ))
                }
            },
        })
        .map(Self)
    }
}

/// Pinhole intrinsics, px.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct IntrinsicsEntry {
    /// Horizontal focal length, px.
    pub fx_px: f64,
    /// Vertical focal length, px.
    pub fy_px: f64,
    /// Principal point, px.
    pub cx_px: f64,
    /// Principal point, px.
    pub cy_px: f64,
}

/// A lens distortion model, as ROS names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DistortionModelName {
    /// Brown-Conrady k1 k2 p1 p2 k3.
    PlumbBob,
    /// k1 k2 p1 p2 k3 k4 k5 k6.
    RationalPolynomial,
    /// Kannala-Brandt fisheye k1 k2 k3 k4.
    Equidistant,
}

impl DistortionModelName {
    /// The number of coefficients, in OpenCV's order.
    pub const fn coefficient_count(self) -> usize {
        match self {
            DistortionModelName::PlumbBob => 5,
            DistortionModelName::RationalPolynomial => 8,
            DistortionModelName::Equidistant => 4,
        }
    }

    /// The name as written in the file.
    pub const fn as_str(self) -> &'static str {
        match self {
            DistortionModelName::PlumbBob => "plumb_bob",
            DistortionModelName::RationalPolynomial => "rational_polynomial",
            DistortionModelName::Equidistant => "equidistant",
        }
    }
}

/// Inline distortion: a model and its coefficients in OpenCV's order.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DistortionEntry {
    /// The model.
    pub model: DistortionModelName,
    /// Its coefficients.
    pub coefficients: Vec<f64>,
}

/// A rigid transform as written: p_to = R·p_from + t.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigidEntry {
    /// t, mm.
    pub translation_mm: Finite3,
    /// R as (w, x, y, z), normalised on reading.
    pub quaternion_wxyz: UnitQuaternionWxyz,
}

/// Three finite numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Finite3(pub [f64; 3]);

impl<'de> Deserialize<'de> for Finite3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_seq(CheckedNumbers::<3> {
            check: |v| {
                if v.iter().all(|x| x.is_finite()) {
                    Ok(())
                } else {
                    Err(format!(
                        "translation_mm must be three finite numbers, got {v:?}"
                    ))
                }
            },
        })
        .map(Self)
    }
}

/// Reads exactly N numbers and checks them before the sequence ends, so that a refusal
/// carries the line of the numbers rather than of the mapping around them.
struct CheckedNumbers<const N: usize> {
    check: fn(&[f64; N]) -> Result<(), String>,
}

impl<'de, const N: usize> de::Visitor<'de> for CheckedNumbers<N> {
    type Value = [f64; N];

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "a list of {N} numbers")
    }

    fn visit_seq<A: de::SeqAccess<'de>>(self, mut seq: A) -> Result<[f64; N], A::Error> {
        let mut v = [0.0; N];
        for (i, x) in v.iter_mut().enumerate() {
            *x = seq
                .next_element()?
                .ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        (self.check)(&v).map_err(de::Error::custom)?;
        if seq.next_element::<de::IgnoredAny>()?.is_some() {
            return Err(de::Error::invalid_length(N + 1, &self));
        }
        Ok(v)
    }
}

/// A rotation from a quaternion (w, x, y, z): normalised, refused when zero or not finite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitQuaternionWxyz(pub UnitQuaternion<f64>);

impl<'de> Deserialize<'de> for UnitQuaternionWxyz {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let check = |&[w, x, y, z]: &[f64; 4]| {
            let norm = Quaternion::new(w, x, y, z).norm();
            if norm.is_finite() && norm >= MIN_QUATERNION_NORM {
                Ok(())
            } else {
                Err(format!(
                    "quaternion_wxyz [{w}, {x}, {y}, {z}] is not a rotation: its norm is {norm}, \
                     it must be finite and non-zero (it is normalised)"
                ))
            }
        };
        let [w, x, y, z] = d.deserialize_seq(CheckedNumbers::<4> { check })?;
        Ok(Self(UnitQuaternion::from_quaternion(Quaternion::new(
            w, x, y, z,
        ))))
    }
}

/// A marker size, mm: positive and finite.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SizeMm(pub f64);

impl<'de> Deserialize<'de> for SizeMm {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = f64::deserialize(d)?;
        if v.is_finite() && v > 0.0 {
            Ok(Self(v))
        } else {
            Err(de::Error::custom(format!(
                "a marker size must be a positive number of mm, got {v}"
            )))
        }
    }
}

/// A regular expression (the `regex` crate's syntax), compiled on reading.
#[derive(Debug, Clone)]
pub struct Pattern(pub regex::Regex);

impl<'de> Deserialize<'de> for Pattern {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let source = String::deserialize(d)?;
        regex::Regex::new(&source)
            .map(Self)
            .map_err(|e| de::Error::custom(format!("invalid pattern {source:?}: {e}")))
    }
}

/// `markers`: a default size and the rules, in order.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkersEntry {
    /// Size of a code no rule matches, mm.
    pub default_size_mm: Option<SizeMm>,
    /// Rules, first match wins.
    #[serde(default)]
    pub sizes: SizeRules,
}

/// How a rule matches a payload.
#[derive(Debug, Clone)]
pub enum Matcher {
    /// The whole payload, exactly.
    Exact(String),
    /// The payload starts with this.
    Prefix(String),
    /// The regular expression matches somewhere in the payload (anchor it with `^…$`).
    Pattern(regex::Regex),
}

impl Matcher {
    /// Whether `payload` matches.
    pub fn matches(&self, payload: &str) -> bool {
        match self {
            Matcher::Exact(p) => payload == p,
            Matcher::Prefix(p) => payload.starts_with(p.as_str()),
            Matcher::Pattern(r) => r.is_match(payload),
        }
    }

    /// `payload`, `prefix` or `pattern` and its text, as written: two rules with the same
    /// key are duplicates.
    pub fn key(&self) -> (&'static str, &str) {
        match self {
            Matcher::Exact(p) => ("payload", p),
            Matcher::Prefix(p) => ("prefix", p),
            Matcher::Pattern(r) => ("pattern", r.as_str()),
        }
    }
}

/// One size rule.
#[derive(Debug, Clone)]
pub struct SizeRule {
    /// What it matches.
    pub matcher: Matcher,
    /// The size, mm.
    pub size_mm: f64,
}

/// The keys of a size rule.
const SIZE_RULE_KEYS: [&str; 4] = ["payload", "prefix", "pattern", "size_mm"];

/// Reads a rule key by key, so that a second matcher is refused where it is written.
struct SizeRuleVisitor;

impl<'de> de::Visitor<'de> for SizeRuleVisitor {
    type Value = SizeRule;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a size rule: one of payload, prefix, pattern, and size_mm")
    }

    fn visit_map<A: de::MapAccess<'de>>(self, mut map: A) -> Result<SizeRule, A::Error> {
        let mut matcher = None;
        let mut size_mm = None;
        while let Some(key) = map.next_key::<String>()? {
            let m = match key.as_str() {
                "payload" => Matcher::Exact(map.next_value()?),
                "prefix" => Matcher::Prefix(map.next_value()?),
                "pattern" => Matcher::Pattern(map.next_value::<Pattern>()?.0),
                "size_mm" => {
                    size_mm = Some(map.next_value::<SizeMm>()?.0);
                    continue;
                }
                other => return Err(de::Error::unknown_field(other, &SIZE_RULE_KEYS)),
            };
            if matcher.replace(m).is_some() {
                return Err(de::Error::custom(
                    "a size rule has exactly one of payload, prefix and pattern",
                ));
            }
        }
        let matcher = matcher.ok_or_else(|| {
            de::Error::custom("a size rule needs one of payload, prefix and pattern")
        })?;
        let size_mm = size_mm.ok_or_else(|| de::Error::missing_field("size_mm"))?;
        Ok(SizeRule { matcher, size_mm })
    }
}

impl<'de> Deserialize<'de> for SizeRule {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(SizeRuleVisitor)
    }
}

/// The size rules, in the file's order (duplicates are refused by [`crate::site`]).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(transparent)]
pub struct SizeRules(pub Vec<SizeRule>);

/// One mapped code: its payload and the pose of its centre in the warehouse frame.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapEntry {
    /// The code's payload.
    pub payload: String,
    /// The code's centre in the warehouse frame, mm.
    pub translation_mm: Finite3,
    /// The code's orientation: p_world = R·p_marker + t (marker axes as in
    /// `docs/conventions.md`, origin at the symbol's centre).
    pub quaternion_wxyz: UnitQuaternionWxyz,
}

/// The map, in the file's order (duplicates are refused by [`crate::site`]).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(transparent)]
pub struct MapEntries(pub Vec<MapEntry>);
