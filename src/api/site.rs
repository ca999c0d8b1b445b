//! The loaded site as JSON: what `GET /v1/site`, `POST /v1/site/reload` and
//! `qrpose site check` print (`docs/site.md`). Every value is the resolved one: a camera from
//! a calibration file shows the intrinsics read from it, a quaternion is shown normalised.

use super::camera::CameraDto;
use crate::geometry::euler::quaternion_wxyz;
use qrpose_site::calibration::CalibrationFormat;
use qrpose_site::file::Matcher;
use qrpose_site::mount::CameraMount;
use qrpose_site::transform::Rigid;
use qrpose_site::{CameraSource, Site, SiteCamera};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// A rigid transform p_to = R·p_from + t.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RigidDto {
    /// t, mm.
    pub translation_mm: [f64; 3],
    /// R as a unit quaternion (w, x, y, z), w ≥ 0.
    pub quaternion_wxyz: [f64; 4],
}

impl From<&Rigid> for RigidDto {
    fn from(r: &Rigid) -> Self {
        Self {
            translation_mm: r.translation_mm.into(),
            quaternion_wxyz: quaternion_wxyz(&r.rotation),
        }
    }
}

/// One standard deviation of a mount about the camera's own axes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MountStdDto {
    /// About x, y, z, degrees.
    pub rotation_deg: [f64; 3],
    /// Along x, y, z, mm.
    pub translation_mm: [f64; 3],
}

/// A camera's mount: T_parent←camera (p_parent = R·p_camera + t).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MountDto {
    /// `robot` or `flange`.
    pub parent: String,
    /// t, mm.
    pub translation_mm: [f64; 3],
    /// R as a unit quaternion (w, x, y, z), w ≥ 0.
    pub quaternion_wxyz: [f64; 4],
    /// Its standard deviation, when the site gives one.
    pub std: Option<MountStdDto>,
}

impl From<&CameraMount> for MountDto {
    fn from(m: &CameraMount) -> Self {
        let RigidDto {
            translation_mm,
            quaternion_wxyz,
        } = RigidDto::from(&m.pose);
        Self {
            parent: m.parent.as_str().to_owned(),
            translation_mm,
            quaternion_wxyz,
            std: m.std.map(|s| MountStdDto {
                rotation_deg: s.rotation_rad.map(f64::to_degrees).into(),
                translation_mm: s.translation_mm.into(),
            }),
        }
    }
}

/// The calibration file a camera was read from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibrationFileDto {
    /// The path as written in the site file (relative to it).
    pub path: String,
    /// `opencv` (FileStorage YAML) or `ros_camera_info`.
    #[schema(example = "opencv")]
    pub format: String,
    /// SHA-256 of the calibration file's bytes, hex.
    pub sha256: String,
}

/// One camera of the site, resolved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SiteCameraDto {
    /// The calibration file, or null for inline intrinsics.
    pub calibration: Option<CalibrationFileDto>,
    /// The camera in use (its intrinsics and lens), as a pose request's `camera` takes it.
    pub camera: CameraDto,
    /// The calibrated image size [width, height], px, when the calibration file gives it.
    pub image_size_px: Option<[u32; 2]>,
    /// The camera's mount as the site file gives it: its `parent` (`robot`: fixed on the
    /// robot; `flange`: on the arm's flange, in the robot frame only with a request's
    /// `flange_pose`), T_parent←camera and its standard deviation; null without one.
    pub mount: Option<MountDto>,
}

/// One size rule: exactly one of `payload`, `prefix`, `pattern`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SizeRuleDto {
    /// The exact payload it matches.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub payload: Option<String>,
    /// The prefix it matches.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prefix: Option<String>,
    /// The regular expression it matches (anywhere in the payload unless anchored).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pattern: Option<String>,
    /// The size, mm.
    pub size_mm: f64,
}

/// The marker sizes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SiteMarkersDto {
    /// The size of a code no rule matches, mm, or null.
    pub default_size_mm: Option<f64>,
    /// The rules, first match wins.
    pub sizes: Vec<SizeRuleDto>,
}

/// One mapped code.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MappedCodeDto {
    /// Its payload.
    pub payload: String,
    /// Its centre in the warehouse frame, mm.
    pub translation_mm: [f64; 3],
    /// Its orientation: p_world = R·p_marker + t (marker origin at the symbol's centre).
    pub quaternion_wxyz: [f64; 4],
}

/// The loaded site (`GET /v1/site`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SiteDto {
    /// The site file, as given to `--site`.
    pub file: String,
    /// SHA-256 of the site file's bytes, lower-case hex (as `sha256sum` prints it).
    pub sha256: String,
    /// Cameras by id.
    pub cameras: BTreeMap<String, SiteCameraDto>,
    /// Marker sizes.
    pub markers: SiteMarkersDto,
    /// The map, in the file's order.
    pub map: Vec<MappedCodeDto>,
}

fn calibration_format_name(format: CalibrationFormat) -> &'static str {
    match format {
        CalibrationFormat::OpenCv => "opencv",
        CalibrationFormat::RosCameraInfo => "ros_camera_info",
    }
}

impl From<&SiteCamera> for SiteCameraDto {
    fn from(c: &SiteCamera) -> Self {
        let cam = &c.camera;
        Self {
            calibration: match &c.source {
                CameraSource::Calibration {
                    path,
                    format,
                    sha256_hex,
                } => Some(CalibrationFileDto {
                    path: path.clone(),
                    format: calibration_format_name(*format).to_owned(),
                    sha256: sha256_hex.clone(),
                }),
                CameraSource::Inline { .. } => None,
            },
            camera: CameraDto::from(cam),
            image_size_px: c.image_size_px.map(|(w, h)| [w, h]),
            mount: c.camera_mount.as_ref().map(MountDto::from),
        }
    }
}

impl From<&Site> for SiteDto {
    fn from(site: &Site) -> Self {
        let sizes = site
            .sizes()
            .rules
            .iter()
            .map(|r| {
                let mut rule = SizeRuleDto {
                    payload: None,
                    prefix: None,
                    pattern: None,
                    size_mm: r.size_mm,
                };
                match &r.matcher {
                    Matcher::Exact(p) => rule.payload = Some(p.clone()),
                    Matcher::Prefix(p) => rule.prefix = Some(p.clone()),
                    Matcher::Pattern(p) => rule.pattern = Some(p.as_str().to_owned()),
                }
                rule
            })
            .collect();
        Self {
            file: site.file().display().to_string(),
            sha256: site.sha256_hex().to_owned(),
            cameras: site
                .cameras()
                .iter()
                .map(|(id, c)| (id.clone(), SiteCameraDto::from(c)))
                .collect(),
            markers: SiteMarkersDto {
                default_size_mm: site.sizes().default_size_mm,
                sizes,
            },
            map: site
                .map()
                .iter()
                .map(|m| {
                    let rigid = RigidDto::from(&m.pose);
                    MappedCodeDto {
                        payload: m.payload.clone(),
                        translation_mm: rigid.translation_mm,
                        quaternion_wxyz: rigid.quaternion_wxyz,
                    }
                })
                .collect(),
        }
    }
}
