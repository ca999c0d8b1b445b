//! Rendered hand-eye sessions with a known mount, for the tests of
//! `POST /v1/calibrate/hand-eye` and `qrpose calibrate hand-eye`: a 640 × 480 camera with
//! barrel distortion looks at one printed 100 mm code from 300-420 mm, tilted by 20-35°
//! about different axes; the flange poses follow from the mount and the target (exact: the
//! rendered views are the truth, the poses reported are the true ones).

// Each test binary uses its own part of it.
#![allow(dead_code)]

use nalgebra::{Isometry3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use qrpose::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose::geometry::marker::Marker;
use qrpose_sim::render::{EcLevel, Effects, Encoding, Scene, render};
use serde_json::{Value, json};

/// Width and height of the photos, px.
pub const SIZE_PX: (u32, u32) = (640, 480);
/// The printed code's side, mm.
pub const CODE_MM: f64 = 100.0;

/// The camera that takes the photos.
pub fn camera() -> Camera {
    let lens =
        Distortion::from_coefficients(DistortionModel::PlumbBob, &[-0.12, 0.03, 0.0, 0.0, 0.0])
            .expect("a lens");
    Camera::from_pixels(600.0, 600.0, 321.0, 238.0)
        .expect("a camera")
        .with_distortion(lens)
}

/// The camera as a request's `camera`.
pub fn camera_json() -> Value {
    json!({"fx_px": 600.0, "fy_px": 600.0, "cx_px": 321.0, "cy_px": 238.0,
           "distortion": {"k1": -0.12, "k2": 0.03}})
}

/// Where the camera is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Setup {
    /// On the flange.
    EyeInHand,
    /// Still; the code on the flange.
    EyeToHand,
}

/// T_flange←camera (eye-in-hand) or T_robot←camera (eye-to-hand): the truth.
pub fn camera_pose(setup: Setup) -> Isometry3<f64> {
    match setup {
        Setup::EyeInHand => iso([35.0, -60.0, 95.0], [0.3, -0.2, 1.4]),
        Setup::EyeToHand => iso([900.0, 150.0, 700.0], [2.4, 0.1, -0.5]),
    }
}

/// T_robot←marker (eye-in-hand) or T_flange←marker (eye-to-hand), the marker frame's origin
/// at the symbol's centre: the truth.
pub fn target_pose(setup: Setup) -> Isometry3<f64> {
    match setup {
        Setup::EyeInHand => iso([650.0, -40.0, 20.0], [0.05, -0.1, 0.7]),
        Setup::EyeToHand => iso([10.0, 20.0, 140.0], [0.2, 0.1, 0.3]),
    }
}

fn iso(t: [f64; 3], scaled_axis: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_scaled_axis(Vector3::from(scaled_axis)),
    )
}

/// One view: distance mm, tilt deg, tilt azimuth deg, spin about the optical axis deg.
type ViewSpec = (f64, f64, f64, f64);

/// Views that turn about many axes.
pub const VIEWS: [ViewSpec; 8] = [
    (320.0, 30.0, 0.0, 0.0),
    (350.0, 25.0, 90.0, 40.0),
    (330.0, 35.0, 180.0, -30.0),
    (360.0, 30.0, 270.0, 70.0),
    (400.0, 20.0, 45.0, -60.0),
    (380.0, 30.0, 135.0, 15.0),
    (420.0, 25.0, 225.0, 100.0),
    (340.0, 35.0, 315.0, -90.0),
];

/// T_marker←camera of every view of [`VIEWS`].
pub fn views() -> Vec<Isometry3<f64>> {
    VIEWS.iter().map(camera_in_marker).collect()
}

/// Six views that differ only by a turn about the code's normal through its centre: every
/// motion of the flange turns about one axis, so the mount cannot be told.
pub fn orbit() -> Vec<Isometry3<f64>> {
    let first = camera_in_marker(&(350.0, 30.0, 0.0, 0.0));
    (0..6)
        .map(|k| {
            let turn = UnitQuaternion::from_axis_angle(
                &Vector3::z_axis(),
                f64::from(k) * 60f64.to_radians(),
            );
            Isometry3::from_parts(Translation3::identity(), turn) * first
        })
        .collect()
}

/// T_marker←camera of a view: the camera `distance` from the code's centre, on a ray
/// tilted from the code's normal, looking at the centre, turned about its optical axis.
fn camera_in_marker(&(distance_mm, tilt_deg, azimuth_deg, spin_deg): &ViewSpec) -> Isometry3<f64> {
    let (tilt, az) = (tilt_deg.to_radians(), azimuth_deg.to_radians());
    // The code faces the camera along its −z.
    let position =
        distance_mm * Vector3::new(tilt.sin() * az.cos(), tilt.sin() * az.sin(), -tilt.cos());
    let axis = Unit::new_normalize(Vector3::z().cross(&-position));
    let look = if axis.norm() > 0.0 {
        Rotation3::from_axis_angle(&axis, Vector3::z().angle(&-position))
    } else {
        Rotation3::identity()
    };
    let r = look * Rotation3::from_axis_angle(&Vector3::z_axis(), spin_deg.to_radians());
    Isometry3::from_parts(
        Translation3::from(position),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// The flange pose (T_robot←flange) of each view, as a controller's quaternion.
pub fn flange_poses(setup: Setup, views: &[Isometry3<f64>]) -> Vec<Isometry3<f64>> {
    views
        .iter()
        .map(|marker_to_camera| {
            match setup {
                // T_robot←flange = T_robot←marker · T_marker←camera · T_camera←flange.
                Setup::EyeInHand => {
                    target_pose(setup) * marker_to_camera * camera_pose(setup).inverse()
                }
                // T_robot←flange = T_robot←camera · T_camera←marker · T_marker←flange.
                Setup::EyeToHand => {
                    camera_pose(setup) * marker_to_camera.inverse() * target_pose(setup).inverse()
                }
            }
        })
        .collect()
}

/// The photos of `views` (T_marker←camera each) as JPEG files.
pub fn photos(views: &[Isometry3<f64>]) -> Vec<Vec<u8>> {
    let camera = camera();
    let marker = Marker::try_new(CODE_MM).expect("a size");
    views
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let camera_to_marker = v.inverse();
            let scene = Scene {
                payload: b"https://example.com/hand-eye".to_vec(),
                ec_level: EcLevel::M,
                marker,
                camera,
                width_px: SIZE_PX.0,
                height_px: SIZE_PX.1,
                pose: marker.pose_centred_at(
                    camera_to_marker.rotation.to_rotation_matrix(),
                    camera_to_marker.translation.vector,
                ),
            };
            let effects = Effects {
                supersample: 3,
                blur_px: 0.6,
                noise: 1.5,
                encoding: Encoding::Jpeg(92),
                seed: k as u64,
                ..Effects::default()
            };
            render(&scene, &effects).expect("the view renders").encoded
        })
        .collect()
}

/// A pose as the wire's quaternion form.
pub fn quaternion_json(pose: &Isometry3<f64>) -> Value {
    let q = pose.rotation;
    let t = pose.translation.vector;
    json!({"translation_mm": [t.x, t.y, t.z], "quaternion_wxyz": [q.w, q.i, q.j, q.k]})
}

/// A pose as Universal Robots' rotation vector.
pub fn rotation_vector_json(pose: &Isometry3<f64>) -> Value {
    let v = pose.rotation.scaled_axis();
    let t = pose.translation.vector;
    json!({"translation_mm": [t.x, t.y, t.z], "rotation_vector_rad": [v.x, v.y, v.z]})
}

/// A pose as KUKA's A, B, C (R = Rz(A)·Ry(B)·Rx(C)), degrees.
pub fn euler_zyx_json(pose: &Isometry3<f64>) -> Value {
    let (roll, pitch, yaw): (f64, f64, f64) = pose.rotation.euler_angles();
    let t = pose.translation.vector;
    json!({"translation_mm": [t.x, t.y, t.z],
           "euler_zyx_deg": [yaw.to_degrees(), pitch.to_degrees(), roll.to_degrees()]})
}

/// The request of a session with the flange poses in `form`.
pub fn request(
    setup: Setup,
    poses: &[Isometry3<f64>],
    form: fn(&Isometry3<f64>) -> Value,
) -> Value {
    json!({
        "setup": match setup { Setup::EyeInHand => "eye_in_hand", Setup::EyeToHand => "eye_to_hand" },
        "camera": camera_json(),
        "marker": {"size_mm": CODE_MM},
        "flange_poses": poses.iter().map(form).collect::<Vec<_>>(),
    })
}

/// The angle between a pose's rotation and the truth's, degrees, and the distance, mm.
pub fn pose_error(pose: &Value, truth: &Isometry3<f64>) -> (f64, f64) {
    let n = |k: &str, i: usize| pose[k][i].as_f64().expect("a number");
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        n("quaternion_wxyz", 0),
        n("quaternion_wxyz", 1),
        n("quaternion_wxyz", 2),
        n("quaternion_wxyz", 3),
    ));
    let t = Vector3::new(
        n("translation_mm", 0),
        n("translation_mm", 1),
        n("translation_mm", 2),
    );
    (
        q.angle_to(&truth.rotation).to_degrees(),
        (t - truth.translation.vector).norm(),
    )
}
