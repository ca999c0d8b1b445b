//! A product on a shelf seen by a camera on the arm's flange, for the picking tests of the
//! API and the command line (docs/pick.md): the site file, the true poses (flange, mount,
//! product, code), the code's exact corners and a rendered photo.

// Each test binary uses its own part of it.
#![allow(dead_code)]

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use qrpose::geometry::camera::Camera;
use qrpose::geometry::marker::Marker;
use qrpose_sim::render::{CodePlacement, EcLevel, Effects, Encoding, MultiScene, render_scene};
use serde_json::{Value, json};

/// A wrist camera on the flange, a fixed camera on the robot, and one product rule: a box
/// with its code on the +x face and a suction grasp on its top, about 150 mm from the code.
pub const SITE: &str = "\
cameras:
  wrist:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}
    mount:
      parent: flange
      translation_mm: [0, 60, 40]
      quaternion_wxyz: [0.9961947, 0, 0, 0.0871557]
      std: {rotation_deg: [0.02, 0.02, 0.02], translation_mm: [0.2, 0.2, 0.2]}
  fixed:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}
    mount: {translation_mm: [0, 0, 0], quaternion_wxyz: [1, 0, 0, 0]}
markers:
  default_size_mm: 60
objects:
  - prefix: \"SKU-\"
    box_mm: [200, 150, 224]
    code: {translation_mm: [100, 0, 0], quaternion_wxyz: [0.5, 0.5, -0.5, 0.5]}
    grasps:
      - name: top
        kind: suction
        translation_mm: [0, 0, 112]
        quaternion_wxyz: [0, 1, 0, 0]
        tolerance: {position_mm: 5, rotation_deg: 3}
        approach_mm: 80
      - name: pinch
        kind: parallel
        translation_mm: [0, 0, 0]
        quaternion_wxyz: [0, 1, 0, 0]
        width_mm: 150
        tolerance: {position_mm: 6, rotation_deg: 4}
";

pub fn iso(t: [f64; 3], q: [f64; 4]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3])),
    )
}

/// T_flange←camera of the wrist camera, as the site says.
pub fn mount() -> Isometry3<f64> {
    iso([0.0, 60.0, 40.0], [0.9961947, 0.0, 0.0, 0.0871557])
}

/// T_object←marker of the rule.
pub fn code_on_box() -> Isometry3<f64> {
    iso([100.0, 0.0, 0.0], [0.5, 0.5, -0.5, 0.5])
}

/// T_robot←object: the product on a shelf.
pub fn object_in_robot() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(800.0, 150.0, 300.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3),
    )
}

/// T_robot←flange: the arm holds the camera about 450 mm from the code, looking at it
/// askew (so that the code's pose is not ambiguous).
pub fn flange_pose() -> Isometry3<f64> {
    let code = object_in_robot() * code_on_box();
    let at = Vector3::new(180.0, -90.0, -400.0);
    let look = UnitQuaternion::rotation_between(&Vector3::z(), &-at).expect("not opposite");
    let spin = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.4);
    let camera_in_marker = Isometry3::from_parts(Translation3::from(at), look * spin);
    code * camera_in_marker * mount().inverse()
}

/// T_camera←marker (origin at the code's centre) with the arm at `flange`.
pub fn marker_in_camera(flange: &Isometry3<f64>) -> Isometry3<f64> {
    (flange * mount()).inverse() * object_in_robot() * code_on_box()
}

pub fn pose_json(pose: &Isometry3<f64>) -> Value {
    let (q, t) = (pose.rotation, pose.translation.vector);
    json!({"translation_mm": [t.x, t.y, t.z], "quaternion_wxyz": [q.w, q.i, q.j, q.k]})
}

/// The code's exact corners, paper order, in the wrist camera.
pub fn corners(marker_in_camera: &Isometry3<f64>) -> Value {
    let size = 60.0;
    let centre = Vector3::new(-size / 2.0, size / 2.0, 0.0);
    let corners: Vec<[f64; 2]> = [[0.0, size], [0.0, 0.0], [-size, 0.0], [-size, size]]
        .iter()
        .map(|[x, y]| {
            let p = marker_in_camera * Point3::from(Vector3::new(*x, *y, 0.0) - centre);
            [1000.0 * p.x / p.z + 639.5, 1000.0 * p.y / p.z + 359.5]
        })
        .collect();
    json!(corners)
}

/// A PNG of the product's code seen with the arm at `flange`.
pub fn photo(flange: &Isometry3<f64>) -> Vec<u8> {
    photo_with(
        flange,
        &Effects {
            supersample: 3,
            encoding: Encoding::Png,
            ..Effects::default()
        },
    )
}

/// The product's code seen with the arm at `flange`, rendered with `effects`.
pub fn photo_with(flange: &Isometry3<f64>, effects: &Effects) -> Vec<u8> {
    let marker = Marker::try_new(60.0).expect("a size");
    let in_camera = marker_in_camera(flange);
    let scene = MultiScene {
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a camera"),
        width_px: 1280,
        height_px: 720,
        codes: vec![CodePlacement {
            payload: b"SKU-0042".to_vec(),
            ec_level: EcLevel::M,
            marker,
            pose: marker.pose_centred_at(
                in_camera.rotation.to_rotation_matrix(),
                in_camera.translation.vector,
            ),
        }],
    };
    render_scene(&scene, effects).expect("renders").encoded
}

/// T_robot←grasp of the rule's `top` grasp: the truth.
pub fn top_grasp_in_robot() -> Isometry3<f64> {
    object_in_robot() * iso([0.0, 0.0, 112.0], [0.0, 1.0, 0.0, 0.0])
}

/// The flange poses of an approach: the camera moves in `frames` steps from 800 mm to
/// 250 mm of the code along a ray `tilt_deg` off the code's normal (azimuth `azimuth_deg`),
/// looking at the code's centre.
pub fn approach(frames: usize, tilt_deg: f64, azimuth_deg: f64) -> Vec<Isometry3<f64>> {
    let (tilt, az) = (tilt_deg.to_radians(), azimuth_deg.to_radians());
    let ray = Vector3::new(tilt.sin() * az.cos(), tilt.sin() * az.sin(), -tilt.cos());
    let code = object_in_robot() * code_on_box();
    (0..frames)
        .map(|k| {
            let distance_mm = 800.0 - 550.0 * k as f64 / (frames - 1).max(1) as f64;
            let at = distance_mm * ray;
            let look = UnitQuaternion::rotation_between(&Vector3::z(), &-at).expect("not opposite");
            code * Isometry3::from_parts(Translation3::from(at), look) * mount().inverse()
        })
        .collect()
}
