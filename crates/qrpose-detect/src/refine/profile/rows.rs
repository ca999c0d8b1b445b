//! A profile across a module row that is narrow against the blur: the modules of the rows
//! on either side of the profile's row bleed into it.
//!
//! The profile runs along the middle of its row, half a row from each neighbour. Under a
//! Gaussian blur of σ (px) that is separable along the row and across it, a module of a
//! neighbouring row adds its darkness with the weight
//!
//! ```text
//! w₁ = Φ(−h / σ),   h = half the row's height, px,
//! ```
//!
//! and the profile's own row keeps w₀ = 1 − 2·w₁ (rows further away are beyond 1.5 rows:
//! Φ(−3h/σ)). The model's darkness is then w₀·S_row + w₁·(S_before + S_after), each S the
//! blurred dark runs of that row ([`super::fit_profile`]). When the neighbours' colours
//! differ from the row's (the data area of a symbol), leaving them out shifts the fitted
//! edge: by up to half a pixel at 4 px per module and σ 1 px on rendered photos.
//!
//! In the profile's units: with s the fitted blur in modules across the edge, `ppm_across`
//! and `ppm_along` the photo's pixels per module across the edge (along the profile) and
//! along it (across the row), h/σ = ½ · `ppm_along` / (s · `ppm_across`) whatever the
//! shear of the grid between the two directions.
//!
//! A tilted code shows its module grid sheared: the lines across the rows make an angle θ
//! other than 90° with the rows. The blur then reaches into a neighbouring row along a
//! slanted module boundary, and sees that row's pattern shifted along the profile by the
//! slant times the mean depth it reaches into the row, ā = σ·φ(h/σ)/Φ(−h/σ) (the mean of
//! a normal variable beyond h): in modules, s·φ(h/σ)/Φ(−h/σ)·cos θ, the row after the
//! profile's shifted forwards for cos θ > 0 and the row before it backwards (to first
//! order: the rows are two h deep and the shifted pattern is blurred a little more, both
//! left out).

use super::normal::cdf_exact;
use super::{DarkRun, Pattern, ProfileFit, fit_pattern, fit_profile};
use std::f64::consts::PI;

/// Below this neighbour weight the rows on either side are left out (a shift below 1e-4
/// module).
const MIN_NEIGHBOUR_WEIGHT: f64 = 1e-4;

/// Fits the edge of a profile along the middle of its module row with the row's dark runs
/// `rows[1]`, and those of the rows before and after it, `rows[0]` and `rows[2]`, weighted
/// by the blur (module doc). `ppm_ratio` = pixels per module along the profile over pixels
/// per module across the row; `cos_shear` = cos θ, θ the angle in the photo between the
/// grid's direction along the profile and its direction towards the row after. First fits the row alone ([`fit_profile`], from δ = 0), then
/// the three rows from that fit's δ and s. `None` as [`fit_profile`].
pub(crate) fn fit_profile_rows(
    rows: [&[DarkRun]; 3],
    (d, intensity): (&[f64], &[f64]),
    sigma0: f64,
    (ppm_ratio, cos_shear): (f64, f64),
) -> Option<ProfileFit> {
    let first = fit_profile(rows[1], d, intensity, sigma0, false)?;
    let w1 = neighbour_weight(first.sigma, ppm_ratio);
    if w1 < MIN_NEIGHBOUR_WEIGHT {
        return Some(first);
    }
    let w0 = 1.0 - 2.0 * w1;
    let z = 0.5 / (first.sigma * ppm_ratio);
    let depth = first.sigma * (-0.5 * z * z).exp() / (2.0 * PI).sqrt() / w1;
    let shift = depth * cos_shear;
    let shifted = |run: &DarkRun, by: f64| DarkRun {
        start: run.start + by,
        end: run.end + by,
    };
    let weighted = rows[1]
        .iter()
        .map(|run| (w0, *run))
        .chain(rows[0].iter().map(|run| (w1, shifted(run, -shift))))
        .chain(rows[2].iter().map(|run| (w1, shifted(run, shift))));
    fit_pattern(
        &Pattern::weighted(weighted)?,
        (d, intensity),
        (first.delta, first.sigma),
        false,
    )
}

/// w₁ of the module doc for the blur `sigma` (modules along the profile).
fn neighbour_weight(sigma: f64, ppm_ratio: f64) -> f64 {
    cdf_exact(-0.5 / (sigma * ppm_ratio))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blurred darkness of one row's runs at profile position x.
    fn darkness(runs: &[DarkRun], x: f64, delta: f64, sigma: f64) -> f64 {
        runs.iter()
            .map(|r| {
                cdf_exact((x - r.start - delta) / sigma) - cdf_exact((x - r.end - delta) / sigma)
            })
            .sum()
    }

    #[test]
    fn neighbouring_rows_of_other_colours_do_not_move_the_edge() {
        // The edge at 0 between a light and a dark module; the row above is dark over
        // [−1, 1), the row below light but for [1, 2). Rows 4 px high, 4 px per module along
        // the profile, σ 1 px: s = 0.25 module, w₁ = Φ(−2) = 2.3 %.
        let row = [DarkRun {
            start: 0.0,
            end: 100.0,
        }];
        let before = [DarkRun {
            start: -1.0,
            end: 1.0,
        }];
        let after = [DarkRun {
            start: 1.0,
            end: 2.0,
        }];
        let (sigma, true_delta) = (0.25, 0.07);
        let w1 = cdf_exact(-2.0);
        let d: Vec<f64> = (0..25).map(|k| -1.5 + 0.125 * f64::from(k)).collect();
        let intensity: Vec<f64> = d
            .iter()
            .map(|&x| {
                let s = (1.0 - 2.0 * w1) * darkness(&row, x, true_delta, sigma)
                    + w1 * (darkness(&before, x, true_delta, sigma)
                        + darkness(&after, x, true_delta, sigma));
                220.0 + (30.0 - 220.0) * s
            })
            .collect();
        let alone = fit_profile(&row, &d, &intensity, 0.3, false).expect("fits");
        let rows = fit_profile_rows([&before, &row, &after], (&d, &intensity), 0.3, (1.0, 0.0))
            .expect("fits");
        assert!(
            (rows.delta - true_delta).abs() < 2e-3,
            "three rows: δ {}",
            rows.delta
        );
        assert!(
            (alone.delta - true_delta).abs() > 5.0 * (rows.delta - true_delta).abs(),
            "the row alone is biased: δ {} against {}",
            alone.delta,
            rows.delta
        );
    }

    #[test]
    fn wide_rows_keep_the_single_row_fit() {
        assert!(neighbour_weight(0.1, 1.0) < MIN_NEIGHBOUR_WEIGHT);
        assert!(neighbour_weight(0.25, 1.0) > 0.02);
    }
}
