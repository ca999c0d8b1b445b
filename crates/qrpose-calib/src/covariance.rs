//! The covariance of the intrinsics: a cluster-robust sandwich over patches of the target,
//! with the CR2 small-sample adjustment of the residuals.
//!
//! The textbook covariance s²·(JᵀWJ)⁻¹ (s² the residual variance) assumes that every point's
//! error is independent. A QR code's points are not: each module corner is the crossing of
//! two line fits over four modules, so neighbouring corners share the errors of the same
//! edge profiles, and a finder pattern's twelve corners share those of its squares. On the
//! rendered photos of `scripts/calibration_compare.py` the residuals of two points of a view
//! less than 6 px apart correlate at 0.33 on average (up to 0.46 in a set), those 6-15 px
//! apart at 0.06 (the fit itself absorbs part of what they share), and s²·(JᵀWJ)⁻¹
//! understated the errors of cx, k1, k2 and k3 by 1.6× (docs/measurements/calibration.md).
//! Errors that move together over
//! a patch move the intrinsics as one larger error, which the sandwich
//!
//! ```text
//! Cov(a) = S⁻¹ · (Σ_g c_g·c_gᵀ) · S⁻¹,    c_g = J̃_gᵀ·W_g^½·(I − H_gg)^−½·W_g^½·e_g
//! ```
//!
//! counts, whatever the correlation within a cluster g (Liang and Zeger 1986; Cameron and
//! Miller, "A practitioner's guide to cluster-robust inference", J. Human Resources 50(2),
//! 2015, Eq. 11). Here:
//!
//! - a cluster is one view's points within one cell of a [`BLOCKS_PER_SIDE`]² grid over
//!   the target's extent in the marker plane (a patch of about 8 × 8 modules of a code:
//!   twice the reach of a corner's line fits, and small enough that a set of 15 views has
//!   some 240 clusters, so the sum over them is stable);
//! - J̃ = J_a − J_b·V_i⁻¹·W_iᵀ is a point's Jacobian in the intrinsics with view i's pose
//!   eliminated (the Schur complement of [`crate::lm`], S = Σ J̃ᵀWJ̃), and W the final IRLS
//!   weights of Huber's loss, held fixed (the weighted least-squares problem the last
//!   iteration solved);
//! - H_gg = W_g^½·J_g·(JᵀWJ)⁻¹·J_gᵀ·W_g^½ is the cluster's block of the hat matrix. The
//!   fitted residuals are shrunk towards zero by the fit (E[ê·êᵀ] = (I − H)·Σ·(I − H)):
//!   each view's six pose parameters are fitted to the same few clusters, so each cluster's
//!   leverage is large (about 6 / 16 in the pose directions) and the unadjusted sandwich
//!   (CR0) would understate the variance. (I − H_gg)^−½ is Bell and McCaffrey's CR2
//!   adjustment (Bell and McCaffrey, Survey Methodology 28(2), 2002; Pustejovsky and
//!   Tipton, J. Bus. Econ. Stat. 36(4), 2018, Eq. 6), which makes the sandwich exactly
//!   unbiased when the errors are in fact independent and of equal variance, and nearly so
//!   otherwise. No factor is fitted to data.
//!
//! H_gg has rank r = 6 + n_a at most: in the basis [J_b | J̃], in which JᵀWJ is block
//! diagonal (J_b,iᵀ·W·J̃_i = 0), H_gg = Z·Zᵀ with Z = B_g·L, B_g = W_g^½·[J_b,g | J̃_g] and
//! L·Lᵀ = diag(V_i⁻¹, S⁻¹). With the eigen-decomposition Zᵀ·Z = Q·diag(σ²)·Qᵀ,
//! (I − H_gg)^−½ = I + Σ_k u_k·u_kᵀ·((1 − σ_k²)^−½ − 1) with u_k = Z·q_k / σ_k, so
//!
//! ```text
//! c_g = E_aᵀ·b_g + E_aᵀ·G_g·L·Q·diag(φ(σ_k²))·Qᵀ·Lᵀ·b_g,   φ(s) = ((1 − s)^−½ − 1) / s
//! ```
//!
//! with G_g = B_gᵀ·B_g and b_g = B_gᵀ·W_g^½·e_g accumulated point by point, and E_a the
//! intrinsics' columns of B: an r × r eigenproblem per cluster instead of one the size of
//! the cluster's points.

use crate::lm::{self, State, ViewData};
use crate::model::{MAX_INTRINSICS, project_with_jacobian};
use crate::robust::Huber;
use nalgebra::{Cholesky, DMatrix, DVector, SMatrix};

/// The clusters of the module doc: a view's target is cut into this many cells a side.
pub const BLOCKS_PER_SIDE: usize = 4;

/// The leverage σ² at which a cluster is taken to determine a direction by itself
/// ((1 − σ²)^−½ would be unbounded): capped there, the cluster's residual in that direction
/// is scaled up 1000×.
const MAX_LEVERAGE: f64 = 1.0 - 1e-6;

/// φ(s) = ((1 − s)^−½ − 1) / s, continuous at s = 0 (φ → 1/2 + 3s/8).
fn phi(s: f64) -> f64 {
    if s < 1e-8 {
        0.5 + 0.375 * s
    } else {
        let s = s.min(MAX_LEVERAGE);
        ((1.0 - s).powf(-0.5) - 1.0) / s
    }
}

/// A point's cluster within its view: the cell of the [`BLOCKS_PER_SIDE`]² grid over the
/// view's target extent.
fn cells(view: &ViewData, blocks_per_side: usize) -> Vec<usize> {
    let Some(first) = view.target_mm.first() else {
        return Vec::new();
    };
    let (lo, hi) = view
        .target_mm
        .iter()
        .fold((*first, *first), |(lo, hi), m| (lo.inf(m), hi.sup(m)));
    let cell = |x: f64, lo: f64, hi: f64| {
        let f = if hi > lo { (x - lo) / (hi - lo) } else { 0.0 };
        // f in [0, 1]: the product is in [0, blocks_per_side].
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let i = (f * blocks_per_side as f64) as usize;
        i.min(blocks_per_side - 1)
    };
    view.target_mm
        .iter()
        .map(|m| cell(m.y, lo.y, hi.y) * blocks_per_side + cell(m.x, lo.x, hi.x))
        .collect()
}

/// A cluster's sums: G_g = B_gᵀ·B_g and b_g = B_gᵀ·W^½·e (module doc).
struct Cluster {
    g: DMatrix<f64>,
    b: DVector<f64>,
}

/// The intrinsics' covariance of the module doc at `state` (n_a × n_a, in the order of
/// [`crate::model::Intrinsics::stepped`]), each view's points clustered by the cells of a
/// `blocks_per_side`² grid over its target; `None` when the normal equations are singular.
pub(crate) fn intrinsic_covariance(
    state: &State,
    views: &[ViewData],
    loss: Huber,
    blocks_per_side: usize,
) -> Option<DMatrix<f64>> {
    let k = &state.intrinsics;
    let lens = k.distortion()?;
    let n = lm::normal_equations(state, views, loss)?;
    let n_a = n.n_a;
    let r = 6 + n_a;
    let reduced = lm::reduced(&n, 0.0)?;
    let s_inv = Cholesky::new(reduced.s)?.inverse();
    let l_s = Cholesky::new(s_inv.clone())?.l();
    let mut meat = DMatrix::<f64>::zeros(n_a, n_a);
    let cells_per_view = blocks_per_side * blocks_per_side;
    for (((view, pose), factor), w_i) in views
        .iter()
        .zip(&state.poses)
        .zip(&reduced.factors)
        .zip(&n.w)
    {
        // P_i = V_i⁻¹·W_iᵀ, and L's pose block: L_v·L_vᵀ = V_i⁻¹.
        let p_i: SMatrix<f64, 6, MAX_INTRINSICS> = factor.solve(&w_i.transpose());
        let l_v = Cholesky::new(factor.inverse())?.l();
        let mut l = DMatrix::<f64>::zeros(r, r);
        l.view_mut((0, 0), (6, 6)).copy_from(&l_v);
        l.view_mut((6, 6), (n_a, n_a)).copy_from(&l_s);
        let mut clusters: Vec<Cluster> = (0..cells_per_view)
            .map(|_| Cluster {
                g: DMatrix::zeros(r, r),
                b: DVector::zeros(r),
            })
            .collect();
        let cell_of = cells(view, blocks_per_side);
        for ((m, uv), &cell) in view.target_mm.iter().zip(&view.pixel_px).zip(&cell_of) {
            let p = project_with_jacobian(k, &lens, pose, m)?;
            let e = p.uv - uv;
            let root_w = loss.weight(e.norm()).sqrt();
            let j_tilde = p.d_intrinsics - p.d_pose * p_i;
            let b_p = DMatrix::from_fn(2, r, |row, col| {
                root_w
                    * if col < 6 {
                        p.d_pose[(row, col)]
                    } else {
                        j_tilde[(row, col - 6)]
                    }
            });
            let e_w = DVector::from_fn(2, |row, _| root_w * e[row]);
            let c = &mut clusters[cell];
            c.g += b_p.transpose() * &b_p;
            c.b += b_p.transpose() * e_w;
        }
        for c in clusters {
            // Zᵀ·Z = Lᵀ·G_g·L = Q·diag(σ²)·Qᵀ; c_g of the module doc.
            let eigen = (l.transpose() * &c.g * &l).symmetric_eigen();
            let phis = eigen.eigenvalues.map(|s| phi(s.max(0.0)));
            let q = &eigen.eigenvectors;
            let inner = q * DMatrix::from_diagonal(&phis) * q.transpose();
            let score = c.b.rows(6, n_a) + c.g.rows(6, n_a) * &l * inner * l.transpose() * &c.b;
            meat += &score * score.transpose();
        }
    }
    let covariance = &s_inv * meat * &s_inv;
    covariance
        .iter()
        .all(|x| x.is_finite())
        .then_some(covariance)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point2, Vector2};

    #[test]
    fn phi_is_the_leverage_adjustment_and_continuous_at_zero() {
        // (1 − 0.75)^−½ = 2: φ = (2 − 1) / 0.75.
        assert!((phi(0.75) - 1.0 / 0.75).abs() < 1e-12);
        assert_eq!(phi(0.0), 0.5);
        let (below, above) = (phi(0.999_999e-8), phi(1.000_001e-8));
        assert!((below - above).abs() < 1e-7, "{below} {above}");
        assert!(phi(1.0).is_finite() && phi(1.0) > 900.0);
    }

    #[test]
    fn a_views_points_fall_in_the_cells_of_a_grid_over_its_target() {
        let target_mm: Vec<Point2<f64>> = [(0.0, 0.0), (29.9, 0.0), (30.1, 0.0), (120.0, 120.0)]
            .iter()
            .map(|&(x, y)| Point2::new(x - 60.0, y - 60.0))
            .collect();
        let view = ViewData {
            pixel_px: vec![Vector2::zeros(); target_mm.len()],
            target_mm,
        };
        assert_eq!(cells(&view, 4), vec![0, 0, 1, 15]);
        assert_eq!(cells(&view, 1), vec![0; 4]);
    }
}
