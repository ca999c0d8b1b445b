//! The module grid of one symbol as the photo shows it, bent by whatever lens took it: the
//! refined module-to-image homography H composed with a smooth warp of module coordinates,
//!
//! ```text
//! x_px ~ H · (u + P_u(u, v), v + P_v(u, v), 1)ᵀ
//! ```
//!
//! P_u and P_v are cubic polynomials in the normalised module coordinates
//! (x, y) = (2u/N − 1, 2v/N − 1) (ten terms each). A lens bends the symbol's straight
//! module lines smoothly; over one symbol a cubic follows that bend to a small fraction of a
//! module, so that every edge profile is taken across its edge at the right place although
//! the camera's distortion is unknown (it is what the calibration is after). An edge
//! observed on the grid line u = c at v = t, δ modules off the warped grid, says that
//! P_u(c, t) is the current warp's u at (c + δ, t) minus c ([`Warp::fit`]; V lines
//! likewise for P_v). Module coordinates: [`crate::refine::ModulePoint`].

use crate::refine::homography::{Homography, ModulePoint};
use nalgebra::{SMatrix, SVector};
use qrpose_core::geometry::frames::PixelPoint;

/// Terms of one warp polynomial: 1, x, y, x², xy, y², x³, x²y, xy², y³.
const TERMS: usize = 10;

/// Huber threshold of the warp fit, modules: an edge further off than this (a misread
/// module, a profile locked to the wrong edge) pulls with a bounded weight.
const HUBER_MODULES: f64 = 0.05;

/// Reweighting rounds of the warp fit.
const ROUNDS: usize = 4;

/// Fewest edges along each axis for a cubic warp: three times its unknowns.
const MIN_EDGES: usize = 3 * TERMS;

/// Step of the finite differences of [`WarpedGrid::px_per_module`], modules.
const SCALE_STEP_MODULES: f64 = 1e-3;

/// One edge measured under a warp: on the grid line `axis = c`, at `t` along it, the edge
/// lies at `c + delta` (modules, in the warped grid's coordinates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct EdgeOffset {
    /// Whether the line is u = c (`true`) or v = c.
    pub(super) along_u: bool,
    /// The line's coordinate, modules.
    pub(super) c: f64,
    /// Where along the line, modules.
    pub(super) t: f64,
    /// The edge's offset from the line, modules.
    pub(super) delta: f64,
}

/// The two warp polynomials of an N-module symbol.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Warp {
    n: f64,
    pu: [f64; TERMS],
    pv: [f64; TERMS],
}

impl Warp {
    /// No warp: module coordinates go to H as they are.
    pub(super) fn identity(n: f64) -> Self {
        Self {
            n,
            pu: [0.0; TERMS],
            pv: [0.0; TERMS],
        }
    }

    /// The polynomial terms at module point (u, v).
    fn basis(&self, u: f64, v: f64) -> [f64; TERMS] {
        let (x, y) = (2.0 * u / self.n - 1.0, 2.0 * v / self.n - 1.0);
        [
            1.0,
            x,
            y,
            x * x,
            x * y,
            y * y,
            x * x * x,
            x * x * y,
            x * y * y,
            y * y * y,
        ]
    }

    /// The warped module point (u + P_u, v + P_v).
    pub(super) fn apply(&self, m: ModulePoint) -> ModulePoint {
        let b = self.basis(m.u, m.v);
        let dot = |p: &[f64; TERMS]| p.iter().zip(&b).map(|(c, t)| c * t).sum::<f64>();
        ModulePoint::new(m.u + dot(&self.pu), m.v + dot(&self.pv))
    }

    /// The warp that puts each measured edge on its line, by iteratively reweighted least
    /// squares (Huber, [`HUBER_MODULES`]); `None` with fewer than [`MIN_EDGES`] edges along
    /// either axis, or a singular system (edges along too few lines).
    pub(super) fn fit(&self, edges: &[EdgeOffset]) -> Option<Self> {
        let mut u_rows = Vec::new();
        let mut v_rows = Vec::new();
        for e in edges {
            if e.along_u {
                let seen = self.apply(ModulePoint::new(e.c + e.delta, e.t));
                u_rows.push((self.basis(e.c, e.t), seen.u - e.c));
            } else {
                let seen = self.apply(ModulePoint::new(e.t, e.c + e.delta));
                v_rows.push((self.basis(e.t, e.c), seen.v - e.c));
            }
        }
        Some(Self {
            n: self.n,
            pu: fit_polynomial(&u_rows)?,
            pv: fit_polynomial(&v_rows)?,
        })
    }
}

/// The coefficients p minimising Σ ρ(bᵀp − y) over `rows` of (b, y), ρ Huber's loss.
fn fit_polynomial(rows: &[([f64; TERMS], f64)]) -> Option<[f64; TERMS]> {
    if rows.len() < MIN_EDGES {
        return None;
    }
    let mut weights = vec![1.0; rows.len()];
    let mut p = SVector::<f64, TERMS>::zeros();
    for _ in 0..ROUNDS {
        let mut ata = SMatrix::<f64, TERMS, TERMS>::zeros();
        let mut aty = SVector::<f64, TERMS>::zeros();
        for ((b, y), w) in rows.iter().zip(&weights) {
            let b = SVector::<f64, TERMS>::from_column_slice(b);
            ata += *w * b * b.transpose();
            aty += *w * *y * b;
        }
        p = ata.cholesky()?.solve(&aty);
        for ((b, y), w) in rows.iter().zip(weights.iter_mut()) {
            let r = (SVector::<f64, TERMS>::from_column_slice(b).dot(&p) - y).abs();
            *w = if r <= HUBER_MODULES {
                1.0
            } else {
                HUBER_MODULES / r
            };
        }
    }
    p.iter().all(|x| x.is_finite()).then(|| p.into())
}

/// Module coordinates to the photo's pixels: H after the warp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct WarpedGrid {
    pub(super) h: Homography,
    pub(super) warp: Warp,
}

impl WarpedGrid {
    /// A module point in the photo, px.
    pub(super) fn map(&self, m: ModulePoint) -> PixelPoint {
        self.h.map(self.warp.apply(m))
    }

    /// The photo's local scale at a module point: pixels per module along u and along v,
    /// and the cosine of the angle between the two directions in the photo.
    pub(super) fn px_per_module(&self, m: ModulePoint) -> (f64, f64, f64) {
        let a = self.map(m);
        let du = (self.map(ModulePoint::new(m.u + SCALE_STEP_MODULES, m.v)).0 - a.0)
            / SCALE_STEP_MODULES;
        let dv = (self.map(ModulePoint::new(m.u, m.v + SCALE_STEP_MODULES)).0 - a.0)
            / SCALE_STEP_MODULES;
        let (lu, lv) = (du.norm(), dv.norm());
        (lu, lv, du.dot(&dv) / (lu * lv))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth bend of a 33-module grid, as a lens would give, and edges observed on it.
    fn bent(m: ModulePoint) -> ModulePoint {
        let (x, y) = (m.u / 33.0 - 0.5, m.v / 33.0 - 0.5);
        ModulePoint::new(m.u + 0.4 * x * y + 0.2 * x * x, m.v - 0.3 * x * x * y + 0.1)
    }

    /// Every edge of a 33-module grid seen under `warp`: the offset δ at which the bent
    /// symbol's line u = c (or v = c) crosses the warped grid's line.
    fn edges_under(warp: &Warp) -> Vec<EdgeOffset> {
        let mut edges = Vec::new();
        for c in 0..=33 {
            for k in 0..33 {
                let (c, t) = (f64::from(c), f64::from(k) + 0.5);
                for along_u in [true, false] {
                    let seen = |d: f64| {
                        let m = if along_u {
                            ModulePoint::new(c + d, t)
                        } else {
                            ModulePoint::new(t, c + d)
                        };
                        let p = bent(warp.apply(m));
                        if along_u { p.u - c } else { p.v - c }
                    };
                    // Newton on d, with the derivative by differences.
                    let mut d = 0.0;
                    for _ in 0..20 {
                        d -= seen(d) / ((seen(d + 1e-6) - seen(d)) / 1e-6);
                    }
                    edges.push(EdgeOffset {
                        along_u,
                        c,
                        t,
                        delta: d,
                    });
                }
            }
        }
        edges
    }

    #[test]
    fn the_fit_follows_a_cubic_bend_and_ignores_an_outlier() {
        let mut warp = Warp::identity(33.0);
        for _ in 0..2 {
            let mut edges = edges_under(&warp);
            edges[100].delta += 0.6;
            warp = warp.fit(&edges).expect("enough edges");
        }
        for (u, v) in [(0.0, 0.0), (16.5, 3.0), (33.0, 33.0), (7.0, 29.0)] {
            // The warp maps a point of the printed grid to where the bend shows it:
            // bent(warp(m)) = m.
            let back = bent(warp.apply(ModulePoint::new(u, v)));
            assert!(
                (back.u - u).abs() < 2e-3 && (back.v - v).abs() < 2e-3,
                "({u}, {v}): {back:?}"
            );
        }
        let residual = edges_under(&warp)
            .iter()
            .map(|e| e.delta.abs())
            .fold(0.0, f64::max);
        assert!(residual < 2e-3, "largest edge offset {residual}");
    }

    #[test]
    fn too_few_edges_fit_no_warp() {
        let edges = vec![
            EdgeOffset {
                along_u: true,
                c: 0.0,
                t: 0.5,
                delta: 0.0
            };
            MIN_EDGES - 1
        ];
        assert!(Warp::identity(21.0).fit(&edges).is_none());
    }
}
