//! The start of the joint fit: each view's pose of the code from its points (homography
//! on undistorted points, Zhang's decomposition, then a Levenberg-Marquardt on the pose
//! through the lens), the mount from the relative motions in closed form (F. C. Park and
//! B. J. Martin, "Robot sensor calibration: solving AX = XB on the Euclidean group", IEEE
//! Trans. Robotics and Automation 10(5), 1994: rotation from the log-map axes, Eq. 8-10, by
//! an orthogonal Procrustes fit; translation by linear least squares, Eq. 12), then the
//! target from the mount.
//!
//! Notation: C_i = T_camera←marker of view i (the paper's marker frame, origin P2), and
//! G_i = F_i (eye-in-hand) or F_i⁻¹ (eye-to-hand), F_i = T_robot←flange. Both setups then
//! read Y = G_i·X·C_i for every i (X the mount, Y the target), so for two views i, j
//! A·X = X·B with A = G_j⁻¹·G_i and B = C_j·C_i⁻¹.

use super::rigid::{compose, inverse, log_rotation};
use crate::lm::ViewData;
use crate::model::{Intrinsics, Pose, project_with_jacobian};
use crate::zhang::pose_from_homography;
use nalgebra::{Matrix3, Matrix6, Point2, Rotation3, Vector3, Vector6};
use qrpose_core::geometry::camera::Distortion;
use qrpose_core::geometry::homography::fit_homography_dlt;

/// Iterations of a view's own pose refinement (it converges in 3-5 from the homography).
const VIEW_POSE_ITERATIONS: usize = 30;
/// A view's pose refinement stops when a step moves a point by less than this, px.
const VIEW_POSE_STEP_TOL_PX: f64 = 1e-9;

/// A view's pose of the code from its points, `None` when the homography or the
/// undistortion fails, or the code is behind the camera.
pub(crate) fn view_pose(k: &Intrinsics, lens: &Distortion, view: &ViewData) -> Option<Pose> {
    let camera = k.camera()?;
    let normalised: Vec<Point2<f64>> = view
        .pixel_px
        .iter()
        .map(|uv| {
            camera
                .normalize(&qrpose_core::geometry::frames::PixelPoint::new(uv.x, uv.y))
                .ok()
                .map(|n| n.0)
        })
        .collect::<Option<_>>()?;
    let h = fit_homography_dlt(&view.target_mm, &normalised).ok()?;
    let (r, t_mm) = pose_from_homography(&h, &Matrix3::identity())?;
    refine_view_pose(k, lens, Pose { r, t_mm }, view)
}

/// Gauss-Newton with Levenberg's damping on one view's pose, the lens and intrinsics fixed.
fn refine_view_pose(
    k: &Intrinsics,
    lens: &Distortion,
    start: Pose,
    view: &ViewData,
) -> Option<Pose> {
    let cost = |pose: &Pose| -> Option<f64> {
        let mut total = 0.0;
        for (m, uv) in view.target_mm.iter().zip(&view.pixel_px) {
            let p = crate::model::project(k, lens, pose, m)?;
            total += (p - uv).norm_squared();
        }
        Some(total)
    };
    let mut pose = start;
    let mut current = cost(&pose)?;
    let mut lambda = 1e-3;
    for _ in 0..VIEW_POSE_ITERATIONS {
        let mut jtj = Matrix6::zeros();
        let mut jte = Vector6::zeros();
        for (m, uv) in view.target_mm.iter().zip(&view.pixel_px) {
            let p = project_with_jacobian(k, lens, &pose, m)?;
            let e = p.uv - uv;
            jtj += p.d_pose.transpose() * p.d_pose;
            jte += p.d_pose.transpose() * e;
        }
        let mut accepted = false;
        while lambda < 1e10 {
            let mut damped = jtj;
            for i in 0..6 {
                damped[(i, i)] *= 1.0 + lambda;
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-jte))) else {
                lambda *= 10.0;
                continue;
            };
            let trial = pose.stepped(&step);
            if let Some(c) = cost(&trial).filter(|&c| c < current) {
                let gain = current - c;
                pose = trial;
                current = c;
                lambda = (lambda / 10.0).max(1e-9);
                accepted = gain > VIEW_POSE_STEP_TOL_PX * VIEW_POSE_STEP_TOL_PX;
                break;
            }
            lambda *= 10.0;
        }
        if !accepted {
            break;
        }
    }
    Some(pose)
}

/// The rotation nearest `m` in the Frobenius norm (SVD), `None` when `m` is not finite.
pub(crate) fn nearest_rotation(m: &Matrix3<f64>) -> Option<Rotation3<f64>> {
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    r.iter()
        .all(|x| x.is_finite())
        .then(|| Rotation3::from_matrix_unchecked(r))
}

/// The relative motions A_ij, B_ij (module doc) of every pair i < j.
fn motions(g: &[Pose], c: &[Pose]) -> Vec<(Pose, Pose)> {
    let mut out = Vec::new();
    for i in 0..g.len() {
        for j in i + 1..g.len() {
            let a = compose(&inverse(&g[j]), &g[i]);
            let b = compose(&c[j], &inverse(&c[i]));
            out.push((a, b));
        }
    }
    out
}

/// The mount X of A·X = X·B over every pair of views (Park and Martin): R_X from the
/// rotation vectors α = log R_A, β = log R_B (α = R_X·β) by Procrustes, t_X from
/// (R_A − I)·t_X = R_X·t_B − t_A by least squares. `None` when the system is singular.
pub(crate) fn mount_from_motions(g: &[Pose], c: &[Pose]) -> Option<Pose> {
    let pairs = motions(g, c);
    // H = Σ β·αᵀ; R = V·diag(1, 1, d)·Uᵀ of H = U·S·Vᵀ minimises Σ ‖α − R·β‖².
    let mut h = Matrix3::zeros();
    for (a, b) in &pairs {
        h += log_rotation(&b.r) * log_rotation(&a.r).transpose();
    }
    let r_x = nearest_rotation(&h.transpose())?;
    let mut lhs = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    for (a, b) in &pairs {
        let m = a.r.matrix() - Matrix3::identity();
        lhs += m.transpose() * m;
        rhs += m.transpose() * (r_x * b.t_mm - a.t_mm);
    }
    let t_mm = lhs.cholesky()?.solve(&rhs);
    t_mm.iter()
        .all(|x| x.is_finite())
        .then_some(Pose { r: r_x, t_mm })
}

/// The target Y = G_i·X·C_i averaged over the views (rotation: the nearest rotation to the
/// sum; translation: the mean). `None` without views.
pub(crate) fn target_from_mount(g: &[Pose], x: &Pose, c: &[Pose]) -> Option<Pose> {
    if g.is_empty() {
        return None;
    }
    let mut r_sum = Matrix3::zeros();
    let mut t_sum = Vector3::zeros();
    for (g_i, c_i) in g.iter().zip(c) {
        let y = compose(&compose(g_i, x), c_i);
        r_sum += y.r.matrix();
        t_sum += y.t_mm;
    }
    #[allow(clippy::cast_precision_loss)]
    let n = g.len() as f64;
    Some(Pose {
        r: nearest_rotation(&r_sum)?,
        t_mm: t_sum / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::handeye::rigid::difference;

    use crate::handeye::rigid::tests::pose;

    #[test]
    fn park_martin_recovers_an_exact_mount_and_target() {
        let x = pose(0.1, -0.2, 1.4, [30.0, -12.0, 80.0]);
        let y = pose(3.0, 0.1, -0.5, [600.0, 150.0, -20.0]);
        let g: Vec<Pose> = [
            (0.1, 0.2, 0.3, [500.0, 100.0, 400.0]),
            (-0.3, 0.1, 0.0, [450.0, 120.0, 380.0]),
            (0.2, -0.4, 0.5, [520.0, 60.0, 420.0]),
            (0.0, 0.3, -0.6, [480.0, 90.0, 390.0]),
        ]
        .iter()
        .map(|&(a, b, c, t)| pose(a, b, c, t))
        .collect();
        // C_i = X⁻¹·G_i⁻¹·Y.
        let c: Vec<Pose> = g
            .iter()
            .map(|g_i| compose(&compose(&inverse(&x), &inverse(g_i)), &y))
            .collect();
        let found = mount_from_motions(&g, &c).expect("solvable");
        assert!(difference(&found, &x).norm() < 1e-9, "{found:?}");
        let target = target_from_mount(&g, &found, &c).expect("views");
        assert!(difference(&target, &y).norm() < 1e-9, "{target:?}");
    }
}
