//! The camera of `qrpose-sim render`: as a scene file writes it ([`CameraSpec`], with an optional
//! lens model and coefficients, [`DistortionSpec`]), validated into a core camera, and as the
//! printed JSON gives it.

use crate::cli::problem::Problem;
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use serde::Deserialize;
use serde_json::json;

/// A lens model, by the name ROS `camera_info` gives it (as the service's API spells it).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum LensModel {
    /// Brown-Conrady: k1 k2 p1 p2 k3 (the default).
    #[default]
    PlumbBob,
    /// OpenCV's rational model: k1 k2 p1 p2 k3 k4 k5 k6.
    RationalPolynomial,
    /// OpenCV's fisheye model: k1 k2 k3 k4.
    Equidistant,
}

impl From<LensModel> for DistortionModel {
    fn from(m: LensModel) -> Self {
        match m {
            LensModel::PlumbBob => Self::PlumbBob,
            LensModel::RationalPolynomial => Self::RationalPolynomial,
            LensModel::Equidistant => Self::Equidistant,
        }
    }
}

/// The camera of a scene file (principal point: the image centre when left out).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraSpec {
    pub(super) fx_px: f64,
    pub(super) fy_px: f64,
    #[serde(default)]
    pub(super) cx_px: Option<f64>,
    #[serde(default)]
    pub(super) cy_px: Option<f64>,
    #[serde(default)]
    pub(super) distortion: Option<DistortionSpec>,
}

/// A lens model and its coefficients in OpenCV's order, as the site file writes them.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DistortionSpec {
    #[serde(default)]
    pub(super) model: LensModel,
    pub(super) coefficients: Vec<f64>,
}

impl DistortionSpec {
    /// The lens; a refusal names `field`.
    fn to_distortion(&self, field: &str) -> Result<Distortion, Problem> {
        Distortion::from_coefficients(DistortionModel::from(self.model), &self.coefficients)
            .map_err(|e| Problem::new("invalid_camera_parameter", e.to_string()).with_field(field))
    }
}

impl Default for CameraSpec {
    fn default() -> Self {
        Self {
            fx_px: 1000.0,
            fy_px: 1000.0,
            cx_px: None,
            cy_px: None,
            distortion: None,
        }
    }
}

/// The camera of `spec` for a `width_px` × `height_px` image (principal point: the image
/// centre when left out); a refused distortion names `distortion_field`.
pub(super) fn camera(
    spec: &CameraSpec,
    width_px: u32,
    height_px: u32,
    distortion_field: &str,
) -> Result<Camera, Problem> {
    let cx = spec.cx_px.unwrap_or(f64::from(width_px) / 2.0 - 0.5);
    let cy = spec.cy_px.unwrap_or(f64::from(height_px) / 2.0 - 0.5);
    let camera = Camera::from_pixels(spec.fx_px, spec.fy_px, cx, cy)
        .map_err(|e| Problem::new("invalid_camera_parameter", e.to_string()))?;
    match &spec.distortion {
        Some(d) => Ok(camera.with_distortion(d.to_distortion(distortion_field)?)),
        None => Ok(camera),
    }
}

/// The camera as the printed JSON gives it, with its lens model and coefficients.
pub(super) fn camera_json(c: &Camera) -> serde_json::Value {
    let d = c.distortion();
    json!({
        "fx_px": c.fx(), "fy_px": c.fy(), "cx_px": c.cx(), "cy_px": c.cy(),
        "distortion": {"model": d.model().name(), "coefficients": d.coefficients()},
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(distortion: serde_json::Value) -> CameraSpec {
        serde_json::from_value(json!({"fx_px": 420, "fy_px": 420, "distortion": distortion}))
            .expect("a camera spec")
    }

    #[test]
    fn a_scene_camera_takes_a_fisheye_and_prints_it() {
        let coefficients = [-0.00566, 0.04186, -0.03869, 0.00673];
        let spec = spec(json!({"model": "equidistant", "coefficients": coefficients}));
        let c = camera(&spec, 1280, 800, "/camera/distortion/coefficients").expect("valid");
        assert_eq!((c.cx(), c.cy()), (639.5, 399.5));
        assert_eq!(c.distortion().model(), DistortionModel::Equidistant);
        assert_eq!(
            camera_json(&c)["distortion"],
            json!({"model": "equidistant", "coefficients": coefficients})
        );
    }

    #[test]
    fn a_scene_camera_without_a_model_is_plumb_bob_and_refuses_a_wrong_count() {
        let spec_ok = spec(json!({"coefficients": [-0.1, 0.01, 0.0, 0.0, 0.0]}));
        let c = camera(&spec_ok, 640, 480, "field").expect("valid");
        assert_eq!(c.distortion().model(), DistortionModel::PlumbBob);
        let bad = spec(
            json!({"model": "rational_polynomial", "coefficients": [0.1, 0.1, 0.1, 0.1, 0.1]}),
        );
        let problem = camera(&bad, 640, 480, "/camera/distortion/coefficients")
            .expect_err("five for the rational model");
        assert_eq!(problem.code, "invalid_camera_parameter");
        assert_eq!(
            problem.field.as_deref(),
            Some("/camera/distortion/coefficients")
        );
        assert!(problem.detail.contains("takes 8"), "{}", problem.detail);
    }
}
