//! A loaded, validated [`Site`]: cameras by id (from calibration files or inline), marker
//! sizes by payload, camera mounts and the map, and the SHA-256 of the file it came from
//! (`docs/site.md`). A site is loaded whole or refused whole, with a [`SiteError`] naming the
//! file, the line and the reason.

use crate::calibration::{CalibrationFormat, parse_calibration};
use crate::error::{Reason, SiteError, line_of};
use crate::file::{
    CameraEntry, DistortionEntry, DistortionModelName, IntrinsicsEntry, MountEntry,
    MountParentName, SiteFile,
};
use crate::mount::{CameraMount, MountParent, MountStd};
use crate::objects::ObjectRule;
use crate::sizes::MarkerSizes;
use crate::transform::Rigid;
use nalgebra::Vector3;
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::distortion::{Distortion, DistortionModel};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Where a camera's intrinsics came from.
#[derive(Debug, Clone, PartialEq)]
pub enum CameraSource {
    /// A calibration file.
    Calibration {
        /// The path as written in the site file.
        path: String,
        /// Its format.
        format: CalibrationFormat,
        /// SHA-256 of its bytes, lower-case hex.
        sha256_hex: String,
    },
    /// `intrinsics` (and `distortion`) in the site file.
    Inline {
        /// The intrinsics as written.
        intrinsics: IntrinsicsEntry,
        /// The distortion as written.
        distortion: Option<DistortionEntry>,
    },
}

/// One camera of the site.
#[derive(Debug, Clone, PartialEq)]
pub struct SiteCamera {
    /// The camera model the estimates use.
    pub camera: Camera,
    /// Where it came from.
    pub source: CameraSource,
    /// The calibrated image size (width, height), px, when the calibration file gives it.
    pub image_size_px: Option<(u32, u32)>,
    /// T_robot←camera: p_robot = R·p_camera + t, for a camera fixed on the robot
    /// (`parent: robot`); `None` without a mount and for a camera on the flange, whose pose
    /// in the robot frame needs the flange's pose ([`CameraMount::camera_in_robot`]).
    pub mount: Option<Rigid>,
    /// The mount as written: parent, T_parent←camera and its standard deviation.
    pub camera_mount: Option<CameraMount>,
}

/// One code of the map.
#[derive(Debug, Clone, PartialEq)]
pub struct MappedCode {
    /// Its payload.
    pub payload: String,
    /// T_world←marker, marker origin at the symbol's centre.
    pub pose: Rigid,
}

/// A validated site.
#[derive(Debug, Clone)]
pub struct Site {
    file: PathBuf,
    sha256_hex: String,
    cameras: BTreeMap<String, SiteCamera>,
    sizes: MarkerSizes,
    map: Vec<MappedCode>,
    objects: Vec<ObjectRule>,
}

/// SHA-256 of `bytes`, lower-case hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn mount_from_entry(e: &MountEntry) -> CameraMount {
    CameraMount {
        parent: match e.parent {
            MountParentName::Robot => MountParent::Robot,
            MountParentName::Flange => MountParent::Flange,
        },
        pose: Rigid {
            rotation: e.quaternion_wxyz.0.to_rotation_matrix(),
            translation_mm: Vector3::from(e.translation_mm.0),
        },
        std: e.std.map(|s| MountStd {
            rotation_rad: Vector3::from(s.rotation_deg.0).map(f64::to_radians),
            translation_mm: Vector3::from(s.translation_mm.0),
        }),
    }
}

/// The core distortion of an inline entry.
///
/// # Errors
/// The reason, for a wrong number of coefficients or one that is not finite.
pub fn distortion_from_entry(e: &DistortionEntry) -> Result<Distortion, String> {
    let model = match e.model {
        DistortionModelName::PlumbBob => DistortionModel::PlumbBob,
        DistortionModelName::RationalPolynomial => DistortionModel::RationalPolynomial,
        DistortionModelName::Equidistant => DistortionModel::Equidistant,
    };
    Distortion::from_coefficients(model, &e.coefficients).map_err(|err| err.to_string())
}

impl Site {
    /// Reads and validates the site file at `path`; calibration files are resolved against
    /// its directory.
    ///
    /// # Errors
    /// A [`SiteError`] with the file, the line when known and the reason.
    pub fn load(path: &Path) -> Result<Self, SiteError> {
        let bytes = std::fs::read(path)
            .map_err(|e| SiteError::new(path, None, Reason::Read(e.to_string())))?;
        let text = String::from_utf8(bytes)
            .map_err(|e| SiteError::new(path, None, Reason::Read(format!("not UTF-8: {e}"))))?;
        Self::parse(&text, path)
    }

    /// Validates the site file text `text`, read from `path`.
    ///
    /// # Errors
    /// As [`Site::load`].
    pub fn parse(text: &str, path: &Path) -> Result<Self, SiteError> {
        let file: SiteFile = serde_norway::from_str(text).map_err(|e| {
            let line = e.location().map(|l| l.line());
            SiteError::new(path, line, Reason::Format(e.to_string()))
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        let mut cameras = BTreeMap::new();
        for (id, entry) in &file.cameras {
            let camera = resolve_camera(id, entry, base)
                .map_err(|reason| SiteError::new(path, camera_line(text, id, &reason), reason))?;
            cameras.insert(id.clone(), camera);
        }
        let sizes = MarkerSizes {
            default_size_mm: file.markers.default_size_mm.map(|s| s.0),
            rules: file.markers.sizes.0,
        };
        let map: Vec<MappedCode> = file
            .map
            .0
            .iter()
            .map(|e| MappedCode {
                payload: e.payload.clone(),
                pose: Rigid {
                    rotation: e.quaternion_wxyz.0.to_rotation_matrix(),
                    translation_mm: Vector3::from(e.translation_mm.0),
                },
            })
            .collect();
        let rule_keys = sizes.rules.iter().map(|r| r.matcher.key());
        check_unique(text, path, "markers.sizes", "sizes", rule_keys)?;
        let map_keys = map.iter().map(|m| ("payload", m.payload.as_str()));
        check_unique(text, path, "map", "map", map_keys)?;
        let objects: Vec<ObjectRule> = file.objects.0.iter().map(ObjectRule::from).collect();
        let object_keys = objects.iter().map(|o| o.matcher.key());
        check_unique(text, path, "objects", "objects", object_keys)?;
        if let Some(without_size) = map
            .iter()
            .find(|m| sizes.lookup(Some(&m.payload)).is_none())
        {
            return Err(SiteError::new(
                path,
                line_of(text, &without_size.payload),
                Reason::MappedCodeWithoutSize {
                    payload: without_size.payload.clone(),
                },
            ));
        }
        Ok(Self {
            file: path.to_path_buf(),
            sha256_hex: sha256_hex(text.as_bytes()),
            cameras,
            sizes,
            map,
            objects,
        })
    }

    /// The file it was loaded from.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// SHA-256 of the site file's bytes, lower-case hex (what `sha256sum` prints).
    pub fn sha256_hex(&self) -> &str {
        &self.sha256_hex
    }

    /// The camera with this id.
    pub fn camera(&self, id: &str) -> Option<&SiteCamera> {
        self.cameras.get(id)
    }

    /// Every camera, by id.
    pub fn cameras(&self) -> &BTreeMap<String, SiteCamera> {
        &self.cameras
    }

    /// The size rules and default.
    pub fn sizes(&self) -> &MarkerSizes {
        &self.sizes
    }

    /// The map, in the file's order.
    pub fn map(&self) -> &[MappedCode] {
        &self.map
    }

    /// The object rules, in the file's order.
    pub fn objects(&self) -> &[ObjectRule] {
        &self.objects
    }

    /// The first object rule that matches `payload`, with its label (`prefix:SKU-`).
    pub fn object_for(&self, payload: &str) -> Option<(&str, &ObjectRule)> {
        crate::objects::object_for(&self.objects, payload).map(|r| (r.label.as_str(), r))
    }

    /// T_world←marker of the code with this payload, when it is mapped.
    pub fn mapped(&self, payload: &str) -> Option<&Rigid> {
        self.map
            .iter()
            .find(|m| m.payload == payload)
            .map(|m| &m.pose)
    }
}

/// Refuses the second of two equal `(kind, text)` keys of `section`, pointing at its line:
/// the second line naming it after the section's key `section_key`.
fn check_unique<'a>(
    text: &str,
    path: &Path,
    section: &'static str,
    section_key: &str,
    keys: impl Iterator<Item = (&'static str, &'a str)>,
) -> Result<(), SiteError> {
    let mut seen = std::collections::HashSet::new();
    for (kind, value) in keys {
        if !seen.insert((kind, value)) {
            let quoted = format!("{value:?}");
            let from = key_line(text, section_key, 1).unwrap_or(1);
            let line = text
                .lines()
                .enumerate()
                .skip(from)
                .filter(|(_, l)| l.contains(kind) && l.contains(value))
                .nth(1)
                .map(|(i, _)| i + 1);
            return Err(SiteError::new(
                path,
                line,
                Reason::Duplicate {
                    section,
                    key: format!("{kind} {quoted}"),
                },
            ));
        }
    }
    Ok(())
}

/// The 1-based line of the first key `key:` at the start of a line (after indentation), at
/// or after line `from` (1-based).
fn key_line(text: &str, key: &str, from: usize) -> Option<usize> {
    let prefix = format!("{key}:");
    text.lines()
        .enumerate()
        .skip(from.saturating_sub(1))
        .find(|(_, l)| l.trim_start().starts_with(&prefix))
        .map(|(i, _)| i + 1)
}

/// The line a camera's refusal points at: its `calibration:` line for a calibration file's
/// refusal, else the line of its id.
fn camera_line(text: &str, id: &str, reason: &Reason) -> Option<usize> {
    let id_line = key_line(text, id, 1)?;
    match reason {
        Reason::MissingCalibration { .. } | Reason::InvalidCalibration { .. } => {
            key_line(text, "calibration", id_line).or(Some(id_line))
        }
        Reason::InvalidCamera { key, .. } => key_line(text, key, id_line).or(Some(id_line)),
        _ => Some(id_line),
    }
}

fn resolve_camera(id: &str, entry: &CameraEntry, base: &Path) -> Result<SiteCamera, Reason> {
    let camera_mount = entry.mount.as_ref().map(mount_from_entry);
    let mount = camera_mount
        .filter(|m| m.parent == MountParent::Robot)
        .map(|m| m.pose);
    let form_error = |detail: &str| Reason::CameraForm {
        id: id.to_owned(),
        detail: detail.to_owned(),
    };
    match (&entry.calibration, &entry.intrinsics) {
        (Some(calibration), None) => {
            if entry.distortion.is_some() {
                return Err(form_error(
                    "distortion comes from the calibration file: give it only with intrinsics",
                ));
            }
            let resolved = base.join(calibration);
            if !resolved.is_file() {
                return Err(Reason::MissingCalibration {
                    id: id.to_owned(),
                    path: resolved,
                });
            }
            let invalid = |detail: String| Reason::InvalidCalibration {
                id: id.to_owned(),
                path: resolved.clone(),
                detail,
            };
            let bytes = std::fs::read(&resolved).map_err(|e| invalid(e.to_string()))?;
            let text =
                std::str::from_utf8(&bytes).map_err(|e| invalid(format!("not UTF-8: {e}")))?;
            let parsed = parse_calibration(text).map_err(|e| invalid(e.to_string()))?;
            Ok(SiteCamera {
                camera: parsed.camera,
                source: CameraSource::Calibration {
                    path: calibration.clone(),
                    format: parsed.format,
                    sha256_hex: sha256_hex(&bytes),
                },
                image_size_px: parsed.image_size_px,
                mount,
                camera_mount,
            })
        }
        (None, Some(intrinsics)) => {
            let invalid = |key: &'static str, detail: String| Reason::InvalidCamera {
                id: id.to_owned(),
                key,
                detail,
            };
            let i = intrinsics;
            let camera = Camera::from_pixels(i.fx_px, i.fy_px, i.cx_px, i.cy_px)
                .map_err(|e| invalid("intrinsics", e.to_string()))?;
            let camera = match &entry.distortion {
                Some(d) => camera.with_distortion(
                    distortion_from_entry(d).map_err(|e| invalid("distortion", e))?,
                ),
                None => camera,
            };
            Ok(SiteCamera {
                camera,
                source: CameraSource::Inline {
                    intrinsics: *intrinsics,
                    distortion: entry.distortion.clone(),
                },
                image_size_px: None,
                mount,
                camera_mount,
            })
        }
        (Some(_), Some(_)) => Err(form_error("give calibration or intrinsics, not both")),
        (None, None) => Err(form_error("give calibration (a file) or intrinsics")),
    }
}
