//! The camera of a request: [`CameraDto`] (pixel, sensor or image-plane form) with its lens
//! distortion, and its validation into a core [`Camera`] (`docs/conventions.md`, Image-plane
//! millimetres and camera forms).

use super::problem::{ErrorCode, Problem};
use super::refusal::problem_from_camera_error;
use super::request::CornersUnit;
use crate::geometry::camera::{Camera, Distortion};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// Brown-Conrady lens distortion, OpenCV's coefficients and meaning. Omitted terms are 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DistortionDto {
    /// Radial r² coefficient.
    #[serde(default)]
    #[schema(example = -0.12)]
    pub k1: f64,
    /// Radial r⁴ coefficient.
    #[serde(default)]
    #[schema(example = 0.03)]
    pub k2: f64,
    /// Tangential coefficient p1.
    #[serde(default)]
    pub p1: f64,
    /// Tangential coefficient p2.
    #[serde(default)]
    pub p2: f64,
    /// Radial r⁶ coefficient.
    #[serde(default)]
    pub k3: f64,
}

/// Camera intrinsics, in exactly one of three forms:
/// pixels (`fx_px, fy_px, cx_px, cy_px`); sensor (`focal_length_mm, pixel_size_um, cx_px,
/// cy_px`, so fx = fy = focal length / pixel size); or, with `corners_mm` only, the paper's
/// image plane (`focal_length_mm`, plus optionally `pixel_size_um` to get pixel diagnostics).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraDto {
    /// Horizontal focal length, px.
    #[schema(example = 1000.0)]
    pub fx_px: Option<f64>,
    /// Vertical focal length, px.
    #[schema(example = 1000.0)]
    pub fy_px: Option<f64>,
    /// Principal point, horizontal, px (pixel centres are integers: the image centre of a
    /// 1280-px-wide image is 639.5).
    #[schema(example = 639.5)]
    pub cx_px: Option<f64>,
    /// Principal point, vertical, px.
    #[schema(example = 359.5)]
    pub cy_px: Option<f64>,
    /// Lens focal length, mm (sensor or paper form).
    pub focal_length_mm: Option<f64>,
    /// Pixel pitch, µm (sensor form).
    pub pixel_size_um: Option<f64>,
    /// Lens distortion of the corner pixels; none when omitted.
    pub distortion: Option<DistortionDto>,
}

fn incomplete(detail: impl Into<String>, field: impl Into<String>) -> Problem {
    Problem::new(ErrorCode::IncompleteCamera, detail).with_field(field)
}

fn require(value: Option<f64>, name: &str, form: &str) -> Result<f64, Problem> {
    value.ok_or_else(|| {
        incomplete(
            format!("the {form} form of the camera needs {name}"),
            format!("/camera/{name}"),
        )
    })
}

impl CameraDto {
    /// Builds the camera for corners in `unit`, and for mm corners with a pixel size the
    /// mm-per-pixel scale that turns them into pixels.
    ///
    /// # Errors
    /// `incomplete_camera` for a missing or conflicting form, `invalid_camera_parameter` or
    /// `non_finite_number` for a bad value.
    pub fn to_camera(&self, unit: CornersUnit) -> Result<(Camera, Option<f64>), Problem> {
        let has_px = self.fx_px.is_some() || self.fy_px.is_some();
        let has_sensor = self.focal_length_mm.is_some() || self.pixel_size_um.is_some();
        let err = |e| problem_from_camera_error(e, "/camera");
        let (camera, mm_per_px) = match unit {
            CornersUnit::Px if has_px && has_sensor => {
                return Err(incomplete(
                    "give fx_px/fy_px or focal_length_mm/pixel_size_um, not both",
                    "/camera",
                ));
            }
            CornersUnit::Px if has_px => {
                let fx = require(self.fx_px, "fx_px", "pixel")?;
                let fy = require(self.fy_px, "fy_px", "pixel")?;
                let cx = require(self.cx_px, "cx_px", "pixel")?;
                let cy = require(self.cy_px, "cy_px", "pixel")?;
                (Camera::from_pixels(fx, fy, cx, cy).map_err(err)?, None)
            }
            CornersUnit::Px if has_sensor => {
                let f = require(self.focal_length_mm, "focal_length_mm", "sensor")?;
                let pitch = require(self.pixel_size_um, "pixel_size_um", "sensor")?;
                let cx = require(self.cx_px, "cx_px", "sensor")?;
                let cy = require(self.cy_px, "cy_px", "sensor")?;
                (
                    Camera::from_focal_length(f, pitch, cx, cy).map_err(err)?,
                    None,
                )
            }
            CornersUnit::Px => {
                return Err(incomplete(
                    "the camera needs fx_px, fy_px, cx_px, cy_px or focal_length_mm, pixel_size_um, cx_px, cy_px",
                    "/camera",
                ));
            }
            CornersUnit::Mm => {
                for (value, name) in [
                    (self.fx_px, "fx_px"),
                    (self.fy_px, "fy_px"),
                    (self.cx_px, "cx_px"),
                    (self.cy_px, "cy_px"),
                ] {
                    if value.is_some() {
                        return Err(incomplete(
                            format!(
                                "corners_mm are relative to the principal point and take focal_length_mm, not {name}"
                            ),
                            format!("/camera/{name}"),
                        ));
                    }
                }
                let f = require(self.focal_length_mm, "focal_length_mm", "image-plane")?;
                match self.pixel_size_um {
                    Some(pitch) => {
                        let camera = Camera::from_focal_length(f, pitch, 0.0, 0.0).map_err(err)?;
                        (camera, Some(pitch * 1e-3))
                    }
                    None => (Camera::image_plane_mm(f).map_err(err)?, None),
                }
            }
        };
        let d = self.distortion.unwrap_or_default();
        let distortion = Distortion::try_new(d.k1, d.k2, d.p1, d.p2, d.k3).map_err(err)?;
        Ok((camera.with_distortion(distortion), mm_per_px))
    }
}
