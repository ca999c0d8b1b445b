//! The camera of a request: [`CameraDto`] (pixel, sensor or image-plane form) with its lens
//! distortion, and its validation into a core [`Camera`] (`docs/conventions.md`, Image-plane
//! millimetres and camera forms).

mod forms;

pub use forms::{IMAGE_PLANE, camera_forms, distortion_forms};

use super::problem::{ErrorCode, Problem};
use super::refusal::problem_from_camera_error;
use super::request::CornersUnit;
use crate::geometry::camera::{Camera, CameraError, CameraParam, Distortion, DistortionModel};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A lens model of `camera.distortion`, by the name ROS `camera_info` gives it.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema, clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum DistortionModelDto {
    /// Brown-Conrady: k1 k2 p1 p2 k3 (the default).
    #[default]
    PlumbBob,
    /// OpenCV's rational model: k1 k2 p1 p2 k3 k4 k5 k6.
    RationalPolynomial,
    /// OpenCV's fisheye model: k1 k2 k3 k4, on the angle from the optical axis.
    Equidistant,
}

impl From<DistortionModelDto> for DistortionModel {
    fn from(m: DistortionModelDto) -> Self {
        match m {
            DistortionModelDto::PlumbBob => Self::PlumbBob,
            DistortionModelDto::RationalPolynomial => Self::RationalPolynomial,
            DistortionModelDto::Equidistant => Self::Equidistant,
        }
    }
}

/// Lens distortion with OpenCV's coefficients and meaning, in one of three models
/// (`docs/calibration.md`): `plumb_bob` (the default: k1 k2 p1 p2 k3), `rational_polynomial`
/// (k1 k2 p1 p2 k3 k4 k5 k6) or `equidistant` (fisheye: k1 k2 k3 k4). Omitted coefficients
/// are 0; a coefficient that the model does not have must be omitted or 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DistortionDto {
    /// The lens model: `plumb_bob` when omitted.
    #[serde(default)]
    pub model: Option<DistortionModelDto>,
    /// Radial r² coefficient (`equidistant`: θ³).
    #[serde(default)]
    #[schema(example = -0.12)]
    pub k1: f64,
    /// Radial r⁴ coefficient (`equidistant`: θ⁵).
    #[serde(default)]
    #[schema(example = 0.03)]
    pub k2: f64,
    /// Tangential coefficient p1 (not in `equidistant`).
    #[serde(default)]
    pub p1: f64,
    /// Tangential coefficient p2 (not in `equidistant`).
    #[serde(default)]
    pub p2: f64,
    /// Radial r⁶ coefficient (`equidistant`: θ⁷).
    #[serde(default)]
    pub k3: f64,
    /// `rational_polynomial`: the denominator's r² coefficient; `equidistant`: θ⁹. Not in
    /// `plumb_bob`.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub k4: f64,
    /// `rational_polynomial` only: the denominator's r⁴ coefficient.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub k5: f64,
    /// `rational_polynomial` only: the denominator's r⁶ coefficient.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub k6: f64,
}

/// Whether a coefficient that only the newer models have is unset: k4 k5 k6 are written
/// only when set, so that a `plumb_bob` distortion serialises as it did before them.
fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

impl DistortionDto {
    /// The named coefficients of `coefficients`, given in `model`'s order (OpenCV's), as
    /// the command line's `--distortion-coefficients` gives them.
    ///
    /// # Errors
    /// `invalid_camera_parameter` at `/camera/distortion` for a count the model does not
    /// take or a non-finite coefficient.
    pub fn from_coefficients(
        model: DistortionModelDto,
        coefficients: &[f64],
    ) -> Result<Self, Problem> {
        Distortion::from_coefficients(model.into(), coefficients)
            .map(|lens| Self::from(&lens))
            .map_err(|e| {
                Problem::new(ErrorCode::InvalidCameraParameter, e.to_string())
                    .with_field("/camera/distortion")
            })
    }

    /// The core distortion these coefficients describe; fields are reported below
    /// `camera_pointer` (`/camera/distortion/k4`).
    ///
    /// # Errors
    /// `non_finite_number` naming a NaN or infinite coefficient; `invalid_camera_parameter`
    /// naming a non-zero coefficient that the model does not have.
    pub fn to_distortion(&self, camera_pointer: &str) -> Result<Distortion, Problem> {
        let model = DistortionModel::from(self.model.unwrap_or_default());
        let named = [
            (CameraParam::K1, self.k1),
            (CameraParam::K2, self.k2),
            (CameraParam::P1, self.p1),
            (CameraParam::P2, self.p2),
            (CameraParam::K3, self.k3),
            (CameraParam::K4, self.k4),
            (CameraParam::K5, self.k5),
            (CameraParam::K6, self.k6),
        ];
        if let Some(&(param, _)) = named.iter().find(|(_, v)| !v.is_finite()) {
            return Err(problem_from_camera_error(
                CameraError::NonFinite { param },
                camera_pointer,
            ));
        }
        if let Some(&(param, value)) = named
            .iter()
            .find(|(p, v)| *v != 0.0 && !model.params().contains(p))
        {
            let takes: Vec<&str> = model.params().iter().map(|p| p.name()).collect();
            return Err(Problem::new(
                ErrorCode::InvalidCameraParameter,
                format!(
                    "{param} = {value} is not a coefficient of the {model} model (it takes {}); omit it or set the model",
                    takes.join(", ")
                ),
            )
            .with_field(format!("{camera_pointer}/distortion/{param}")));
        }
        let coefficients: Vec<f64> = model
            .params()
            .iter()
            .filter_map(|p| named.iter().find(|(q, _)| q == p).map(|&(_, v)| v))
            .collect();
        Distortion::from_coefficients(model, &coefficients).map_err(|e| {
            Problem::new(ErrorCode::InvalidCameraParameter, e.to_string())
                .with_field(format!("{camera_pointer}/distortion"))
        })
    }
}

/// Camera intrinsics, in exactly one of three forms:
/// pixels (`fx_px, fy_px, cx_px, cy_px`); sensor (`focal_length_mm, pixel_size_um, cx_px,
/// cy_px`, so fx = fy = focal length / pixel size); or, with `corners_mm` only, the paper's
/// image plane (`focal_length_mm`, plus optionally `pixel_size_um` to get pixel diagnostics);
/// or, with a site loaded, by `id` alone.
///
/// Answers that give a camera (`POST /v1/calibrate`, `GET /v1/site`) give it in this shape,
/// pixel form, so that a request takes it as it is.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraDto {
    /// The id of a camera of the loaded site (`qrpose serve --site`), instead of every
    /// other field: its calibration, distortion and mount come from the site
    /// (`docs/site.md`).
    #[schema(min_length = 1)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    /// Horizontal focal length, px.
    #[schema(example = 1000.0, minimum = 1e-3, maximum = 1e9)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fx_px: Option<f64>,
    /// Vertical focal length, px.
    #[schema(example = 1000.0, minimum = 1e-3, maximum = 1e9)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fy_px: Option<f64>,
    /// Principal point, horizontal, px (pixel centres are integers: the image centre of a
    /// 1280-px-wide image is 639.5).
    #[schema(example = 639.5)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cx_px: Option<f64>,
    /// Principal point, vertical, px.
    #[schema(example = 359.5)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cy_px: Option<f64>,
    /// Lens focal length, mm (sensor or paper form).
    #[schema(minimum = 1e-3, maximum = 1e5)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub focal_length_mm: Option<f64>,
    /// Pixel pitch, µm (sensor form).
    #[schema(minimum = 1e-3, maximum = 1e5)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pixel_size_um: Option<f64>,
    /// Lens distortion of the corner pixels; none when omitted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distortion: Option<DistortionDto>,
}

impl From<&Distortion> for DistortionDto {
    /// The named coefficients of `lens`, its model always written.
    fn from(lens: &Distortion) -> Self {
        let model = lens.model();
        let mut dto = Self {
            model: Some(model.into()),
            ..Self::default()
        };
        for (param, value) in model.params().iter().zip(lens.coefficients()) {
            match param {
                CameraParam::K1 => dto.k1 = value,
                CameraParam::K2 => dto.k2 = value,
                CameraParam::P1 => dto.p1 = value,
                CameraParam::P2 => dto.p2 = value,
                CameraParam::K3 => dto.k3 = value,
                CameraParam::K4 => dto.k4 = value,
                CameraParam::K5 => dto.k5 = value,
                CameraParam::K6 => dto.k6 = value,
                _ => {}
            }
        }
        dto
    }
}

impl From<&Camera> for CameraDto {
    /// The pixel form of `camera`, with its lens: what a pose request takes as it is.
    fn from(camera: &Camera) -> Self {
        Self {
            fx_px: Some(camera.fx()),
            fy_px: Some(camera.fy()),
            cx_px: Some(camera.cx()),
            cy_px: Some(camera.cy()),
            distortion: Some(DistortionDto::from(camera.distortion())),
            ..Self::default()
        }
    }
}

/// The focal lengths a pixel camera may have, px: what the schema states and the server
/// checks first. Far wider than any lens, and narrow enough that no ray coordinate of a
/// corner within the image limits leaves the solvers' double-precision range.
pub const FOCAL_RANGE_PX: (f64, f64) = (1e-3, 1e9);
/// The lens focal lengths and pixel pitches the sensor form may have, mm and µm.
pub const SENSOR_RANGE: (f64, f64) = (1e-3, 1e5);

/// The camera's numbers outside their stated ranges, as problems at `camera_pointer/NAME`
/// (`invalid_camera_parameter`; `non_finite_number` for NaN or infinity).
///
/// # Errors
/// The first value out of range.
pub fn check_ranges(camera: &CameraDto, camera_pointer: &str) -> Result<(), Problem> {
    let checked = [
        (camera.fx_px, CameraParam::FxPx, FOCAL_RANGE_PX),
        (camera.fy_px, CameraParam::FyPx, FOCAL_RANGE_PX),
        (
            camera.focal_length_mm,
            CameraParam::FocalLengthMm,
            SENSOR_RANGE,
        ),
        (camera.pixel_size_um, CameraParam::PixelSizeUm, SENSOR_RANGE),
    ];
    for (value, param, (low, high)) in checked {
        let Some(v) = value else { continue };
        if !v.is_finite() {
            return Err(problem_from_camera_error(
                CameraError::NonFinite { param },
                camera_pointer,
            ));
        }
        if !(low..=high).contains(&v) {
            return Err(Problem::new(
                ErrorCode::InvalidCameraParameter,
                format!("{param} = {v:e} is outside [{low:e}, {high:e}]"),
            )
            .with_field(format!("{camera_pointer}/{param}")));
        }
    }
    Ok(())
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
        check_ranges(self, "/camera")?;
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
        let distortion = self
            .distortion
            .unwrap_or_default()
            .to_distortion("/camera")?;
        Ok((camera.with_distortion(distortion), mm_per_px))
    }
}

#[cfg(test)]
mod tests;
