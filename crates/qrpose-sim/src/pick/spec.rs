//! The scene file of a picking study: poses, the camera, products with their grasps, the
//! photos' flange poses (docs/rendering.md, Picking scenes).

use super::{PickSceneError, UNIT_QUATERNION_TOLERANCE};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use serde::{Deserialize, Serialize};

/// A rigid transform as the scene and truth files write it: p_a = R·p_b + t.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseSpec {
    /// t, mm.
    pub translation_mm: [f64; 3],
    /// R as (w, x, y, z), w ≥ 0 when written by this module.
    pub quaternion_wxyz: [f64; 4],
}

impl PoseSpec {
    /// The transform, or `None` for a non-unit quaternion or a value that is not finite.
    pub fn to_isometry(&self) -> Option<Isometry3<f64>> {
        let [w, x, y, z] = self.quaternion_wxyz;
        let q = Quaternion::new(w, x, y, z);
        let finite = self
            .translation_mm
            .iter()
            .chain(&self.quaternion_wxyz)
            .all(|v| v.is_finite());
        if !finite || (q.norm() - 1.0).abs() > UNIT_QUATERNION_TOLERANCE {
            return None;
        }
        Some(Isometry3::from_parts(
            Translation3::from(Vector3::from(self.translation_mm)),
            UnitQuaternion::from_quaternion(q),
        ))
    }

    /// The spec of `iso`, quaternion with w ≥ 0.
    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        let q = iso.rotation.into_inner();
        let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
        let t = iso.translation.vector;
        Self {
            translation_mm: [t.x, t.y, t.z],
            quaternion_wxyz: [sign * q.w, sign * q.i, sign * q.j, sign * q.k],
        }
    }
}

/// A lens model, by the name ROS `camera_info` gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LensModelName {
    /// Brown-Conrady k1 k2 p1 p2 k3.
    PlumbBob,
    /// k1 k2 p1 p2 k3 k4 k5 k6.
    RationalPolynomial,
    /// Kannala-Brandt fisheye k1 k2 k3 k4.
    Equidistant,
}

/// A lens: model and coefficients in OpenCV's order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LensSpec {
    /// The model.
    pub model: LensModelName,
    /// Its coefficients.
    pub coefficients: Vec<f64>,
}

/// The camera: intrinsics, image size and lens.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Focal length, px.
    pub fx_px: f64,
    /// Focal length, px.
    pub fy_px: f64,
    /// Principal point, px.
    pub cx_px: f64,
    /// Principal point, px.
    pub cy_px: f64,
    /// Image width, px.
    pub width_px: u32,
    /// Image height, px.
    pub height_px: u32,
    /// The lens distortion; none when left out.
    #[serde(default)]
    pub distortion: Option<LensSpec>,
}

impl CameraSpec {
    /// The core camera.
    ///
    /// # Errors
    /// [`PickSceneError::Camera`] for intrinsics or distortion the model refuses.
    pub fn camera(&self) -> Result<Camera, PickSceneError> {
        let refused = |detail: String| PickSceneError::Camera { detail };
        let camera = Camera::from_pixels(self.fx_px, self.fy_px, self.cx_px, self.cy_px)
            .map_err(|e| refused(e.to_string()))?;
        let Some(lens) = &self.distortion else {
            return Ok(camera);
        };
        let model = match lens.model {
            LensModelName::PlumbBob => DistortionModel::PlumbBob,
            LensModelName::RationalPolynomial => DistortionModel::RationalPolynomial,
            LensModelName::Equidistant => DistortionModel::Equidistant,
        };
        let distortion = Distortion::from_coefficients(model, &lens.coefficients)
            .map_err(|e| refused(e.to_string()))?;
        Ok(camera.with_distortion(distortion))
    }
}

/// A grasp of a product, for the truth: T_object←grasp.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraspSpec {
    /// Its name.
    pub name: String,
    /// T_object←grasp.
    pub pose: PoseSpec,
}

/// A product: a box with a code on a face, standing in the robot's frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProductSpec {
    /// The code's payload.
    pub payload: String,
    /// The code's side, mm (the symbol without its quiet zone).
    pub code_size_mm: f64,
    /// The box's extents along the object's x, y, z, mm (origin at its centre).
    pub box_mm: [f64; 3],
    /// T_robot←object.
    pub object_in_robot: PoseSpec,
    /// T_object←marker.
    pub marker_in_object: PoseSpec,
    /// Grasps whose true poses the truth gives (none when left out).
    #[serde(default)]
    pub grasps: Vec<GraspSpec>,
}

/// One photo: where the flange was.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhotoSpec {
    /// A name for the photo (its file is `LABEL.png` or `.jpg`).
    pub label: String,
    /// T_robot←flange when the photo was taken.
    pub flange_pose: PoseSpec,
}

/// A picking scene: one camera on the flange, products, photos.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PickScene {
    /// The camera.
    pub camera: CameraSpec,
    /// T_flange←camera.
    pub mount: PoseSpec,
    /// The products.
    pub products: Vec<ProductSpec>,
    /// The photos, in order.
    pub photos: Vec<PhotoSpec>,
}
