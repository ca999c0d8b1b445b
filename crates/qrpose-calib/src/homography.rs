//! The homography of one view: the plane-to-image map H with s·(u, v, 1)ᵀ = H·(X, Y, 1)ᵀ
//! (Zhang 2000, Eq. 2: H = A·[r1 r2 t] up to scale), by the normalised direct linear
//! transform (Hartley, "In defense of the eight-point algorithm", TPAMI 19(6), 1997; Hartley
//! & Zisserman, *Multiple View Geometry*, 2nd ed., Alg. 4.2).
//!
//! Both point sets are first moved to their centroid and scaled to a mean distance of √2;
//! each correspondence gives the two DLT rows, and h is the eigenvector of AᵀA (9 × 9, built
//! directly) with the smallest eigenvalue. Zhang refines each H by maximum likelihood
//! (Appendix A); here the one Levenberg-Marquardt of [`crate::lm`] refines everything
//! instead, so the linear estimate is all the closed form needs. The homography ignores lens
//! distortion: it is the starting point, not the answer.

use nalgebra::{Matrix3, Point2, SMatrix, SVector, SymmetricEigen};

/// Below this ratio of AᵀA's second-smallest to largest eigenvalue the DLT's null space is
/// more than one-dimensional (collinear or coincident points): no unique homography. Well
/// spread points give ratios above 1e-4 after normalisation.
const MIN_EIGEN_RATIO: f64 = 1e-10;

/// The similarity that moves `points` to their centroid and scales them to a mean distance
/// of √2 from it; `None` when they all coincide or are not finite.
fn normalising_transform(points: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    let n = points.len() as f64;
    let centroid = points
        .iter()
        .fold(Point2::origin(), |c, p| c + p.coords / n);
    let mean_distance = points.iter().map(|p| (p - centroid).norm()).sum::<f64>() / n;
    let s = std::f64::consts::SQRT_2 / mean_distance;
    if !s.is_finite() || !centroid.x.is_finite() || !centroid.y.is_finite() {
        return None;
    }
    #[rustfmt::skip]
    let t = Matrix3::new(
        s, 0.0, -s * centroid.x,
        0.0, s, -s * centroid.y,
        0.0, 0.0, 1.0,
    );
    Some(t)
}

/// `p` mapped by the affine `t` (a normalising transform).
fn apply(t: &Matrix3<f64>, p: &Point2<f64>) -> Point2<f64> {
    Point2::new(t[(0, 0)] * p.x + t[(0, 2)], t[(1, 1)] * p.y + t[(1, 2)])
}

/// The homography taking each `target_mm` point (X, Y) to its `pixel_px` point (u, v), scaled
/// to unit Frobenius norm. `None` with fewer than 4 points, for a degenerate configuration
/// (three or more collinear in a way that leaves the map undetermined, coincident points),
/// or for non-finite arithmetic.
pub(crate) fn homography_from_points(
    target_mm: &[Point2<f64>],
    pixel_px: &[Point2<f64>],
) -> Option<Matrix3<f64>> {
    if target_mm.len() < 4 || target_mm.len() != pixel_px.len() {
        return None;
    }
    let t_target = normalising_transform(target_mm)?;
    let t_pixel = normalising_transform(pixel_px)?;
    // AᵀA of the DLT rows (Hartley & Zisserman Eq. 4.3):
    // [-X, -Y, -1, 0, 0, 0, uX, uY, u] and [0, 0, 0, -X, -Y, -1, vX, vY, v].
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (m, p) in target_mm.iter().zip(pixel_px) {
        let m = apply(&t_target, m);
        let p = apply(&t_pixel, p);
        let rows = [
            [-m.x, -m.y, -1.0, 0.0, 0.0, 0.0, p.x * m.x, p.x * m.y, p.x],
            [0.0, 0.0, 0.0, -m.x, -m.y, -1.0, p.y * m.x, p.y * m.y, p.y],
        ];
        for row in rows {
            let a = SVector::<f64, 9>::from(row);
            ata += a * a.transpose();
        }
    }
    let eigen = SymmetricEigen::new(ata);
    let mut order: Vec<usize> = (0..9).collect();
    order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
    let largest = eigen.eigenvalues[order[8]];
    if !largest.is_finite()
        || largest <= 0.0
        || eigen.eigenvalues[order[1]] < MIN_EIGEN_RATIO * largest
    {
        return None;
    }
    let h = eigen.eigenvectors.column(order[0]);
    #[rustfmt::skip]
    let h_normalised = Matrix3::new(
        h[0], h[1], h[2],
        h[3], h[4], h[5],
        h[6], h[7], h[8],
    );
    let t_pixel_inv = t_pixel.try_inverse()?;
    let h = t_pixel_inv * h_normalised * t_target;
    let norm = h.norm();
    (norm.is_finite() && norm > 0.0).then(|| h / norm)
}

/// `target_mm` mapped through `h`, px; `None` on the line at infinity.
#[cfg(test)]
pub(crate) fn transfer(h: &Matrix3<f64>, target_mm: &Point2<f64>) -> Option<Point2<f64>> {
    let p = h * target_mm.to_homogeneous();
    (p.z.abs() > f64::EPSILON).then(|| Point2::new(p.x / p.z, p.y / p.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Vec<Point2<f64>> {
        (0..25)
            .map(|i| {
                Point2::new(
                    f64::from(i % 5) * 30.0 - 60.0,
                    f64::from(i / 5) * 30.0 - 60.0,
                )
            })
            .collect()
    }

    #[test]
    fn recovers_an_exact_perspective_map() {
        #[rustfmt::skip]
        let truth = Matrix3::new(
            2.1, 0.3, 640.0,
            -0.2, 1.9, 360.0,
            4e-4, -3e-4, 1.0,
        );
        let target = grid();
        let pixels: Vec<_> = target
            .iter()
            .map(|m| transfer(&truth, m).expect("finite"))
            .collect();
        let h = homography_from_points(&target, &pixels).expect("a homography");
        for (m, p) in target.iter().zip(&pixels) {
            let back = transfer(&h, m).expect("finite");
            assert!((back - p).norm() < 1e-9, "{back} vs {p}");
        }
    }

    #[test]
    fn refuses_collinear_and_too_few_points() {
        let line: Vec<_> = (0..8).map(|i| Point2::new(f64::from(i), 0.0)).collect();
        let pixels: Vec<_> = (0..8)
            .map(|i| Point2::new(f64::from(i) * 3.0, 5.0))
            .collect();
        assert!(homography_from_points(&line, &pixels).is_none());
        let few = &grid()[..3];
        assert!(homography_from_points(few, few).is_none());
        let same = vec![Point2::new(1.0, 1.0); 6];
        assert!(homography_from_points(&same, &same).is_none());
    }
}
