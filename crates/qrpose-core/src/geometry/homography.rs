//! The plane-to-plane homography of point correspondences by the normalised direct linear
//! transform: H with s·(x', y', 1)ᵀ = H·(x, y, 1)ᵀ for each pair (x, y) → (x', y').
//!
//! Hartley, "In defense of the eight-point algorithm", TPAMI 19(6), 1997; Hartley &
//! Zisserman, *Multiple View Geometry*, 2nd ed., Algorithm 4.2. Both point sets are first
//! moved to their centroid and scaled to a mean distance of √2 from it; each
//! correspondence gives the two DLT rows (H&Z Eq. 4.3), and h is the eigenvector of AᵀA
//! (9 × 9, accumulated directly, no 2N × 9 matrix) with the smallest eigenvalue, which is
//! A's right singular vector of the smallest singular value. The result is the algebraic
//! least-squares fit: exact for four points in general position or for exact
//! correspondences, the usual starting point for a geometric refinement otherwise.
//!
//! Users: the pose from many marker-plane points (`estimate::reprojection`), each
//! calibration view's homography (qrpose-calib) and the module grid of a located symbol
//! (qrpose-detect).

use nalgebra::{Matrix3, Point2, SMatrix, SVector, SymmetricEigen};
use thiserror::Error;

/// Fewest correspondences that determine a homography (8 degrees of freedom, 2 per pair).
pub const MIN_HOMOGRAPHY_POINTS: usize = 4;

/// Below this ratio of AᵀA's second-smallest to largest eigenvalue the DLT's null space is
/// more than one-dimensional (collinear or coincident points): no unique homography. Well
/// spread points give ratios above 1e-4 after normalisation.
const MIN_EIGEN_RATIO: f64 = 1e-10;

/// Why [`fit_homography_dlt`] found no homography.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum HomographyError {
    /// Fewer than [`MIN_HOMOGRAPHY_POINTS`] pairs, or two lists of different lengths.
    #[error(
        "a homography needs at least {MIN_HOMOGRAPHY_POINTS} point pairs, got {from} and {to} points"
    )]
    PointCount {
        /// Points in the source plane.
        from: usize,
        /// Points in the target plane.
        to: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("a point coordinate is not finite")]
    NotFinite,
    /// The points leave the homography undetermined: all coincident, or too many of them
    /// collinear.
    #[error("the points are degenerate (coincident or collinear): no unique homography")]
    Degenerate,
}

/// The similarity that moves `points` to their centroid and scales them to a mean distance
/// of √2 from it; `None` when they all coincide.
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

/// `p` mapped by the axis-aligned similarity `t` (a normalising transform).
fn apply(t: &Matrix3<f64>, p: &Point2<f64>) -> Point2<f64> {
    Point2::new(t[(0, 0)] * p.x + t[(0, 2)], t[(1, 1)] * p.y + t[(1, 2)])
}

/// The homography H taking each `from[i]` to `to[i]` (s·toᵢ = H·fromᵢ, homogeneous), by the
/// normalised DLT (module docs). H is scaled to unit Frobenius norm; its sign is arbitrary,
/// so a caller that wants H33 = 1 divides by H33 (see [`with_unit_h33`]).
///
/// # Errors
/// [`HomographyError::PointCount`] for fewer than four pairs or lists of different
/// lengths, [`HomographyError::NotFinite`] for a NaN or infinite coordinate and
/// [`HomographyError::Degenerate`] for points that determine no unique homography
/// (coincident, collinear) or arithmetic that overflows.
pub fn fit_homography_dlt(
    from: &[Point2<f64>],
    to: &[Point2<f64>],
) -> Result<Matrix3<f64>, HomographyError> {
    if from.len() < MIN_HOMOGRAPHY_POINTS || from.len() != to.len() {
        return Err(HomographyError::PointCount {
            from: from.len(),
            to: to.len(),
        });
    }
    if !from
        .iter()
        .chain(to)
        .all(|p| p.x.is_finite() && p.y.is_finite())
    {
        return Err(HomographyError::NotFinite);
    }
    let t_from = normalising_transform(from).ok_or(HomographyError::Degenerate)?;
    let t_to = normalising_transform(to).ok_or(HomographyError::Degenerate)?;
    // AᵀA of the DLT rows (Hartley & Zisserman Eq. 4.3), for (x, y) → (u, v):
    // [-x, -y, -1, 0, 0, 0, ux, uy, u] and [0, 0, 0, -x, -y, -1, vx, vy, v].
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (m, p) in from.iter().zip(to) {
        let m = apply(&t_from, m);
        let p = apply(&t_to, p);
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
    let mut order: [usize; 9] = std::array::from_fn(|i| i);
    order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
    let largest = eigen.eigenvalues[order[8]];
    if !largest.is_finite()
        || largest <= 0.0
        || eigen.eigenvalues[order[1]] < MIN_EIGEN_RATIO * largest
    {
        return Err(HomographyError::Degenerate);
    }
    let h = eigen.eigenvectors.column(order[0]);
    #[rustfmt::skip]
    let h_normalised = Matrix3::new(
        h[0], h[1], h[2],
        h[3], h[4], h[5],
        h[6], h[7], h[8],
    );
    let t_to_inv = t_to.try_inverse().ok_or(HomographyError::Degenerate)?;
    let h = t_to_inv * h_normalised * t_from;
    let norm = h.norm();
    if norm.is_finite() && norm > 0.0 {
        Ok(h / norm)
    } else {
        Err(HomographyError::Degenerate)
    }
}

/// `h` scaled so that H33 = 1 (which also fixes its sign); `None` when H33 is zero, so
/// tiny that the scaling is meaningless (|H33| ≤ f64::EPSILON), or not finite. H33 = 0
/// means that the source plane's origin maps to infinity.
pub fn with_unit_h33(h: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let scale = h[(2, 2)];
    (scale.is_finite() && scale.abs() > f64::EPSILON).then(|| h / scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `p` mapped through `h`; `None` on the line at infinity.
    fn transfer(h: &Matrix3<f64>, p: &Point2<f64>) -> Option<Point2<f64>> {
        let x = h * p.to_homogeneous();
        (x.z.abs() > f64::EPSILON).then(|| Point2::new(x.x / x.z, x.y / x.z))
    }

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

    #[rustfmt::skip]
    fn perspective() -> Matrix3<f64> {
        Matrix3::new(
            2.1, 0.3, 640.0,
            -0.2, 1.9, 360.0,
            4e-4, -3e-4, 1.0,
        )
    }

    #[test]
    fn recovers_a_known_homography_from_a_grid() {
        let truth = perspective();
        let from = grid();
        let to: Vec<_> = from
            .iter()
            .map(|m| transfer(&truth, m).expect("finite"))
            .collect();
        let h = fit_homography_dlt(&from, &to).expect("a homography");
        assert!((h.norm() - 1.0).abs() < 1e-12);
        let h = with_unit_h33(&h).expect("H33 is not 0");
        assert!((h - truth).norm() < 1e-9 * truth.norm(), "{h} vs {truth}");
        for (m, p) in from.iter().zip(&to) {
            let back = transfer(&h, m).expect("finite");
            assert!((back - p).norm() < 1e-9, "{back} vs {p}");
        }
    }

    #[test]
    fn four_points_in_general_position_give_the_exact_map() {
        let truth = perspective();
        let from = [
            Point2::new(0.0, 0.0),
            Point2::new(21.0, 0.0),
            Point2::new(21.0, 21.0),
            Point2::new(0.0, 21.0),
        ];
        let to = from.map(|m| transfer(&truth, &m).expect("finite"));
        let h = with_unit_h33(&fit_homography_dlt(&from, &to).expect("a homography"))
            .expect("H33 is not 0");
        assert!((h - truth).norm() < 1e-9 * truth.norm(), "{h} vs {truth}");
        let inside = Point2::new(7.5, 13.25);
        let expected = transfer(&truth, &inside).expect("finite");
        let got = transfer(&h, &inside).expect("finite");
        assert!((got - expected).norm() < 1e-9, "{got} vs {expected}");
    }

    #[test]
    fn refuses_degenerate_input() {
        let line: Vec<_> = (0..8).map(|i| Point2::new(f64::from(i), 0.0)).collect();
        let pixels: Vec<_> = (0..8)
            .map(|i| Point2::new(f64::from(i) * 3.0, 5.0))
            .collect();
        assert_eq!(
            fit_homography_dlt(&line, &pixels),
            Err(HomographyError::Degenerate)
        );
        let few = &grid()[..3];
        assert_eq!(
            fit_homography_dlt(few, few),
            Err(HomographyError::PointCount { from: 3, to: 3 })
        );
        let g = grid();
        assert_eq!(
            fit_homography_dlt(&g, &g[..24]),
            Err(HomographyError::PointCount { from: 25, to: 24 })
        );
        let same = vec![Point2::new(1.0, 1.0); 6];
        assert_eq!(
            fit_homography_dlt(&same, &same),
            Err(HomographyError::Degenerate)
        );
        let mut nan = grid();
        nan[3].y = f64::NAN;
        assert_eq!(
            fit_homography_dlt(&nan, &grid()),
            Err(HomographyError::NotFinite)
        );
    }

    #[test]
    fn unit_h33_refuses_a_vanishing_corner_element() {
        let mut h = perspective();
        assert_eq!(with_unit_h33(&(h * -2.0)), Some(h));
        h[(2, 2)] = 0.0;
        assert_eq!(with_unit_h33(&h), None);
        h[(2, 2)] = f64::NAN;
        assert_eq!(with_unit_h33(&h), None);
    }
}
