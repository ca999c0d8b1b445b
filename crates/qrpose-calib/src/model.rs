//! The model fitted (Zhang 2000, Eq. 14, with qrpose-core's lens models in place of Zhang's
//! k1, k2): a target point (X, Y, 0), mm, is seen at
//!
//! ```text
//! p = R·(X, Y, 0)ᵀ + t                  camera frame, mm
//! (x, y) = (p_x / p_z, p_y / p_z)       ideal normalised point
//! (x_d, y_d) = D_k(x, y)                qrpose-core's Distortion::distort
//! (u, v) = (fx·x_d + cx, fy·y_d + cy)   px
//! ```
//!
//! The unknowns are the intrinsics a = (fx, fy, cx, cy, k…) ([`Intrinsics`], OpenCV's
//! coefficient order) and every view's pose ([`Pose`]). A pose step is a rotation vector ω
//! applied on the left, R ← exp([ω]×)·R, and a translation step, t ← t + δt: the rotation
//! stays a rotation and the step's Jacobian is −[R·X]× at every pose.
//!
//! Jacobians ([`project_with_jacobian`]) are analytic throughout: for the intrinsics, the
//! pose and, through [`crate::lens`], the distortion.

use crate::lens::{MAX_COEFFICIENTS, lens_jacobian};
use nalgebra::{Matrix2x3, Point2, Rotation3, SMatrix, Vector2, Vector3, Vector6};
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose_core::geometry::frames::NormalizedPoint;

/// Most intrinsic unknowns: fx, fy, cx, cy and eight coefficients.
pub(crate) const MAX_INTRINSICS: usize = 4 + MAX_COEFFICIENTS;

/// The intrinsics being fitted: focal lengths and principal point, px, and the lens
/// coefficients of `model` in OpenCV's order (entries past its count are 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub model: DistortionModel,
    pub coefficients: [f64; MAX_COEFFICIENTS],
}

impl Intrinsics {
    /// Pinhole intrinsics with every coefficient of `model` zero.
    pub fn pinhole(fx: f64, fy: f64, cx: f64, cy: f64, model: DistortionModel) -> Self {
        Self {
            fx,
            fy,
            cx,
            cy,
            model,
            coefficients: [0.0; MAX_COEFFICIENTS],
        }
    }

    /// How many unknowns: 4 plus the model's coefficient count.
    pub fn count(&self) -> usize {
        4 + self.model.coefficient_count()
    }

    /// The model's coefficients, OpenCV's order.
    pub fn model_coefficients(&self) -> &[f64] {
        &self.coefficients[..self.model.coefficient_count()]
    }

    /// qrpose-core's lens; `None` when a coefficient is not finite.
    pub fn distortion(&self) -> Option<Distortion> {
        Distortion::from_coefficients(self.model, self.model_coefficients()).ok()
    }

    /// qrpose-core's camera; `None` for a focal length that is not positive or a value
    /// that is not finite.
    pub fn camera(&self) -> Option<Camera> {
        let camera = Camera::from_pixels(self.fx, self.fy, self.cx, self.cy).ok()?;
        Some(camera.with_distortion(self.distortion()?))
    }

    /// These intrinsics moved by `step` (the first [`Intrinsics::count`] entries are used).
    pub fn stepped(&self, step: &[f64]) -> Self {
        let mut next = *self;
        next.fx += step[0];
        next.fy += step[1];
        next.cx += step[2];
        next.cy += step[3];
        for (c, d) in next.coefficients.iter_mut().zip(&step[4..self.count()]) {
            *c += d;
        }
        next
    }
}

/// A view's pose: `p_cam = r · p_target + t_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pose {
    pub r: Rotation3<f64>,
    pub t_mm: Vector3<f64>,
}

impl Pose {
    /// The pose moved by `step` = (ω, δt): R ← exp([ω]×)·R, t ← t + δt.
    pub fn stepped(&self, step: &Vector6<f64>) -> Self {
        let omega = Vector3::new(step[0], step[1], step[2]);
        Self {
            r: Rotation3::new(omega) * self.r,
            t_mm: self.t_mm + Vector3::new(step[3], step[4], step[5]),
        }
    }
}

/// A projection and its derivatives.
pub(crate) struct Projected {
    /// The pixel, px.
    pub uv: Vector2<f64>,
    /// ∂(u, v)/∂(fx, fy, cx, cy, k…); columns past [`Intrinsics::count`] are 0.
    pub d_intrinsics: SMatrix<f64, 2, MAX_INTRINSICS>,
    /// ∂(u, v)/∂(ω, δt).
    pub d_pose: SMatrix<f64, 2, 6>,
}

/// The ideal normalised point of `target` and its camera-frame position; `None` at or
/// behind the camera.
fn normalised(pose: &Pose, target: &Point2<f64>) -> Option<(Vector3<f64>, f64, f64)> {
    let p = pose.r * Vector3::new(target.x, target.y, 0.0) + pose.t_mm;
    (p.z > 0.0).then(|| (p, p.x / p.z, p.y / p.z))
}

/// Where `target` is seen, px; `None` at or behind the camera.
pub(crate) fn project(
    k: &Intrinsics,
    lens: &Distortion,
    pose: &Pose,
    target: &Point2<f64>,
) -> Option<Vector2<f64>> {
    let (_, x, y) = normalised(pose, target)?;
    let d = lens.distort(&NormalizedPoint::new(x, y));
    Some(Vector2::new(k.fx * d.x() + k.cx, k.fy * d.y() + k.cy))
}

/// Where `target` is seen, px, with the derivatives of the module doc; `None` at or behind
/// the camera.
pub(crate) fn project_with_jacobian(
    k: &Intrinsics,
    lens: &Distortion,
    pose: &Pose,
    target: &Point2<f64>,
) -> Option<Projected> {
    let (p, x, y) = normalised(pose, target)?;
    let d = lens.distort(&NormalizedPoint::new(x, y));
    let (xd, yd) = (d.x(), d.y());
    let lens_j = lens_jacobian(lens, x, y);
    let mut d_intrinsics = SMatrix::<f64, 2, MAX_INTRINSICS>::zeros();
    d_intrinsics[(0, 0)] = xd;
    d_intrinsics[(1, 1)] = yd;
    d_intrinsics[(0, 2)] = 1.0;
    d_intrinsics[(1, 3)] = 1.0;
    for c in 0..k.model.coefficient_count() {
        d_intrinsics[(0, 4 + c)] = k.fx * lens_j.d_coefficients[(0, c)];
        d_intrinsics[(1, 4 + c)] = k.fy * lens_j.d_coefficients[(1, c)];
    }
    // ∂(x, y)/∂p for the perspective division.
    let inv_z = 1.0 / p.z;
    #[rustfmt::skip]
    let d_division = Matrix2x3::new(
        inv_z, 0.0, -x * inv_z,
        0.0, inv_z, -y * inv_z,
    );
    // ∂(u, v)/∂p = diag(fx, fy) · ∂(x_d, y_d)/∂(x, y) · ∂(x, y)/∂p.
    let focal = nalgebra::Matrix2::new(k.fx, 0.0, 0.0, k.fy);
    let d_p = focal * lens_j.d_point * d_division;
    // ∂p/∂ω = −[R·X]×, ∂p/∂δt = I.
    let rx = p - pose.t_mm;
    let d_rotation = d_p * (-rx.cross_matrix());
    let mut d_pose = SMatrix::<f64, 2, 6>::zeros();
    d_pose.fixed_columns_mut::<3>(0).copy_from(&d_rotation);
    d_pose.fixed_columns_mut::<3>(3).copy_from(&d_p);
    Some(Projected {
        uv: Vector2::new(k.fx * xd + k.cx, k.fy * yd + k.cy),
        d_intrinsics,
        d_pose,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whole Jacobian against central differences of [`project`], for each model.
    #[test]
    fn the_projection_jacobian_matches_central_differences() {
        let pose = Pose {
            r: Rotation3::from_euler_angles(0.4, -0.3, 1.2),
            t_mm: Vector3::new(40.0, -25.0, 450.0),
        };
        let target = Point2::new(35.0, -20.0);
        let cases: [(DistortionModel, &[f64]); 3] = [
            (
                DistortionModel::PlumbBob,
                &[-0.25, 0.08, 1e-3, -5e-4, -0.01],
            ),
            (
                DistortionModel::RationalPolynomial,
                &[0.3, -0.05, 4e-4, -3e-4, 0.001, 0.6, 0.01, -0.003],
            ),
            (DistortionModel::Equidistant, &[-0.01, 0.04, -0.04, 0.007]),
        ];
        for (model, coefficients) in cases {
            let mut k = Intrinsics::pinhole(1000.0, 1005.0, 650.0, 350.0, model);
            k.coefficients[..coefficients.len()].copy_from_slice(coefficients);
            let lens = k.distortion().expect("finite");
            let at = |k: &Intrinsics, pose: &Pose| {
                project(k, &k.distortion().expect("finite"), pose, &target).expect("in front")
            };
            let j = project_with_jacobian(&k, &lens, &pose, &target).expect("in front");
            assert!((j.uv - at(&k, &pose)).norm() < 1e-12);
            for i in 0..k.count() {
                let h = if i < 4 { 1e-4 } else { 1e-7 };
                let mut step = [0.0; MAX_INTRINSICS];
                step[i] = h;
                let plus = at(&k.stepped(&step), &pose);
                step[i] = -h;
                let minus = at(&k.stepped(&step), &pose);
                let numeric = (plus - minus) / (2.0 * h);
                let analytic = j.d_intrinsics.column(i);
                assert!(
                    (numeric - analytic).norm() < 1e-4 * (1.0 + analytic.norm()),
                    "{model} intrinsic {i}: {analytic} vs {numeric}"
                );
            }
            for i in 0..6 {
                let h = if i < 3 { 1e-7 } else { 1e-5 };
                let mut step = Vector6::zeros();
                step[i] = h;
                let plus = at(&k, &pose.stepped(&step));
                step[i] = -h;
                let minus = at(&k, &pose.stepped(&step));
                let numeric = (plus - minus) / (2.0 * h);
                let analytic = j.d_pose.column(i);
                assert!(
                    (numeric - analytic).norm() < 1e-5 * (1.0 + analytic.norm()),
                    "{model} pose {i}: {analytic} vs {numeric}"
                );
            }
        }
    }

    #[test]
    fn points_behind_the_camera_do_not_project() {
        let k = Intrinsics::pinhole(1000.0, 1000.0, 640.0, 360.0, DistortionModel::PlumbBob);
        let pose = Pose {
            r: Rotation3::identity(),
            t_mm: Vector3::new(0.0, 0.0, -10.0),
        };
        let lens = k.distortion().expect("finite");
        assert!(project(&k, &lens, &pose, &Point2::new(1.0, 2.0)).is_none());
        assert!(project_with_jacobian(&k, &lens, &pose, &Point2::new(1.0, 2.0)).is_none());
    }
}
