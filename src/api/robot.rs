//! A robot's pose as its controller reports it (`docs/hand-eye.md`, Robot poses): the
//! translation in mm and exactly one rotation form, whichever the controller speaks. Every
//! request that carries a robot pose (the hand-eye calibration's `flange_poses`, a pose
//! request's `flange_pose`) takes this one shape ([`RobotPoseDto`]) and validates it here
//! into a [`Rigid`] T_robot←flange.
//!
//! The forms: `quaternion_wxyz` (ABB), `rotation_vector_rad` (axis times angle: Universal
//! Robots), `euler_zyx_deg` [a, b, c] with R = Rz(a)·Ry(b)·Rx(c) (KUKA A, B, C; Fanuc and
//! Yaskawa W, P, R sent as [R, P, W]).

use super::alternatives::{Form, Rule};
use super::problem::{ErrorCode, Problem};
use super::site::RigidDto;
use crate::app::Pick;
use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};
use qrpose_site::pick::DEFAULT_MIN_GRASP_PROBABILITY;
use qrpose_site::transform::Rigid;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// How far |q| may be from 1 before a quaternion is refused rather than normalised.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// A robot pose (T_robot←flange as the controller reports it): `translation_mm` and exactly
/// one of `quaternion_wxyz`, `rotation_vector_rad`, `euler_zyx_deg`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"translation_mm": [412.5, -120.0, 380.2], "quaternion_wxyz": [0.0, 0.6, 0.8, 0.0]}))]
pub struct RobotPoseDto {
    /// The flange's origin in the robot frame, mm.
    #[schema(min_items = 3, max_items = 3)]
    pub translation_mm: [f64; 3],
    /// The rotation as a unit quaternion (w, x, y, z) (ABB); |q| within 1e-3 of 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(min_items = 4, max_items = 4)]
    pub quaternion_wxyz: Option<[f64; 4]>,
    /// The rotation as axis times angle, rad (Universal Robots' rx, ry, rz).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(min_items = 3, max_items = 3)]
    pub rotation_vector_rad: Option<[f64; 3]>,
    /// The rotation as Z-Y-X Euler angles [a, b, c], degrees: R = Rz(a)·Ry(b)·Rx(c) (KUKA
    /// A, B, C; Fanuc and Yaskawa: send [R, P, W]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(min_items = 3, max_items = 3)]
    pub euler_zyx_deg: Option<[f64; 3]>,
}

/// A robot pose's forms in the document ([`crate::api::alternatives`]): the translation and
/// exactly one rotation form.
#[must_use]
pub fn robot_pose_forms() -> Rule {
    let form = |name, summary, fields: &'static [&'static str; 2]| Form {
        name,
        summary,
        fields: fields.to_vec(),
        required: fields,
        narrowed: vec![],
    };
    Rule::Split {
        component: "RobotPoseDto",
        forms: vec![
            form(
                "RobotPoseQuaternion",
                "quaternion (ABB)",
                &["translation_mm", "quaternion_wxyz"],
            ),
            form(
                "RobotPoseRotationVector",
                "rotation vector (Universal Robots)",
                &["translation_mm", "rotation_vector_rad"],
            ),
            form(
                "RobotPoseEulerZyx",
                "Z-Y-X Euler angles (KUKA; Fanuc, Yaskawa)",
                &["translation_mm", "euler_zyx_deg"],
            ),
        ],
        only_within: &[],
    }
}

/// The problem of a robot pose at `pointer`.
fn invalid(detail: impl Into<String>, pointer: String) -> Problem {
    Problem::new(ErrorCode::InvalidRobotPose, detail).with_field(pointer)
}

/// The first non-finite number of `values` named `name`, as a problem at `pointer/name/k`.
fn finite(values: &[f64], name: &str, pointer: &str) -> Result<(), Problem> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(k) => Err(Problem::new(
            ErrorCode::NonFiniteNumber,
            format!("{name}[{k}] is not a finite number"),
        )
        .with_field(format!("{pointer}/{name}/{k}"))),
        None => Ok(()),
    }
}

/// R = Rz(a)·Ry(b)·Rx(c), angles in degrees.
pub fn euler_zyx(deg: [f64; 3]) -> Rotation3<f64> {
    let [a, b, c] = deg.map(f64::to_radians);
    Rotation3::from_axis_angle(&Vector3::z_axis(), a)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), b)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), c)
}

impl RobotPoseDto {
    /// The pose as a rigid transform; problems are reported below `pointer`
    /// (`/flange_poses/3`, `/flange_pose`).
    ///
    /// # Errors
    /// `invalid_robot_pose` naming the pose for no rotation or two, naming the quaternion
    /// for one whose norm is off 1 by more than [`QUATERNION_NORM_TOLERANCE`];
    /// `non_finite_number` naming a NaN or infinite number.
    pub fn to_rigid(&self, pointer: &str) -> Result<Rigid, Problem> {
        finite(&self.translation_mm, "translation_mm", pointer)?;
        let rotation = match (
            self.quaternion_wxyz,
            self.rotation_vector_rad,
            self.euler_zyx_deg,
        ) {
            (Some(q), None, None) => {
                finite(&q, "quaternion_wxyz", pointer)?;
                let [w, x, y, z] = q;
                let norm = (w * w + x * x + y * y + z * z).sqrt();
                if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
                    return Err(invalid(
                        format!(
                            "quaternion_wxyz has norm {norm}, not 1 (within {QUATERNION_NORM_TOLERANCE}): is it (w, x, y, z)?"
                        ),
                        format!("{pointer}/quaternion_wxyz"),
                    ));
                }
                UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)).to_rotation_matrix()
            }
            (None, Some(v), None) => {
                finite(&v, "rotation_vector_rad", pointer)?;
                Rotation3::new(Vector3::from(v))
            }
            (None, None, Some(e)) => {
                finite(&e, "euler_zyx_deg", pointer)?;
                euler_zyx(e)
            }
            (None, None, None) => {
                return Err(invalid(
                    "a robot pose needs one rotation: quaternion_wxyz, rotation_vector_rad or euler_zyx_deg",
                    pointer.to_owned(),
                ));
            }
            _ => {
                return Err(invalid(
                    "a robot pose takes exactly one rotation form, not two",
                    pointer.to_owned(),
                ));
            }
        };
        Ok(Rigid {
            rotation,
            translation_mm: Vector3::from(self.translation_mm),
        })
    }
}

/// The picking part of a pose request: the arm's pose when the image was taken and the
/// least probability of landing within tolerance for a grasp to be `graspable`
/// (`docs/pick.md`).
///
/// # Errors
/// The flange pose's problems at `/flange_pose`; `invalid_grasp_probability` at
/// `/min_grasp_probability` outside [0, 1].
pub fn pick_of(
    flange_pose: Option<&RobotPoseDto>,
    min_grasp_probability: Option<f64>,
) -> Result<Pick, Problem> {
    let flange = flange_pose
        .map(|pose| pose.to_rigid("/flange_pose"))
        .transpose()?;
    let min = min_grasp_probability.unwrap_or(DEFAULT_MIN_GRASP_PROBABILITY);
    if !(0.0..=1.0).contains(&min) {
        return Err(Problem::new(
            ErrorCode::InvalidGraspProbability,
            format!("min_grasp_probability must be between 0 and 1, got {min}"),
        )
        .with_field("/min_grasp_probability"));
    }
    Ok(Pick {
        flange,
        min_grasp_probability: min,
    })
}

/// A rigid transform in a named parent frame: p_parent = R·p_child + t.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ParentedPoseDto {
    /// The frame it is given in: `robot` or `flange`.
    pub parent: String,
    /// t, mm.
    pub translation_mm: [f64; 3],
    /// R as a unit quaternion (w, x, y, z), w ≥ 0.
    pub quaternion_wxyz: [f64; 4],
}

impl ParentedPoseDto {
    /// `pose` given in `parent`.
    pub fn new(parent: &str, pose: &Rigid) -> Self {
        let RigidDto {
            translation_mm,
            quaternion_wxyz,
        } = RigidDto::from(pose);
        Self {
            parent: parent.to_owned(),
            translation_mm,
            quaternion_wxyz,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// One motion in every form a controller gives it.
    fn forms() -> (Rotation3<f64>, [RobotPoseDto; 3]) {
        let truth = Rotation3::from_euler_angles(0.3, -0.5, 1.2);
        let q = UnitQuaternion::from_rotation_matrix(&truth);
        let t = [412.5, -120.0, 380.25];
        let (a, b, c) = {
            // Z-Y-X: R = Rz(a)·Ry(b)·Rx(c); nalgebra's euler_angles gives (roll, pitch, yaw)
            // of R = Rz(yaw)·Ry(pitch)·Rx(roll).
            let (roll, pitch, yaw): (f64, f64, f64) = truth.euler_angles();
            (yaw.to_degrees(), pitch.to_degrees(), roll.to_degrees())
        };
        let v = truth.scaled_axis();
        (
            truth,
            [
                RobotPoseDto {
                    translation_mm: t,
                    quaternion_wxyz: Some([q.w, q.i, q.j, q.k]),
                    ..RobotPoseDto::default()
                },
                RobotPoseDto {
                    translation_mm: t,
                    rotation_vector_rad: Some([v.x, v.y, v.z]),
                    ..RobotPoseDto::default()
                },
                RobotPoseDto {
                    translation_mm: t,
                    euler_zyx_deg: Some([a, b, c]),
                    ..RobotPoseDto::default()
                },
            ],
        )
    }

    #[test]
    fn every_form_of_one_motion_is_the_same_transform() {
        let (truth, forms) = forms();
        for dto in forms {
            let rigid = dto.to_rigid("/flange_pose").expect("valid");
            assert_relative_eq!(rigid.rotation, truth, epsilon = 1e-12);
            assert_eq!(rigid.translation_mm, Vector3::new(412.5, -120.0, 380.25));
        }
    }

    #[test]
    fn kuka_angles_turn_about_z_then_the_new_y_then_the_new_x() {
        // A = 90° alone takes the flange's x to the robot's y.
        let r = euler_zyx([90.0, 0.0, 0.0]);
        assert_relative_eq!(r * Vector3::x(), Vector3::y(), epsilon = 1e-12);
        // B = 90° alone takes x to −z; C = 90° alone takes y to z.
        assert_relative_eq!(
            euler_zyx([0.0, 90.0, 0.0]) * Vector3::x(),
            -Vector3::z(),
            epsilon = 1e-12
        );
        assert_relative_eq!(
            euler_zyx([0.0, 0.0, 90.0]) * Vector3::y(),
            Vector3::z(),
            epsilon = 1e-12
        );
    }

    #[test]
    fn no_rotation_two_rotations_or_a_non_unit_quaternion_are_refused_naming_the_field() {
        let (_, [quaternion, vector, _]) = forms();
        let none = RobotPoseDto {
            translation_mm: [0.0; 3],
            ..RobotPoseDto::default()
        };
        let two = RobotPoseDto {
            rotation_vector_rad: vector.rotation_vector_rad,
            ..quaternion
        };
        let long = RobotPoseDto {
            quaternion_wxyz: Some([1.002, 0.0, 0.0, 0.0]),
            ..none
        };
        let cases = [
            (none, "/flange_poses/2"),
            (two, "/flange_poses/2"),
            (long, "/flange_poses/2/quaternion_wxyz"),
        ];
        for (dto, field) in cases {
            let problem = dto.to_rigid("/flange_poses/2").expect_err("refused");
            assert_eq!(problem.code, ErrorCode::InvalidRobotPose, "{dto:?}");
            assert_eq!(problem.field.as_deref(), Some(field), "{dto:?}");
        }
        let nearly = RobotPoseDto {
            quaternion_wxyz: Some([1.0009, 0.0, 0.0, 0.0]),
            ..none
        };
        assert!(nearly.to_rigid("/p").is_ok(), "within the tolerance");
        let nan = RobotPoseDto {
            translation_mm: [0.0, f64::NAN, 0.0],
            ..quaternion
        };
        let problem = nan.to_rigid("/p").expect_err("NaN");
        assert_eq!(problem.code, ErrorCode::NonFiniteNumber);
        assert_eq!(problem.field.as_deref(), Some("/p/translation_mm/1"));
    }
}
