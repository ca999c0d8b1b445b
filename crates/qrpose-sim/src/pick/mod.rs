//! Ground truth for picking (docs/rendering.md, Picking scenes): products (boxes with a code on
//! a face) standing in the robot's frame, photographed by a camera on the arm's flange from
//! given flange poses, with the truth of every product in view.
//!
//! Frames (docs/site.md, Frames; docs/conventions.md): a pose T_ab maps points of b into a,
//! p_a = R·p_b + t, written `{translation_mm, quaternion_wxyz}`. The scene gives the mount
//! T_flange←camera, per photo the flange pose T_robot←flange, per product T_robot←object and
//! T_object←marker (marker origin at the symbol's centre, x to the symbol's right, y down it,
//! z into the printed face). The camera is T_robot←camera = T_robot←flange · T_flange←camera;
//! a code is T_camera←marker = (T_robot←camera)⁻¹ · T_robot←object · T_object←marker.
//!
//! Only the codes are drawn (on the renderer's background, [`crate::render::render_scene`]);
//! the boxes' faces are not. A product is in a photo when its code faces the camera and the
//! code with its quiet zone lies inside the image; codes of different products that overlap in
//! the image are both drawn (keep products apart: the study generator places them 10 m
//! apart and keeps only cameras that see one).

mod spec;
pub mod study;

pub use spec::{
    CameraSpec, GraspSpec, LensModelName, LensSpec, PhotoSpec, PickScene, PoseSpec, ProductSpec,
};

use crate::render::{
    CodePlacement, EcLevel, Effects, GroundTruth, MultiScene, RenderError, code_outline_px,
    render_scene,
};
use nalgebra::{Isometry3, Vector3};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::marker::Marker;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// How far a scene's quaternion norm may be from 1.
pub const UNIT_QUATERNION_TOLERANCE: f64 = 1e-3;

/// Why a picking scene cannot be rendered.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PickSceneError {
    /// A quaternion whose norm is off 1 by more than [`UNIT_QUATERNION_TOLERANCE`], or a
    /// value that is not finite.
    #[error("{field}: not a rigid transform (a unit quaternion and finite numbers)")]
    Pose {
        /// The field, a JSON pointer.
        field: String,
    },
    /// Intrinsics or distortion the camera model refuses.
    #[error("camera: {detail}")]
    Camera {
        /// The camera model's reason.
        detail: String,
    },
    /// A code size or box size that is not positive.
    #[error("{field}: must be a positive number of mm")]
    Size {
        /// The field, a JSON pointer.
        field: String,
    },
    /// The study generator drew no camera that sees this product alone.
    #[error("no camera drawn sees product {product} alone")]
    NoView {
        /// The product's index.
        product: usize,
    },
    /// The renderer refused a photo.
    #[error("photo {index}: {error}")]
    Render {
        /// The photo's index.
        index: usize,
        /// Why.
        error: RenderError,
    },
}

/// The truth of one grasp: its pose in the robot frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraspTruth {
    /// The grasp's name.
    pub name: String,
    /// T_robot←grasp.
    pub in_robot: PoseSpec,
    /// T_camera←grasp.
    pub in_camera: PoseSpec,
}

/// The truth of one product in one photo.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProductTruth {
    /// Its index in [`PickScene::products`].
    pub product: usize,
    /// Its payload.
    pub payload: String,
    /// T_camera←object.
    pub object_in_camera: PoseSpec,
    /// T_robot←object.
    pub object_in_robot: PoseSpec,
    /// T_camera←marker (origin at the symbol's centre).
    pub marker_in_camera: PoseSpec,
    /// The code's corners and finder corners, px, qr order (TL, TR, BR, BL).
    pub code: GroundTruth,
    /// Its grasps.
    pub grasps: Vec<GraspTruth>,
}

/// The truth of one photo.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhotoTruth {
    /// Its index in [`PickScene::photos`].
    pub index: usize,
    /// Its label.
    pub label: String,
    /// T_robot←flange.
    pub flange_pose: PoseSpec,
    /// T_robot←camera.
    pub camera_in_robot: PoseSpec,
    /// Every product in view.
    pub products: Vec<ProductTruth>,
}

/// A rendered photo of a picking scene.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedPick {
    /// The encoded image (PNG or JPEG, as the effects say).
    pub encoded: Vec<u8>,
    /// Its truth.
    pub truth: PhotoTruth,
}

/// The checked geometry of a product.
struct Product<'a> {
    spec: &'a ProductSpec,
    marker: Marker,
    object_in_robot: Isometry3<f64>,
    marker_in_object: Isometry3<f64>,
    grasps: Vec<(&'a str, Isometry3<f64>)>,
}

fn pose_at(spec: &PoseSpec, field: String) -> Result<Isometry3<f64>, PickSceneError> {
    spec.to_isometry().ok_or(PickSceneError::Pose { field })
}

fn products(scene: &PickScene) -> Result<Vec<Product<'_>>, PickSceneError> {
    scene
        .products
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let marker = Marker::try_new(p.code_size_mm).map_err(|_| PickSceneError::Size {
                field: format!("/products/{i}/code_size_mm"),
            })?;
            if !p.box_mm.iter().all(|x| x.is_finite() && *x > 0.0) {
                return Err(PickSceneError::Size {
                    field: format!("/products/{i}/box_mm"),
                });
            }
            let grasps = p
                .grasps
                .iter()
                .enumerate()
                .map(|(k, g)| {
                    pose_at(&g.pose, format!("/products/{i}/grasps/{k}/pose"))
                        .map(|pose| (g.name.as_str(), pose))
                })
                .collect::<Result<_, _>>()?;
            Ok(Product {
                spec: p,
                marker,
                object_in_robot: pose_at(
                    &p.object_in_robot,
                    format!("/products/{i}/object_in_robot"),
                )?,
                marker_in_object: pose_at(
                    &p.marker_in_object,
                    format!("/products/{i}/marker_in_object"),
                )?,
                grasps,
            })
        })
        .collect()
}

/// Whether the printed face of a code at `marker_in_camera` faces the camera: its z axis
/// (into the printed face) points away from the camera.
fn faces_camera(marker_in_camera: &Isometry3<f64>) -> bool {
    let z = marker_in_camera.rotation * Vector3::z();
    z.dot(&marker_in_camera.translation.vector) > 0.0
}

/// The indices of the products of `scene` in view from `camera_in_robot` (each one's code
/// faces the camera and lies, with `quiet_zone_modules` of quiet zone, inside the image).
///
/// # Errors
/// As [`render_pick_scene`], for the scene's camera and products.
pub fn products_in_view(
    scene: &PickScene,
    camera_in_robot: &Isometry3<f64>,
    quiet_zone_modules: f64,
) -> Result<Vec<usize>, PickSceneError> {
    let camera = scene.camera.camera()?;
    Ok(products(scene)?
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            placement_in_view(&camera, scene, p, camera_in_robot, quiet_zone_modules).is_some()
        })
        .map(|(i, _)| i)
        .collect())
}

/// The code of a product seen from `camera_in_robot`, when it is in view.
fn placement_in_view(
    camera: &Camera,
    scene: &PickScene,
    product: &Product<'_>,
    camera_in_robot: &Isometry3<f64>,
    quiet_zone_modules: f64,
) -> Option<(CodePlacement, Isometry3<f64>)> {
    let marker_in_camera =
        camera_in_robot.inverse() * product.object_in_robot * product.marker_in_object;
    if !faces_camera(&marker_in_camera) {
        return None;
    }
    let placement = CodePlacement {
        payload: product.spec.payload.as_bytes().to_vec(),
        ec_level: EcLevel::M,
        marker: product.marker,
        pose: product.marker.pose_centred_at(
            marker_in_camera.rotation.to_rotation_matrix(),
            marker_in_camera.translation.vector,
        ),
    };
    let outline = code_outline_px(camera, &placement, quiet_zone_modules).ok()?;
    let (w, h) = (
        f64::from(scene.camera.width_px) - 0.5,
        f64::from(scene.camera.height_px) - 0.5,
    );
    let inside = outline
        .iter()
        .all(|p| p[0] >= -0.5 && p[1] >= -0.5 && p[0] <= w && p[1] <= h);
    inside.then_some((placement, marker_in_camera))
}

/// T_robot←camera for a photo: T_robot←flange · T_flange←camera.
///
/// # Errors
/// [`PickSceneError::Pose`] for a refused mount or flange pose.
pub fn camera_in_robot(scene: &PickScene, photo: usize) -> Result<Isometry3<f64>, PickSceneError> {
    let mount = pose_at(&scene.mount, "/mount".to_owned())?;
    let flange = scene
        .photos
        .get(photo)
        .ok_or(PickSceneError::Pose {
            field: format!("/photos/{photo}"),
        })
        .and_then(|p| pose_at(&p.flange_pose, format!("/photos/{photo}/flange_pose")))?;
    Ok(flange * mount)
}

/// Renders every photo of `scene` with `effects` (photo i with seed `effects.seed + i`),
/// with the truth of every product in view; photos in parallel (rayon), returned in order.
///
/// # Errors
/// A [`PickSceneError`] for a refused pose, size or camera, or a photo the renderer
/// refuses.
pub fn render_pick_scene(
    scene: &PickScene,
    effects: &Effects,
) -> Result<Vec<RenderedPick>, PickSceneError> {
    let camera = scene.camera.camera()?;
    let products = products(scene)?;
    (0..scene.photos.len())
        .into_par_iter()
        .map(|index| render_photo(scene, &camera, &products, index, effects))
        .collect()
}

fn render_photo(
    scene: &PickScene,
    camera: &Camera,
    products: &[Product<'_>],
    index: usize,
    effects: &Effects,
) -> Result<RenderedPick, PickSceneError> {
    let camera_in_robot = camera_in_robot(scene, index)?;
    let photo = &scene.photos[index];
    let in_view: Vec<(usize, CodePlacement, Isometry3<f64>)> = products
        .iter()
        .enumerate()
        .filter_map(|(i, p)| {
            placement_in_view(
                camera,
                scene,
                p,
                &camera_in_robot,
                effects.quiet_zone_modules,
            )
            .map(|(placement, pose)| (i, placement, pose))
        })
        .collect();
    let multi = MultiScene {
        camera: *camera,
        width_px: scene.camera.width_px,
        height_px: scene.camera.height_px,
        codes: in_view.iter().map(|(_, c, _)| c.clone()).collect(),
    };
    let photo_effects = Effects {
        seed: effects.seed.wrapping_add(index as u64),
        ..*effects
    };
    let rendered = render_scene(&multi, &photo_effects)
        .map_err(|error| PickSceneError::Render { index, error })?;
    let robot_in_camera = camera_in_robot.inverse();
    let truths = in_view
        .iter()
        .zip(rendered.truth)
        .map(|((i, _, marker_in_camera), code)| {
            let p = &products[*i];
            ProductTruth {
                product: *i,
                payload: p.spec.payload.clone(),
                object_in_camera: PoseSpec::from_isometry(&(robot_in_camera * p.object_in_robot)),
                object_in_robot: PoseSpec::from_isometry(&p.object_in_robot),
                marker_in_camera: PoseSpec::from_isometry(marker_in_camera),
                code,
                grasps: p
                    .grasps
                    .iter()
                    .map(|(name, g)| GraspTruth {
                        name: (*name).to_owned(),
                        in_robot: PoseSpec::from_isometry(&(p.object_in_robot * g)),
                        in_camera: PoseSpec::from_isometry(
                            &(robot_in_camera * p.object_in_robot * g),
                        ),
                    })
                    .collect(),
            }
        })
        .collect();
    Ok(RenderedPick {
        encoded: rendered.encoded,
        truth: PhotoTruth {
            index,
            label: photo.label.clone(),
            flange_pose: photo.flange_pose,
            camera_in_robot: PoseSpec::from_isometry(&camera_in_robot),
            products: truths,
        },
    })
}
