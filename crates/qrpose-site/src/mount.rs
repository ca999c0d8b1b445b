//! A camera's mount (`docs/site.md`, Mounts): on the robot's base (`parent: robot`, the mount
//! is T_robot←camera) or on the tool flange (`parent: flange`, eye-in-hand: the mount is
//! T_flange←camera, and the camera's pose in the robot frame exists only with the flange's
//! pose when the photo was taken), with an optional standard deviation.
//!
//! **The standard deviation** is about and along the camera's own axes, as a hand-eye
//! calibration reports it: the true mount is T·exp(φ, ρ) with R → R·exp(\[φ\]×) and
//! t → t + R·ρ, φ rad and ρ mm in camera axes, independent, with the given standard
//! deviations. In [`crate::transform`]'s convention (parent axes, left perturbation) that
//! is δθ = R·φ, δt = R·ρ, so Σ = B·diag(σφ², σρ²)·Bᵀ with B = blockdiag(R, R)
//! ([`CameraMount::covariance`]). Without `std` the mount is exact (a zero covariance).

use crate::transform::{PoseWithCovariance, Rigid, fixed_then};
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// What a camera is mounted on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MountParent {
    /// The robot's base frame.
    Robot,
    /// The tool flange.
    Flange,
}

impl MountParent {
    /// The name as written: `robot`, `flange`.
    pub const fn as_str(self) -> &'static str {
        match self {
            MountParent::Robot => "robot",
            MountParent::Flange => "flange",
        }
    }
}

/// One standard deviation of a mount about and along the camera's own axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MountStd {
    /// About the camera's x, y, z, rad.
    pub rotation_rad: Vector3<f64>,
    /// Along the camera's x, y, z, mm.
    pub translation_mm: Vector3<f64>,
}

/// A camera's mount: its parent, T_parent←camera and its uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraMount {
    /// What the camera is fixed to.
    pub parent: MountParent,
    /// T_parent←camera: p_parent = R·p_camera + t.
    pub pose: Rigid,
    /// One standard deviation, when known; `None`: taken as exact.
    pub std: Option<MountStd>,
}

impl CameraMount {
    /// The 6×6 covariance of [`CameraMount::pose`] over (δθ rad, δt mm) in the parent's axes
    /// (module docs); zero without a standard deviation.
    pub fn covariance(&self) -> Matrix6<f64> {
        let Some(std) = self.std else {
            return Matrix6::zeros();
        };
        let sigma = Vector6::new(
            std.rotation_rad.x,
            std.rotation_rad.y,
            std.rotation_rad.z,
            std.translation_mm.x,
            std.translation_mm.y,
            std.translation_mm.z,
        );
        let diag = Matrix6::from_diagonal(&sigma.component_mul(&sigma));
        let r: Matrix3<f64> = *self.pose.rotation.matrix();
        let mut b = Matrix6::zeros();
        b.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        b.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
        let c = b * diag * b.transpose();
        (c + c.transpose()) * 0.5
    }

    /// T_parent←camera with [`CameraMount::covariance`].
    pub fn pose_with_covariance(&self) -> PoseWithCovariance {
        PoseWithCovariance {
            pose: self.pose,
            covariance: Some(self.covariance()),
        }
    }

    /// T_robot←camera with its covariance: the mount itself for a `robot` mount (the flange
    /// pose is not needed and ignored); T_robot←flange · T_flange←camera for a `flange`
    /// mount, `None` without `flange_in_robot` (T_robot←flange when the photo was taken,
    /// taken as exact: a controller's reading).
    pub fn camera_in_robot(&self, flange_in_robot: Option<&Rigid>) -> Option<PoseWithCovariance> {
        let mount = self.pose_with_covariance();
        match self.parent {
            MountParent::Robot => Some(mount),
            MountParent::Flange => flange_in_robot.map(|f| fixed_then(f, &mount)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn mount(parent: MountParent) -> CameraMount {
        CameraMount {
            parent,
            pose: Rigid {
                rotation: Rotation3::from_euler_angles(0.2, -0.4, 1.1),
                translation_mm: Vector3::new(10.0, -20.0, 80.0),
            },
            std: Some(MountStd {
                rotation_rad: Vector3::new(0.001, 0.002, 0.003),
                translation_mm: Vector3::new(0.5, 1.0, 2.0),
            }),
        }
    }

    #[test]
    fn the_standard_deviation_is_about_the_cameras_own_axes() {
        let m = mount(MountParent::Robot);
        let c = m.covariance();
        let r = *m.pose.rotation.matrix();
        // The rotation variance about the camera's z axis, seen from the parent frame.
        let z_parent = r * Vector3::z();
        let var_z = (z_parent.transpose() * c.fixed_view::<3, 3>(0, 0) * z_parent)[(0, 0)];
        assert!((var_z - 0.003f64.powi(2)).abs() < 1e-15, "{var_z}");
        let x_parent = r * Vector3::x();
        let var_x = (x_parent.transpose() * c.fixed_view::<3, 3>(3, 3) * x_parent)[(0, 0)];
        assert!((var_x - 0.25).abs() < 1e-12, "{var_x}");
        let exact = CameraMount { std: None, ..m };
        assert_eq!(exact.covariance(), Matrix6::zeros());
    }

    #[test]
    fn a_flange_mount_needs_the_flange_pose() {
        let m = mount(MountParent::Flange);
        assert!(m.camera_in_robot(None).is_none());
        let flange = Rigid {
            rotation: Rotation3::from_euler_angles(3.0, 0.1, -0.5),
            translation_mm: Vector3::new(400.0, 100.0, 600.0),
        };
        let in_robot = m.camera_in_robot(Some(&flange)).expect("with the flange");
        let expected = flange.then(&m.pose);
        assert!((in_robot.pose.translation_mm - expected.translation_mm).norm() < 1e-12);
        let robot = mount(MountParent::Robot);
        let in_robot = robot.camera_in_robot(Some(&flange)).expect("robot mount");
        assert_eq!(in_robot.pose, robot.pose);
    }
}
