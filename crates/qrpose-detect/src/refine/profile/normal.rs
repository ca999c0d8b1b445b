//! The standard normal distribution for the profile model: Φ and φ from a table, linearly
//! interpolated (the profile fit evaluates them a million times per frame), and the exact
//! functions the table is built from (erf by Abramowitz & Stegun).

use std::sync::LazyLock;

/// erf, Abramowitz & Stegun 7.1.26 (|error| < 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let y = 1.0
        - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t
            + 0.254_829_592)
            * t
            * (-x * x).exp();
    if x >= 0.0 { y } else { -y }
}

/// Half-width of the tabulated normal distribution, standard deviations: beyond it Φ is 0
/// or 1 and φ is 0 to double precision for this model's purposes (φ(8) ≈ 5e-15).
const TABLE_Z_MAX: f64 = 8.0;
/// Table entries per standard deviation. Linear interpolation between entries errs by at
/// most h²/8 · max|φ'| ≈ 5e-7 in Φ at h = 1/256: far below a grey level.
const TABLE_STEPS_PER_UNIT: f64 = 256.0;

/// Φ and φ of the standard normal distribution at `TABLE_STEPS_PER_UNIT` steps on
/// [−TABLE_Z_MAX, TABLE_Z_MAX], each entry with its forward differences for the linear
/// interpolation: [Φ(z_k), φ(z_k), Φ(z_k+1) − Φ(z_k), φ(z_k+1) − φ(z_k)]. The profile fit
/// evaluates them a million times per frame; a table lookup replaces two `exp` calls (and
/// libm's slow underflow path for the far ends of a pattern, which `exp(-z²)` hits at
/// |z| > 27), and one entry is one bounds check and half a cache line.
pub(super) struct NormalTable {
    entries: Vec<[f64; 4]>,
}

// The table length is a small positive constant (4097).
#[allow(clippy::cast_possible_truncation)]
pub(super) static NORMAL_TABLE: LazyLock<NormalTable> = LazyLock::new(|| {
    let count = (2.0 * TABLE_Z_MAX * TABLE_STEPS_PER_UNIT) as usize + 1;
    let z = |k: usize| k as f64 / TABLE_STEPS_PER_UNIT - TABLE_Z_MAX;
    NormalTable {
        entries: (0..count)
            .map(|k| {
                let (c0, p0) = (cdf_exact(z(k)), pdf_exact(z(k)));
                let (c1, p1) = (cdf_exact(z(k + 1)), pdf_exact(z(k + 1)));
                [c0, p0, c1 - c0, p1 - p0]
            })
            .collect(),
    }
});

/// Φ(z) from erf (to its 1.5e-7).
pub(super) fn cdf_exact(z: f64) -> f64 {
    0.5 * (1.0 + erf(z / std::f64::consts::SQRT_2))
}

/// φ(z), exact.
fn pdf_exact(z: f64) -> f64 {
    (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// (Φ(z), φ(z)) from the table, linearly interpolated.
// x is in [0, 2 · TABLE_Z_MAX · TABLE_STEPS_PER_UNIT) here, so the index cannot truncate.
#[allow(clippy::cast_possible_truncation)]
#[inline]
pub(super) fn normal(table: &NormalTable, z: f64) -> (f64, f64) {
    if z.is_nan() || z <= -TABLE_Z_MAX {
        return (0.0, 0.0);
    }
    if z >= TABLE_Z_MAX {
        return (1.0, 0.0);
    }
    let x = (z + TABLE_Z_MAX) * TABLE_STEPS_PER_UNIT;
    let k = x as usize;
    let f = x - k as f64;
    match table.entries.get(k) {
        Some([c, p, dc, dp]) => (c + f * dc, p + f * dp),
        None => (cdf_exact(z), pdf_exact(z)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tabulated_normal_matches_the_exact_functions() {
        for k in -2000..=2000 {
            let z = f64::from(k) * 0.00437;
            let (c, p) = normal(&NORMAL_TABLE, z);
            assert!((c - cdf_exact(z)).abs() < 1e-6, "Φ({z})");
            assert!((p - pdf_exact(z)).abs() < 1e-6, "φ({z})");
        }
        assert_eq!(normal(&NORMAL_TABLE, -1e3), (0.0, 0.0));
        assert_eq!(normal(&NORMAL_TABLE, 1e3), (1.0, 0.0));
        assert_eq!(normal(&NORMAL_TABLE, f64::NAN), (0.0, 0.0));
    }

    #[test]
    fn erf_matches_known_values() {
        assert!((erf(0.5) - 0.520_499_877_8).abs() < 2e-7);
        assert!((erf(-1.5) + 0.966_105_146_5).abs() < 2e-7);
    }
}
