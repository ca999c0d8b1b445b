//! The linear initial estimate of the two leading radial coefficients (Zhang 2000, Sec. 3.3,
//! Eq. 13), given the closed-form intrinsics and poses.
//!
//! With (u, v) a point's ideal (distortion-free) pixel under the current estimate, (x, y) its
//! ideal normalised point, r² = x² + y², and (ŭ, v̆) the measured pixel, Zhang's model
//! ŭ = u + (u − u0)·(k1·r² + k2·r⁴) (and the same for v) is linear in k1, k2; stacking two
//! rows per point gives D·k = d (Eq. 13), solved by least squares, k = (DᵀD)⁻¹Dᵀd. For
//! `plumb_bob` and `rational_polynomial` these are the k1, k2 of the numerator (the other
//! coefficients start at 0). For `equidistant` the same idea on the fisheye model: with
//! θ = atan r, ŭ = cx + fx·(x / r)·θ·(1 + k1·θ² + k2·θ⁴), so the rows are
//! fx·(x / r)·(θ³, θ⁵) against ŭ − cx − fx·(x / r)·θ.
//!
//! The estimate is kept only where it helps: [`crate::fit`] compares the reprojection cost
//! with and without it, as the closed form's poses already absorb part of the distortion.

use crate::lm::{State, ViewData};
use nalgebra::{Matrix2, Vector2, Vector3};
use qrpose_core::geometry::camera::DistortionModel;

/// Below this radius (normalised) a point carries no radial information: it is skipped.
const MIN_RADIUS: f64 = 1e-8;

/// `state` with k1, k2 from Eq. 13 (or its fisheye form); `None` when the system is
/// singular or a point is behind the camera.
pub(crate) fn with_radial_estimate(state: &State, views: &[ViewData]) -> Option<State> {
    let k = &state.intrinsics;
    let fisheye = k.model == DistortionModel::Equidistant;
    let mut dtd = Matrix2::zeros();
    let mut dtr = Vector2::zeros();
    for (view, pose) in views.iter().zip(&state.poses) {
        for (m, measured) in view.target_mm.iter().zip(&view.pixel_px) {
            let p = pose.r * Vector3::new(m.x, m.y, 0.0) + pose.t_mm;
            if p.z <= 0.0 {
                return None;
            }
            let (x, y) = (p.x / p.z, p.y / p.z);
            let r = x.hypot(y);
            if r < MIN_RADIUS {
                continue;
            }
            // Each row: (coefficient of k1, coefficient of k2, right-hand side).
            let rows = if fisheye {
                let theta = r.atan();
                let (t3, t5) = (theta.powi(3), theta.powi(5));
                let (sx, sy) = (k.fx * x / r, k.fy * y / r);
                [
                    (sx * t3, sx * t5, measured.x - k.cx - sx * theta),
                    (sy * t3, sy * t5, measured.y - k.cy - sy * theta),
                ]
            } else {
                // Eq. 13: (u − u0)·r², (u − u0)·r⁴ against ŭ − u.
                let r2 = r * r;
                let (du, dv) = (k.fx * x, k.fy * y);
                [
                    (du * r2, du * r2 * r2, measured.x - (du + k.cx)),
                    (dv * r2, dv * r2 * r2, measured.y - (dv + k.cy)),
                ]
            };
            for (a, b, d) in rows {
                let row = Vector2::new(a, b);
                dtd += row * row.transpose();
                dtr += row * d;
            }
        }
    }
    let k12 = dtd.try_inverse()? * dtr;
    if !k12.iter().all(|x| x.is_finite()) {
        return None;
    }
    let mut next = state.clone();
    next.intrinsics.coefficients[0] = k12[0];
    next.intrinsics.coefficients[1] = k12[1];
    Some(next)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Intrinsics, Pose, project};
    use nalgebra::{Point2, Rotation3};

    /// Exact data of a purely radial lens give back its k1, k2.
    #[test]
    fn recovers_the_radial_coefficients_of_exact_data() {
        let mut truth =
            Intrinsics::pinhole(1000.0, 1005.0, 650.0, 350.0, DistortionModel::PlumbBob);
        truth.coefficients[0] = -0.25;
        truth.coefficients[1] = 0.08;
        let lens = truth.distortion().expect("finite");
        let poses = [
            Pose {
                r: Rotation3::from_euler_angles(0.3, -0.2, 0.1),
                t_mm: Vector3::new(-60.0, -40.0, 400.0),
            },
            Pose {
                r: Rotation3::from_euler_angles(-0.2, 0.35, 1.0),
                t_mm: Vector3::new(80.0, 30.0, 350.0),
            },
        ];
        let target_mm: Vec<Point2<f64>> = (0..100)
            .map(|i| {
                Point2::new(
                    f64::from(i % 10) * 15.0 - 70.0,
                    f64::from(i / 10) * 15.0 - 70.0,
                )
            })
            .collect();
        let views: Vec<ViewData> = poses
            .iter()
            .map(|pose| ViewData {
                pixel_px: target_mm
                    .iter()
                    .map(|m| project(&truth, &lens, pose, m).expect("in front"))
                    .collect(),
                target_mm: target_mm.clone(),
            })
            .collect();
        let start = State {
            intrinsics: Intrinsics {
                coefficients: [0.0; 8],
                ..truth
            },
            poses: poses.to_vec(),
        };
        let estimate = with_radial_estimate(&start, &views).expect("solvable");
        let k = estimate.intrinsics.coefficients;
        assert!(
            (k[0] + 0.25).abs() < 1e-9 && (k[1] - 0.08).abs() < 1e-9,
            "{k:?}"
        );
    }
}
