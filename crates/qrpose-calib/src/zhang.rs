//! Zhang's closed-form initial estimate (Z. Zhang, "A flexible new technique for camera
//! calibration", IEEE TPAMI 22(11), 2000): the intrinsics from the views' homographies
//! (Sec. 3.1, Eqs. 3-9, Appendix B) and each view's pose from its homography and the
//! intrinsics (Sec. 3.1, Appendix C).
//!
//! Symbols are Zhang's: A = [[α, γ, u0], [0, β, v0], [0, 0, 1]] (α = fx, β = fy, γ the skew,
//! (u0, v0) the principal point), B = A⁻ᵀA⁻¹ (Eq. 5), b = [B11, B12, B22, B13, B23, B33]ᵀ
//! (Eq. 6), h_i the i-th column of H.
//!
//! The homographies are first expressed in conditioned pixels, H' = N·H with N moving the
//! image centre to the origin and scaling by 2 / (w + h), so that B's entries are of one
//! order; N·A is upper triangular like A, and A = N⁻¹·A' at the end.
//!
//! The closed form is ill-posed for fewer than three views or for views whose planes are
//! (nearly) parallel, among them the all-fronto-parallel set (Zhang, Sec. 4). It is tried in
//! three stages, each assuming more, and [`ClosedFormAssumption`] names the stage used:
//!
//! 1. three views or more: Eq. 9 as it stands, then Appendix B (γ found and dropped: qrpose's
//!    camera has no skew);
//! 2. two views or more: with γ = 0 imposed (Zhang, Sec. 3.1: "we can impose the skewless
//!    constraint γ = 0"), by dropping B12 from b;
//! 3. any number: the principal point at the image centre and γ = 0 (as OpenCV's
//!    `initIntrinsicParams2D`), so that Eq. 8 is linear in 1/α², 1/β², and finally α = β.
//!
//! A stage's answer is taken when it is plausible ([`plausible`]); otherwise the next runs.

use crate::error::SolveFailure;
use crate::input::ImageSize;
use nalgebra::{DMatrix, Matrix3, Rotation3, SymmetricEigen, Vector3};

/// Below this ratio of VᵀV's second-smallest to largest eigenvalue, Eq. 9 has more than a
/// one-dimensional null space (too few distinct plane orientations): stage 1 or 2 is skipped.
const MIN_EIGEN_RATIO: f64 = 1e-10;

/// Largest fy / fx (or fx / fy) a closed-form answer may have: sensors have square pixels to
/// within a few percent, and a ratio beyond this means the stage's system was ill-posed.
const MAX_ASPECT_RATIO: f64 = 1.5;

/// Largest focal length a closed-form answer may have, in multiples of the image's larger
/// side (a field of view under 0.06°): beyond it the views carried no perspective.
const MAX_FOCAL_PER_SIDE: f64 = 1000.0;

/// Which simplification the closed form needed (the warning `closed_form_fallback`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ClosedFormAssumption {
    /// Zero skew was imposed on Eq. 9 (stage 2).
    ZeroSkew,
    /// The principal point was put at the image centre (stage 3).
    PrincipalPointAtCentre,
    /// The principal point at the centre and fx = fy (stage 3, last resort).
    EqualFocalLengths,
}

impl ClosedFormAssumption {
    /// The assumption's stable name (`zero_skew`, `principal_point_at_centre`,
    /// `equal_focal_lengths`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::ZeroSkew => "zero_skew",
            Self::PrincipalPointAtCentre => "principal_point_at_centre",
            Self::EqualFocalLengths => "equal_focal_lengths",
        }
    }
}

/// The initial intrinsics, px, and what the closed form had to assume (`None`: Zhang's
/// general solution).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct InitialIntrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub assumption: Option<ClosedFormAssumption>,
}

/// The conditioning map N and its scale s (module doc).
struct Conditioning {
    n: Matrix3<f64>,
    s: f64,
    centre_x: f64,
    centre_y: f64,
}

impl Conditioning {
    fn new(image: ImageSize) -> Self {
        let s = 2.0 / (image.width() + image.height());
        let c = image.centre_px();
        #[rustfmt::skip]
        let n = Matrix3::new(
            s, 0.0, -s * c.x,
            0.0, s, -s * c.y,
            0.0, 0.0, 1.0,
        );
        Self {
            n,
            s,
            centre_x: c.x,
            centre_y: c.y,
        }
    }

    /// Pixel intrinsics from conditioned ones: A = N⁻¹·A'.
    fn pixels(&self, alpha: f64, beta: f64, u0: f64, v0: f64) -> (f64, f64, f64, f64) {
        (
            alpha / self.s,
            beta / self.s,
            u0 / self.s + self.centre_x,
            v0 / self.s + self.centre_y,
        )
    }
}

/// v_ij of Zhang's Eq. 7: h_iᵀ·B·h_j = v_ijᵀ·b, with h_i the i-th column of H.
fn v_ij(h: &Matrix3<f64>, i: usize, j: usize) -> [f64; 6] {
    let (hi, hj) = (h.column(i), h.column(j));
    [
        hi[0] * hj[0],
        hi[0] * hj[1] + hi[1] * hj[0],
        hi[1] * hj[1],
        hi[2] * hj[0] + hi[0] * hj[2],
        hi[2] * hj[1] + hi[1] * hj[2],
        hi[2] * hj[2],
    ]
}

/// The null vector of the stacked rows (the eigenvector of VᵀV with the smallest
/// eigenvalue), `None` when the null space is not one-dimensional.
fn null_vector(rows: &[Vec<f64>], cols: usize) -> Option<Vec<f64>> {
    let v = DMatrix::from_fn(rows.len(), cols, |r, c| rows[r][c]);
    let eigen = SymmetricEigen::new(v.transpose() * v);
    let mut order: Vec<usize> = (0..cols).collect();
    order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
    let largest = eigen.eigenvalues[order[cols - 1]];
    if !largest.is_finite()
        || largest <= 0.0
        || eigen.eigenvalues[order[1]] < MIN_EIGEN_RATIO * largest
    {
        return None;
    }
    Some(
        eigen
            .eigenvectors
            .column(order[0])
            .iter()
            .copied()
            .collect(),
    )
}

/// Zhang's Appendix B: (α, β, u0, v0) from b (γ is computed there and dropped). `None` when
/// B is not positive definite (the square roots have no real value).
fn intrinsics_from_b(b: &[f64]) -> Option<(f64, f64, f64, f64)> {
    // b is found up to sign; B = A⁻ᵀA⁻¹ is positive definite, so B11 > 0.
    let sign = if b[0] < 0.0 { -1.0 } else { 1.0 };
    let [b11, b12, b22, b13, b23, b33] = [b[0], b[1], b[2], b[3], b[4], b[5]].map(|x| sign * x);
    let det = b11 * b22 - b12 * b12;
    let v0 = (b12 * b13 - b11 * b23) / det;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha = (lambda / b11).sqrt();
    let beta = (lambda * b11 / det).sqrt();
    let gamma = -b12 * alpha * alpha * beta / lambda;
    let u0 = gamma * v0 / beta - b13 * alpha * alpha / lambda;
    [alpha, beta, u0, v0]
        .iter()
        .all(|x| x.is_finite())
        .then_some((alpha, beta, u0, v0))
}

/// Whether a closed-form answer is one a camera can have: positive focal lengths below
/// [`MAX_FOCAL_PER_SIDE`], an aspect within [`MAX_ASPECT_RATIO`], the principal point
/// inside the image.
fn plausible(k: &InitialIntrinsics, image: ImageSize) -> bool {
    let max_focal = MAX_FOCAL_PER_SIDE * image.width().max(image.height());
    let positive = k.fx > 0.0 && k.fy > 0.0 && k.fx < max_focal && k.fy < max_focal;
    let aspect = k.fy / k.fx;
    positive
        && (1.0 / MAX_ASPECT_RATIO..=MAX_ASPECT_RATIO).contains(&aspect)
        && (-0.5..=image.width() - 0.5).contains(&k.cx)
        && (-0.5..=image.height() - 0.5).contains(&k.cy)
}

/// Stage 1 (all of b, Eq. 9) or 2 (B12 = 0 imposed): Eq. 8 for each view, stacked (Eq. 9),
/// then Appendix B.
fn general(hs: &[Matrix3<f64>], skew_free: bool) -> Option<(f64, f64, f64, f64)> {
    let mut rows = Vec::with_capacity(2 * hs.len());
    for h in hs {
        let v12 = v_ij(h, 0, 1);
        let (v11, v22) = (v_ij(h, 0, 0), v_ij(h, 1, 1));
        let diff: [f64; 6] = std::array::from_fn(|k| v11[k] - v22[k]);
        // Eq. 8: [v12ᵀ; (v11 − v22)ᵀ]·b = 0.
        for row in [v12, diff] {
            rows.push(if skew_free {
                vec![row[0], row[2], row[3], row[4], row[5]]
            } else {
                row.to_vec()
            });
        }
    }
    let b = if skew_free {
        let b = null_vector(&rows, 5)?;
        vec![b[0], 0.0, b[1], b[2], b[3], b[4]]
    } else {
        null_vector(&rows, 6)?
    };
    intrinsics_from_b(&b)
}

/// Least squares of Σ (a_i·p − c_i)² over the rows, for one or two unknowns.
fn least_squares(rows: &[([f64; 2], f64)], two: bool) -> Option<(f64, f64)> {
    if two {
        let (mut m00, mut m01, mut m11, mut r0, mut r1) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for ([a0, a1], c) in rows {
            m00 += a0 * a0;
            m01 += a0 * a1;
            m11 += a1 * a1;
            r0 += a0 * c;
            r1 += a1 * c;
        }
        let det = m00 * m11 - m01 * m01;
        let p = (m11 * r0 - m01 * r1) / det;
        let q = (m00 * r1 - m01 * r0) / det;
        (p.is_finite() && q.is_finite()).then_some((p, q))
    } else {
        let (mut m, mut r) = (0.0, 0.0);
        for ([a0, a1], c) in rows {
            let a = a0 + a1;
            m += a * a;
            r += a * c;
        }
        let p = r / m;
        p.is_finite().then_some((p, p))
    }
}

/// Stage 3: A' = diag(a, b, 1) in conditioned pixels, so Eq. 8 reads, with p = 1/a²,
/// q = 1/b² and h_i = (h_i1, h_i2, h_i3):
/// h_11·h_21·p + h_12·h_22·q = −h_13·h_23 and
/// (h_11² − h_21²)·p + (h_12² − h_22²)·q = −(h_13² − h_23²).
/// Returns (a, b), or (a, a) when `equal`.
fn centred(hs: &[Matrix3<f64>], equal: bool) -> Option<(f64, f64)> {
    let mut rows = Vec::with_capacity(2 * hs.len());
    for h in hs {
        let (h1, h2) = (h.column(0), h.column(1));
        rows.push(([h1[0] * h2[0], h1[1] * h2[1]], -h1[2] * h2[2]));
        rows.push((
            [h1[0] * h1[0] - h2[0] * h2[0], h1[1] * h1[1] - h2[1] * h2[1]],
            -(h1[2] * h1[2] - h2[2] * h2[2]),
        ));
    }
    let (p, q) = least_squares(&rows, !equal)?;
    (p > 0.0 && q > 0.0).then(|| (1.0 / p.sqrt(), 1.0 / q.sqrt()))
}

/// The homographies in conditioned pixels, each scaled to unit Frobenius norm.
fn conditioned(homographies: &[Matrix3<f64>], cond: &Conditioning) -> Vec<Matrix3<f64>> {
    homographies
        .iter()
        .map(|h| {
            let hc = cond.n * h;
            hc / hc.norm()
        })
        .collect()
}

/// Stage 3 alone: the principal point at the image centre, fx and fy from Eq. 8 (then
/// fx = fy if that fails); `None` when neither is plausible.
pub(crate) fn centred_intrinsics(
    homographies: &[Matrix3<f64>],
    image: ImageSize,
) -> Option<InitialIntrinsics> {
    let cond = Conditioning::new(image);
    let hs = conditioned(homographies, &cond);
    [
        (false, ClosedFormAssumption::PrincipalPointAtCentre),
        (true, ClosedFormAssumption::EqualFocalLengths),
    ]
    .into_iter()
    .find_map(|(equal, assumption)| {
        let (a, b) = centred(&hs, equal)?;
        let (fx, fy, cx, cy) = cond.pixels(a, b, 0.0, 0.0);
        let k = InitialIntrinsics {
            fx,
            fy,
            cx,
            cy,
            assumption: Some(assumption),
        };
        plausible(&k, image).then_some(k)
    })
}

/// The initial intrinsics from the views' homographies (pixel homographies, any scale).
///
/// # Errors
/// [`SolveFailure::FocalLengthUndetermined`] when no stage gives a plausible camera.
pub(crate) fn intrinsics_from_homographies(
    homographies: &[Matrix3<f64>],
    image: ImageSize,
) -> Result<InitialIntrinsics, SolveFailure> {
    let cond = Conditioning::new(image);
    let hs = conditioned(homographies, &cond);
    let stages = [
        (3, false, None),
        (2, true, Some(ClosedFormAssumption::ZeroSkew)),
    ];
    for (min_views, skew_free, assumption) in stages {
        if hs.len() < min_views {
            continue;
        }
        if let Some((alpha, beta, u0, v0)) = general(&hs, skew_free) {
            let (fx, fy, cx, cy) = cond.pixels(alpha, beta, u0, v0);
            let k = InitialIntrinsics {
                fx,
                fy,
                cx,
                cy,
                assumption,
            };
            if plausible(&k, image) {
                return Ok(k);
            }
        }
    }
    centred_intrinsics(homographies, image).ok_or(SolveFailure::FocalLengthUndetermined)
}

/// A view's pose from its homography (Zhang, Sec. 3.1): r1 = λ·A⁻¹h1, r2 = λ·A⁻¹h2,
/// r3 = r1 × r2, t = λ·A⁻¹h3, with λ = 1/‖A⁻¹h1‖ = 1/‖A⁻¹h2‖ (here 2 over the sum of the
/// two norms, which differ with noise), its sign chosen to put the target in front of the
/// camera (t_z > 0); then the rotation nearest [r1 r2 r3] in Frobenius norm (Appendix C:
/// R = U·Vᵀ from the SVD, with det R = +1). `None` when the arithmetic is not finite.
pub(crate) fn pose_from_homography(
    h: &Matrix3<f64>,
    a: &Matrix3<f64>,
) -> Option<(Rotation3<f64>, Vector3<f64>)> {
    let a_inv = a.try_inverse()?;
    let (r1, r2, t) = (
        a_inv * h.column(0),
        a_inv * h.column(1),
        a_inv * h.column(2),
    );
    let mut lambda = 2.0 / (r1.norm() + r2.norm());
    if lambda * t.z < 0.0 {
        lambda = -lambda;
    }
    let (r1, r2, t) = (r1 * lambda, r2 * lambda, t * lambda);
    let q = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    // Appendix C: the rotation nearest Q.
    let svd = q.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    (r.iter().all(|x| x.is_finite()) && t.iter().all(|x| x.is_finite()))
        .then(|| (Rotation3::from_matrix_unchecked(r), t))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Matrix3<f64> {
        #[rustfmt::skip]
        let a = Matrix3::new(
            1000.0, 0.0, 650.0,
            0.0, 1005.0, 350.0,
            0.0, 0.0, 1.0,
        );
        a
    }

    /// H = A·[r1 r2 t] for a plane tilted by `tilt` about `axis`, at `t`.
    fn homography(axis: Vector3<f64>, tilt: f64, t: Vector3<f64>) -> Matrix3<f64> {
        let r = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), tilt);
        let m = r.matrix();
        camera() * Matrix3::from_columns(&[m.column(0).into(), m.column(1).into(), t])
    }

    fn tilted_set() -> Vec<Matrix3<f64>> {
        vec![
            homography(
                Vector3::new(1.0, 0.2, 0.0),
                0.5,
                Vector3::new(-30.0, 10.0, 500.0),
            ),
            homography(
                Vector3::new(0.1, 1.0, 0.0),
                -0.4,
                Vector3::new(20.0, -40.0, 450.0),
            ),
            homography(
                Vector3::new(1.0, -1.0, 0.3),
                0.6,
                Vector3::new(50.0, 30.0, 600.0),
            ),
            homography(
                Vector3::new(-0.5, 1.0, 0.1),
                0.3,
                Vector3::new(0.0, 0.0, 400.0),
            ),
        ]
    }

    const IMAGE: ImageSize = ImageSize::new(1280, 720);

    #[test]
    fn the_general_closed_form_recovers_exact_intrinsics() {
        let k = intrinsics_from_homographies(&tilted_set(), IMAGE).expect("solvable");
        assert_eq!(k.assumption, None);
        for (got, want) in [(k.fx, 1000.0), (k.fy, 1005.0), (k.cx, 650.0), (k.cy, 350.0)] {
            assert!((got - want).abs() < 1e-6, "{got} vs {want}");
        }
    }

    #[test]
    fn two_views_impose_zero_skew_and_still_recover_the_intrinsics() {
        let k = intrinsics_from_homographies(&tilted_set()[..2], IMAGE).expect("solvable");
        assert_eq!(k.assumption, Some(ClosedFormAssumption::ZeroSkew));
        assert!(
            (k.fx - 1000.0).abs() < 1e-6 && (k.cy - 350.0).abs() < 1e-6,
            "{k:?}"
        );
    }

    #[test]
    fn one_view_puts_the_principal_point_at_the_centre() {
        let k = intrinsics_from_homographies(&tilted_set()[2..3], IMAGE).expect("solvable");
        assert!(matches!(
            k.assumption,
            Some(
                ClosedFormAssumption::PrincipalPointAtCentre
                    | ClosedFormAssumption::EqualFocalLengths
            )
        ));
        assert_eq!((k.cx, k.cy), (639.5, 359.5));
        assert!((k.fx / 1000.0 - 1.0).abs() < 0.1, "{k:?}");
    }

    #[test]
    fn fronto_parallel_views_determine_no_focal_length() {
        let a = camera();
        let hs: Vec<_> = [0.0, 0.7, 2.0]
            .iter()
            .map(|&spin: &f64| {
                let r = Rotation3::from_axis_angle(&Vector3::z_axis(), spin);
                let m = r.matrix();
                let t = Vector3::new(10.0 * spin, -5.0, 400.0 + 50.0 * spin);
                a * Matrix3::from_columns(&[m.column(0).into(), m.column(1).into(), t])
            })
            .collect();
        assert_eq!(
            intrinsics_from_homographies(&hs, IMAGE),
            Err(SolveFailure::FocalLengthUndetermined)
        );
    }

    #[test]
    fn the_pose_from_a_homography_is_the_pose_that_made_it() {
        let axis = nalgebra::Unit::new_normalize(Vector3::new(1.0, -1.0, 0.3));
        let r = Rotation3::from_axis_angle(&axis, 0.6);
        let t = Vector3::new(50.0, 30.0, 600.0);
        // Any scale and sign: the pose comes back in front of the camera.
        let h = homography(axis.into_inner(), 0.6, t) * -0.003;
        let (r_est, t_est) = pose_from_homography(&h, &camera()).expect("a pose");
        assert!(r_est.angle_to(&r) < 1e-9 && (t_est - t).norm() < 1e-6);
    }
}
