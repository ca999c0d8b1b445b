//! The module map of a symbol under its grid (stage 2 of [`super::refine_corners`]):
//! the function patterns (three finders with their separators, two timing patterns) are
//! known for every module count; data modules are read at their centres. Also the light
//! and dark reference levels (quiet zone, finder cores) that the reading thresholds at.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use crate::raster::GrayImage;
use crate::refine::homography::ModulePoint;
use qrpose_core::geometry::frames::PixelPoint;

/// Module colours: `Some(true)` dark, `Some(false)` light, `None` unknown. Outside the
/// symbol everything is light (the quiet zone).
pub(crate) struct ModuleMap {
    /// Modules per side.
    pub(crate) n: usize,
    dark: Vec<Option<bool>>,
}

impl ModuleMap {
    /// The colour of module (i, j) (column i, row j).
    pub(crate) fn get(&self, i: i64, j: i64) -> Option<bool> {
        let n = self.n as i64;
        if i < 0 || j < 0 || i >= n || j >= n {
            return Some(false);
        }
        self.dark[(j as usize) * self.n + i as usize]
    }
}

/// The colour of function-pattern module (i, j), or `None` for a data module.
fn function_module(n: usize, i: usize, j: usize) -> Option<bool> {
    let finder = |di: usize, dj: usize| -> Option<bool> {
        // A finder with its separator: 8 × 8 from its corner.
        if di == 7 || dj == 7 {
            return Some(false);
        }
        let ring = di == 0 || dj == 0 || di == 6 || dj == 6;
        let core = (2..=4).contains(&di) && (2..=4).contains(&dj);
        Some(ring || core)
    };
    if i < 8 && j < 8 {
        return finder(i, j);
    }
    if i + 8 >= n && j < 8 {
        return finder(n - 1 - i, j);
    }
    if i < 8 && j + 8 >= n {
        return finder(i, n - 1 - j);
    }
    if j == 6 {
        return Some(i.is_multiple_of(2));
    }
    if i == 6 {
        return Some(j.is_multiple_of(2));
    }
    None
}

/// Whether module (i, j) of an N-module symbol belongs to a finder pattern (with its
/// separator) or a timing pattern, whose colours are known without reading them; `false`
/// outside the symbol.
pub(crate) fn is_function_module(n: usize, i: i64, j: i64) -> bool {
    match (usize::try_from(i), usize::try_from(j)) {
        (Ok(i), Ok(j)) if i < n && j < n => function_module(n, i, j).is_some(),
        _ => false,
    }
}

/// Every function-pattern module (i, j, dark) of an N-module symbol: the three finders with
/// their separators, and the two timing patterns between them. The same modules as
/// [`function_module`] marks, without visiting the N² data modules.
pub(super) fn function_modules(n: usize) -> impl Iterator<Item = (usize, usize, bool)> {
    let origins = [(0, 0), (n - 8, 0), (0, n - 8)];
    let finders = origins.into_iter().flat_map(move |(i0, j0)| {
        (0..64).filter_map(move |k| {
            let (i, j) = (i0 + k % 8, j0 + k / 8);
            function_module(n, i, j).map(|dark| (i, j, dark))
        })
    });
    let timing = (8..n - 8).flat_map(|k| [(k, 6, k % 2 == 0), (6, k, k % 2 == 0)]);
    // The timing patterns first: they tell module counts apart soonest.
    timing.chain(finders)
}

/// How many modules [`function_modules`] lists: three 8 × 8 finders with separators and
/// two timing patterns of N − 16 modules each.
pub(super) fn function_module_count(n: usize) -> usize {
    3 * 64 + 2 * (n - 16)
}

/// Light and dark reference levels: the quiet zone just outside the symbol and the finder
/// cores, sampled where `map` (module coordinates to the photo's pixels) puts them. `None`
/// when they cannot be sampled.
pub(crate) fn reference_levels(
    image: &GrayImage,
    map: impl Fn(ModulePoint) -> PixelPoint,
    n: usize,
) -> Option<(f64, f64)> {
    let nf = n as f64;
    let mut light = Vec::new();
    for k in 0..(4 * n) {
        let t = (k as f64 + 0.5) / 4.0;
        for p in [
            ModulePoint::new(t, -1.5),
            ModulePoint::new(t, nf + 1.5),
            ModulePoint::new(-1.5, t),
            ModulePoint::new(nf + 1.5, t),
        ] {
            let x = map(p);
            if let Some(i) = image.sample(x.u(), x.v()) {
                light.push(i);
            }
        }
    }
    let mut dark = Vec::new();
    for (u0, v0) in [(2.0, 2.0), (nf - 5.0, 2.0), (2.0, nf - 5.0)] {
        for a in 0..3 {
            for b in 0..3 {
                let x = map(ModulePoint::new(
                    u0 + f64::from(a) + 0.5,
                    v0 + f64::from(b) + 0.5,
                ));
                if let Some(i) = image.sample(x.u(), x.v()) {
                    dark.push(i);
                }
            }
        }
    }
    Some((median(&mut light)?, median(&mut dark)?))
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(values[values.len() / 2])
}

/// The module map under `map` (module coordinates to the photo's pixels): function
/// patterns known, data modules read at their centres.
pub(crate) fn module_map(
    image: &GrayImage,
    map: impl Fn(ModulePoint) -> PixelPoint,
    n: usize,
    light: f64,
    dark: f64,
) -> ModuleMap {
    let threshold = 0.5 * (light + dark);
    let inverted = dark > light;
    let mut colours = vec![None; n * n];
    for j in 0..n {
        for i in 0..n {
            colours[j * n + i] = function_module(n, i, j).or_else(|| {
                let x = map(ModulePoint::new(i as f64 + 0.5, j as f64 + 0.5));
                image
                    .sample(x.u(), x.v())
                    .map(|value| (value < threshold) != inverted)
            });
        }
    }
    ModuleMap { n, dark: colours }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn function_modules_lists_exactly_the_function_patterns() {
        for n in [21, 25, 57, 177] {
            let mut listed: Vec<_> = function_modules(n).collect();
            listed.sort_unstable();
            let mut scanned: Vec<_> = (0..n)
                .flat_map(|j| (0..n).map(move |i| (i, j)))
                .filter_map(|(i, j)| function_module(n, i, j).map(|dark| (i, j, dark)))
                .collect();
            scanned.sort_unstable();
            assert_eq!(listed.len(), function_module_count(n), "N = {n}");
            assert_eq!(listed, scanned, "N = {n}");
        }
    }
}
