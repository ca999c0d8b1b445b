//! Rigid fit of the model square onto four camera-frame points (orthogonal Procrustes,
//! Kabsch), and the reprojection error of a pose.
//!
//! The model is planar, so the cross-covariance has rank two and Kabsch reduces to a 3×2
//! Procrustes problem with a closed form: with centred model points m_i = (a_i, b_i, 0) and
//! centred observations p_i, the first two columns of R are the polar factor of
//! C = [Σ a_i p_i, Σ b_i p_i], i.e. C (CᵀC)^(−1/2), and r3 = r1 × r2 makes det R = +1.
//! This is the same rotation as the SVD form U·diag(1, 1, det)·Vᵀ, without an SVD.

use crate::geometry::{
    camera::Camera,
    frames::{CameraPoint, MarkerToCamera, NormalizedPoint},
    marker::Marker,
};
use nalgebra::{Matrix2, Matrix3, Rotation3, Vector3};

/// Below this value of det(CᵀC) / (trace CᵀC)², the observed points do not span a plane and
/// the rotation is undetermined (the points are nearly collinear or coincide).
const RANK_TWO_REL_TOL: f64 = 1e-12;

/// The rigid pose that best maps the marker's model corners onto `observed` (P1..P4) in the
/// least-squares sense, or `None` when the observed points are (nearly) collinear.
pub fn fit_rigid(marker: &Marker, observed: &[CameraPoint; 4]) -> Option<MarkerToCamera> {
    let model = marker.object_points();
    let model_centre = marker.centre().0.coords;
    let obs_centre = observed.iter().map(|p| p.0.coords).sum::<Vector3<f64>>() / 4.0;
    let mut c1 = Vector3::zeros();
    let mut c2 = Vector3::zeros();
    for (m, p) in model.iter().zip(observed) {
        let m = m.0.coords - model_centre;
        let p = p.0.coords - obs_centre;
        c1 += m.x * p;
        c2 += m.y * p;
    }
    let ctc = Matrix2::new(c1.dot(&c1), c1.dot(&c2), c1.dot(&c2), c2.dot(&c2));
    let det = ctc.determinant();
    let tr = ctc.trace();
    if det.is_nan() || det <= RANK_TWO_REL_TOL * tr * tr {
        return None;
    }
    // (CᵀC)^(1/2) for a 2×2 SPD matrix: (A + √det·I) / √(tr A + 2√det).
    let s = det.sqrt();
    let sqrt_ctc = (ctc + Matrix2::identity() * s) / (tr + 2.0 * s).sqrt();
    let inv_sqrt = sqrt_ctc.try_inverse()?;
    let r1 = c1 * inv_sqrt[(0, 0)] + c2 * inv_sqrt[(1, 0)];
    let r2 = c1 * inv_sqrt[(0, 1)] + c2 * inv_sqrt[(1, 1)];
    let r3 = r1.cross(&r2);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[r1, r2, r3]));
    let t = obs_centre - r * model_centre;
    Some(MarkerToCamera::new(r, t))
}

/// Root-mean-square distance, in the camera's image units (px, or image-plane mm), between
/// the model corners projected under `pose` and the measured corners, over all eight
/// coordinates' worth of four points (√(Σ|Δ|² / 4)). Distances are measured in the ideal
/// (undistorted) image. `None` when a corner lies at or behind the camera.
pub fn reprojection_rms(
    camera: &Camera,
    marker: &Marker,
    pose: &MarkerToCamera,
    measured: &[NormalizedPoint; 4],
) -> Option<f64> {
    let mut sum_sq = 0.0;
    for (m, n) in marker.object_points().iter().zip(measured) {
        let projected = pose.transform(m).normalized()?;
        let du = camera.fx() * (projected.x() - n.x());
        let dv = camera.fy() * (projected.y() - n.y());
        sum_sq += du * du + dv * dv;
    }
    Some((sum_sq / 4.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::euler::{EulerXyz, angle_between};

    #[test]
    fn recovers_an_exact_rigid_transform() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let r = EulerXyz::from_degrees(20.0, -35.0, 170.0).to_rotation();
        let truth = MarkerToCamera::new(r, Vector3::new(60.0, -50.0, 300.0));
        let observed = marker.object_points().map(|m| truth.transform(&m));
        let fit = fit_rigid(&marker, &observed).expect("non-degenerate");
        assert!(angle_between(&fit.rotation(), &r) < 1e-12);
        assert!((fit.translation_mm() - truth.translation_mm()).norm() < 1e-9);
        assert!((fit.rotation().matrix().determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn matches_the_svd_form_of_kabsch_on_a_distorted_square() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let observed = [
            CameraPoint(nalgebra::Point3::new(3.0, 51.0, 404.0)),
            CameraPoint(nalgebra::Point3::new(1.0, -2.0, 397.0)),
            CameraPoint(nalgebra::Point3::new(-47.0, 1.0, 402.0)),
            CameraPoint(nalgebra::Point3::new(-52.0, 48.0, 399.0)),
        ];
        let fit = fit_rigid(&marker, &observed).expect("non-degenerate");
        let model = marker.object_points();
        let mc = marker.centre().0.coords;
        let oc = observed.iter().map(|p| p.0.coords).sum::<Vector3<f64>>() / 4.0;
        let h: Matrix3<f64> = model
            .iter()
            .zip(&observed)
            .map(|(m, p)| (p.0.coords - oc) * (m.0.coords - mc).transpose())
            .sum();
        let svd = h.svd(true, true);
        let (u, v_t) = (svd.u.expect("u"), svd.v_t.expect("v_t"));
        let d = (u * v_t).determinant().signum();
        let kabsch = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
        assert!((fit.rotation().matrix() - kabsch).norm() < 1e-12);
    }

    #[test]
    fn refuses_collinear_points() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let line =
            [0.0, 1.0, 2.0, 3.0].map(|s| CameraPoint(nalgebra::Point3::new(s, 2.0 * s, 100.0)));
        assert!(fit_rigid(&marker, &line).is_none());
    }
}
