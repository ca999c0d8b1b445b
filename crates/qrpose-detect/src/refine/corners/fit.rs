//! From edge observations to geometry (stages 4 and 5 of [`super::refine_corners`]): the
//! module-to-image homography that puts every observation on its grid line (iteratively
//! reweighted linear least squares, Huber weights), and the twelve finder corners from
//! line fits to each finder side.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use super::edges::{Axis, Observation};
use crate::refine::homography::Homography;
use nalgebra::{DMatrix, Matrix3};
use qrpose_core::geometry::frames::PixelPoint;

/// Huber threshold of the homography fit, px.
const HUBER_PX: f64 = 0.3;
/// The reweighted homography fit stops once no Huber weight changes by more than this.
const WEIGHT_SETTLED: f64 = 1e-3;
/// Fewest edge observations on one finder side for its line fit.
const MIN_SIDE_OBSERVATIONS: usize = 3;

/// The homography (module → image) that best puts each observation on its grid line.
pub(super) fn fit_homography(obs: &[Observation], start: &Homography) -> Option<Homography> {
    if obs.len() < 8 {
        return None;
    }
    // Normalise image coordinates.
    let n = obs.len() as f64;
    let (mx, my) = obs.iter().fold((0.0, 0.0), |(a, b), o| {
        (a + o.point.u() / n, b + o.point.v() / n)
    });
    let scale = obs
        .iter()
        .map(|o| (o.point.u() - mx).hypot(o.point.v() - my))
        .sum::<f64>()
        / n;
    if scale <= 0.0 {
        return None;
    }
    let s = 1.0 / scale;
    let t = Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0);
    let t_inv = t.try_inverse()?;
    // G maps normalised image points to module coordinates: G = H⁻¹ · T⁻¹.
    let mut g = start.matrix().try_inverse()? * t_inv;
    let mut weights = vec![1.0; obs.len()];
    for _ in 0..6 {
        let mut a = DMatrix::<f64>::zeros(obs.len(), 9);
        for (k, o) in obs.iter().enumerate() {
            let x = t * nalgebra::Vector3::new(o.point.u(), o.point.v(), 1.0);
            let w3 = g.row(2).dot(&x.transpose());
            if w3.abs() < 1e-12 {
                return None;
            }
            // Module-unit residual = row · g / w3; times px per module for pixels.
            let wk = weights[k] * o.px_per_module / w3;
            let base = match o.axis {
                Axis::U => 0,
                Axis::V => 3,
            };
            for c in 0..3 {
                a[(k, base + c)] = wk * x[c];
                a[(k, 6 + c)] = -wk * o.c * x[c];
            }
        }
        let svd = (a.transpose() * &a).symmetric_eigen();
        let (imin, _) = svd
            .eigenvalues
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))?;
        let v = svd.eigenvectors.column(imin);
        g = Matrix3::new(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]);
        // Huber weights from the pixel residuals; once they stop changing, so does G.
        let mut largest_change: f64 = 0.0;
        for (k, o) in obs.iter().enumerate() {
            let r = residual_px(&g, &t, o).abs();
            let w = if r <= HUBER_PX { 1.0 } else { HUBER_PX / r };
            largest_change = largest_change.max((w - weights[k]).abs());
            weights[k] = w;
        }
        if largest_change < WEIGHT_SETTLED {
            break;
        }
    }
    let h = (g * t).try_inverse()?;
    Homography::from_matrix(h / h[(2, 2)])
}

fn residual_px(g: &Matrix3<f64>, t: &Matrix3<f64>, o: &Observation) -> f64 {
    let x = t * nalgebra::Vector3::new(o.point.u(), o.point.v(), 1.0);
    let m = g * x;
    let coord = match o.axis {
        Axis::U => m.x / m.z,
        Axis::V => m.y / m.z,
    };
    (coord - o.c) * o.px_per_module
}

/// A line a·u + b·v = c in the image, (a, b) unit.
#[derive(Debug, Clone, Copy)]
struct Line {
    a: f64,
    b: f64,
    c: f64,
}

/// Total-least-squares line through points, with one Huber reweighting.
fn fit_line(points: &[PixelPoint]) -> Option<Line> {
    if points.len() < 2 {
        return None;
    }
    let mut w = vec![1.0; points.len()];
    let mut line = None;
    for _ in 0..3 {
        let sw: f64 = w.iter().sum();
        let (mu, mv) = points.iter().zip(&w).fold((0.0, 0.0), |(a, b), (p, wk)| {
            (a + wk * p.u() / sw, b + wk * p.v() / sw)
        });
        let (mut suu, mut suv, mut svv) = (0.0, 0.0, 0.0);
        for (p, wk) in points.iter().zip(&w) {
            let (du, dv) = (p.u() - mu, p.v() - mv);
            suu += wk * du * du;
            suv += wk * du * dv;
            svv += wk * dv * dv;
        }
        // Normal = eigenvector of the smaller eigenvalue of the scatter matrix.
        let angle = 0.5 * (2.0 * suv).atan2(suu - svv);
        let (a, b) = (-angle.sin(), angle.cos());
        let l = Line {
            a,
            b,
            c: a * mu + b * mv,
        };
        for (p, wk) in points.iter().zip(w.iter_mut()) {
            let r = (l.a * p.u() + l.b * p.v() - l.c).abs();
            *wk = if r <= HUBER_PX { 1.0 } else { HUBER_PX / r };
        }
        line = Some(l);
    }
    line
}

fn intersect(l1: &Line, l2: &Line) -> Option<PixelPoint> {
    let det = l1.a * l2.b - l1.b * l2.a;
    if det.abs() < 1e-9 {
        return None;
    }
    Some(PixelPoint::new(
        (l1.c * l2.b - l1.b * l2.c) / det,
        (l1.a * l2.c - l1.c * l2.a) / det,
    ))
}

/// Finder corners from per-side line fits: `None` unless all twelve sides were measured.
pub(super) fn finder_corners(obs: &[Observation]) -> Option<[PixelPoint; 12]> {
    let mut out = [PixelPoint::new(0.0, 0.0); 12];
    for f in 0..3 {
        let mut lines = [None; 4];
        for (side, line) in lines.iter_mut().enumerate() {
            let points: Vec<PixelPoint> = obs
                .iter()
                .filter(|o| o.finder_side == Some((f, side)))
                .map(|o| o.point)
                .collect();
            if points.len() < MIN_SIDE_OBSERVATIONS {
                return None;
            }
            *line = fit_line(&points);
        }
        let [top, right, bottom, left] = lines.map(|l| l.ok_or(()));
        let (top, right, bottom, left) = (top.ok()?, right.ok()?, bottom.ok()?, left.ok()?);
        out[4 * f] = intersect(&top, &left)?;
        out[4 * f + 1] = intersect(&top, &right)?;
        out[4 * f + 2] = intersect(&bottom, &right)?;
        out[4 * f + 3] = intersect(&bottom, &left)?;
    }
    Some(out)
}
