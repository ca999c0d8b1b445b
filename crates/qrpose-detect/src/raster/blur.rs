//! Gaussian blurs: [`sharpen`] (an unsharp mask on a [`GrayImage`], or with amount −1 the
//! Gaussian blur itself), for the second passes of `auto` ([`crate::find_candidates`]), and
//! [`gaussian_blur_plane`] on a floating-point plane, for the renderer's lens blur
//! (`qrpose_sim::render`).
//!
//! Both are one separable convolution (`separable_gaussian`) with the same kernel
//! ([`gaussian_kernel`]: radius ⌈3σ⌉, at least 1, normalised to sum 1) and borders clamped
//! to the nearest pixel; they differ only in the number type: `f32` for [`sharpen`] (u8 in
//! and out: speed), `f64` for the renderer's plane (before noise and quantisation).

use crate::raster::GrayImage;
use std::iter::Sum;
use std::ops::{AddAssign, Mul};

/// Unsharp mask: `image + amount · (image − Gaussian(image, σ))`, clamped to 0-255
/// (`amount` = −1 is the Gaussian blur itself).
/// Blur of σ ≈ 0.5 module leaves a module-wide pattern a sixth of its contrast; this gives
/// the binarisers of the backends some of it back (measured on the rendered set, see
/// docs/detection.md).
pub fn sharpen(image: &GrayImage, sigma_px: f64, amount: f64) -> Option<GrayImage> {
    let (w, h) = (image.width(), image.height());
    let src = image.pixels();
    let amount = amount as f32;
    let mut pixels = Vec::with_capacity(w * h);
    separable_gaussian(
        h,
        w,
        sigma_px,
        |y, row: &mut [f32]| {
            let line = src.get(y * w..(y + 1) * w).unwrap_or_default();
            for (r, &p) in row.iter_mut().zip(line) {
                *r = f32::from(p);
            }
        },
        |y, blurred| {
            let row = src.get(y * w..(y + 1) * w).unwrap_or_default();
            pixels.extend(row.iter().zip(blurred).map(|(&p, &b)| {
                let v = f32::from(p);
                // Clamped first, then rounded half up: the same as `round()` on 0..=255, without
                // a call to libm per pixel.
                ((v + amount * (v - b)).clamp(0.0, 255.0) + 0.5) as u8
            }));
        },
    );
    GrayImage::new(w, h, pixels)
}

/// Gaussian blur of σ `sigma_px` of a row-major `width` × `height` plane, borders clamped
/// (the renderer's lens blur, in `f64`). `None` unless `plane.len() == width · height` and
/// both are positive.
pub fn gaussian_blur_plane(
    plane: &[f64],
    width: usize,
    height: usize,
    sigma_px: f64,
) -> Option<Vec<f64>> {
    if width == 0 || height == 0 || width.checked_mul(height) != Some(plane.len()) {
        return None;
    }
    let mut out = Vec::with_capacity(plane.len());
    separable_gaussian(
        height,
        width,
        sigma_px,
        |y, row: &mut [f64]| row.copy_from_slice(&plane[y * width..(y + 1) * width]),
        |_, blurred| out.extend_from_slice(blurred),
    );
    Some(out)
}

/// The normalised Gaussian kernel of σ `sigma_px`: 2r + 1 taps, r = ⌈3σ⌉ (at least 1).
fn gaussian_kernel(sigma_px: f64) -> Vec<f64> {
    let radius = (3.0 * sigma_px).ceil().max(1.0) as i64;
    let raw: Vec<f64> = (-radius..=radius)
        .map(|k| (-0.5 * (k as f64 / sigma_px).powi(2)).exp())
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|k| k / sum).collect()
}

/// The number types [`separable_gaussian`] works in.
trait Sample: Copy + Default + Mul<Output = Self> + AddAssign + Sum {
    /// A kernel tap (computed in `f64`) in this type.
    fn from_f64(x: f64) -> Self;
}

impl Sample for f32 {
    fn from_f64(x: f64) -> Self {
        x as f32
    }
}

impl Sample for f64 {
    fn from_f64(x: f64) -> Self {
        x
    }
}

/// Outputs that [`weighted_sum`] computes together, their partial sums held in registers.
const LANES: usize = 8;

/// `out[i] = Σ_k kernel[k] · sources[k][i]`, the taps added in kernel order starting from
/// zero (so each output is the same number a tap-by-tap loop over the whole row gives), for
/// [`LANES`] outputs at a time: their sums stay in registers across the taps instead of
/// going through memory after each one, which made the filter several times slower.
/// Every source is at least `out.len()` long.
fn weighted_sum<T: Sample>(kernel: &[T], sources: &[&[T]], out: &mut [T]) {
    let w = out.len();
    let blocked = w - w % LANES;
    for (i, chunk) in out[..blocked].chunks_exact_mut(LANES).enumerate() {
        let at = i * LANES;
        let mut acc = [T::default(); LANES];
        for (&kv, src) in kernel.iter().zip(sources) {
            let Some(lanes) = src
                .get(at..at + LANES)
                .and_then(|s| <&[T; LANES]>::try_from(s).ok())
            else {
                continue;
            };
            for (a, &p) in acc.iter_mut().zip(lanes) {
                *a += kv * p;
            }
        }
        chunk.copy_from_slice(&acc);
    }
    for (i, o) in out.iter_mut().enumerate().skip(blocked) {
        let mut acc = T::default();
        for (&kv, src) in kernel.iter().zip(sources) {
            acc += kv * src.get(i).copied().unwrap_or_default();
        }
        *o = acc;
    }
}

/// Separable Gaussian blur of a `height` × `width` plane whose row `y` the caller writes
/// into a buffer with `read_row(y, row)`, borders clamped to the nearest pixel: a horizontal
/// pass on an edge-padded copy of each row, then the vertical pass a whole row at a time
/// (both by [`weighted_sum`], which vectorises). Each blurred row is handed to `emit(y, row)`
/// in order.
///
/// Memory is O(width · kernel length): the horizontally blurred rows live in a ring of
/// 2r + 1 rows (row `s` in slot `s mod (2r + 1)`), each computed once when the vertical
/// pass first needs it, so a whole-frame filter never holds a second full-size plane in
/// floating point (that was 8 bytes a pixel on a 50 MP frame). Taps are summed in kernel
/// order, horizontal pass first. Nothing is emitted for a zero `width` or `height`.
fn separable_gaussian<T: Sample>(
    height: usize,
    width: usize,
    sigma_px: f64,
    mut read_row: impl FnMut(usize, &mut [T]),
    mut emit: impl FnMut(usize, &[T]),
) {
    if width == 0 || height == 0 {
        return;
    }
    let (w, h) = (width, height);
    let kernel: Vec<T> = gaussian_kernel(sigma_px)
        .into_iter()
        .map(T::from_f64)
        .collect();
    let radius = kernel.len() / 2;
    let slots = kernel.len();
    let mut ring = vec![T::default(); slots * w];
    let mut padded = vec![T::default(); w + 2 * radius];
    let mut blurred = vec![T::default(); w];
    // Source rows 0..next are in the ring (the last `slots` of them still valid).
    let mut next = 0;
    for y in 0..h {
        let needed = (y + radius).min(h - 1);
        while next <= needed {
            read_row(next, &mut padded[radius..radius + w]);
            let (first, last) = (padded[radius], padded[radius + w - 1]);
            padded[..radius].fill(first);
            padded[radius + w..].fill(last);
            let slot = (next % slots) * w;
            let shifted: Vec<&[T]> = (0..slots).map(|k| &padded[k..k + w]).collect();
            weighted_sum(&kernel, &shifted, &mut ring[slot..slot + w]);
            next += 1;
        }
        let rows: Vec<&[T]> = (0..slots)
            .map(|k| {
                let slot = ((y + k).saturating_sub(radius).min(h - 1) % slots) * w;
                &ring[slot..slot + w]
            })
            .collect();
        weighted_sum(&kernel, &rows, &mut blurred);
        emit(y, &blurred);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blur written out directly: every output pixel a sum over the kernel, borders
    /// clamped (the renderer's blur before it moved here).
    fn direct_blur(src: &[f64], w: usize, h: usize, sigma: f64) -> Vec<f64> {
        let kernel = gaussian_kernel(sigma);
        let r = (kernel.len() / 2) as i64;
        let at = |i: i64, n: usize| i.clamp(0, n as i64 - 1) as usize;
        let pass = |src: &[f64], horizontal: bool| -> Vec<f64> {
            (0..w * h)
                .map(|p| {
                    let (x, y) = ((p % w) as i64, (p / w) as i64);
                    kernel
                        .iter()
                        .enumerate()
                        .map(|(k, kv)| {
                            let d = k as i64 - r;
                            let q = if horizontal {
                                y as usize * w + at(x + d, w)
                            } else {
                                at(y + d, h) * w + x as usize
                            };
                            kv * src[q]
                        })
                        .sum()
                })
                .collect()
        };
        pass(&pass(src, true), false)
    }

    fn test_plane(w: usize, h: usize) -> Vec<f64> {
        (0..w * h)
            .map(|k| ((k * 37 + (k / w) * 101) % 251) as f64 * 0.93 + 3.0)
            .collect()
    }

    #[test]
    fn kernel_is_normalised_symmetric_and_three_sigma_wide() {
        for (sigma, radius) in [(0.1, 1), (0.5, 2), (1.0, 3), (1.5, 5), (2.0, 6)] {
            let k = gaussian_kernel(sigma);
            assert_eq!(k.len(), 2 * radius + 1, "σ {sigma}");
            assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(k.iter().zip(k.iter().rev()).all(|(a, b)| a == b));
        }
    }

    #[test]
    fn plane_blur_is_the_direct_convolution_exactly() {
        for (w, h) in [(1, 1), (1, 7), (9, 1), (17, 13), (40, 30)] {
            let plane = test_plane(w, h);
            for sigma in [0.3, 0.8, 1.4, 2.5] {
                let fast = gaussian_blur_plane(&plane, w, h, sigma).expect("a size");
                assert_eq!(
                    fast,
                    direct_blur(&plane, w, h, sigma),
                    "{w} × {h}, σ {sigma}"
                );
            }
        }
    }

    #[test]
    fn plane_blur_refuses_a_wrong_size() {
        assert_eq!(gaussian_blur_plane(&[1.0; 6], 4, 2, 1.0), None);
        assert_eq!(gaussian_blur_plane(&[], 0, 0, 1.0), None);
    }

    /// The f32 path (`sharpen`) against the direct convolution in f32, taps in kernel
    /// order from zero: the blocked sums are the same numbers, bit for bit.
    #[test]
    fn sharpen_blur_is_the_direct_f32_convolution_exactly() {
        for (w, h) in [(1, 1), (7, 3), (8, 8), (17, 13), (41, 29)] {
            let pixels: Vec<u8> = (0..w * h)
                .map(|k| ((k * 53 + k / w * 7) % 256) as u8)
                .collect();
            for sigma in [0.75, 1.0, 1.5, 2.0] {
                let kernel: Vec<f32> = gaussian_kernel(sigma).iter().map(|&k| k as f32).collect();
                let r = (kernel.len() / 2) as i64;
                let at = |i: i64, n: usize| i.clamp(0, n as i64 - 1) as usize;
                let horizontal: Vec<f32> = (0..w * h)
                    .map(|p| {
                        let (x, y) = ((p % w) as i64, p / w);
                        let mut acc = 0.0f32;
                        for (k, kv) in kernel.iter().enumerate() {
                            acc += kv * f32::from(pixels[y * w + at(x + k as i64 - r, w)]);
                        }
                        acc
                    })
                    .collect();
                let mut want = Vec::with_capacity(w * h);
                for p in 0..w * h {
                    let (x, y) = (p % w, (p / w) as i64);
                    let mut acc = 0.0f32;
                    for (k, kv) in kernel.iter().enumerate() {
                        acc += kv * horizontal[at(y + k as i64 - r, h) * w + x];
                    }
                    want.push(acc);
                }
                let mut got = Vec::with_capacity(w * h);
                separable_gaussian(
                    h,
                    w,
                    sigma,
                    |y, row: &mut [f32]| {
                        for (o, &p) in row.iter_mut().zip(&pixels[y * w..(y + 1) * w]) {
                            *o = f32::from(p);
                        }
                    },
                    |_, row| got.extend_from_slice(row),
                );
                assert_eq!(got, want, "{w} × {h}, σ {sigma}");
            }
        }
    }

    #[test]
    fn sharpen_of_minus_one_is_the_rounded_blur() {
        let (w, h) = (23, 17);
        let pixels: Vec<u8> = (0..w * h).map(|k| ((k * 53) % 256) as u8).collect();
        let image = GrayImage::new(w, h, pixels).expect("a size");
        let blurred = sharpen(&image, 1.2, -1.0).expect("a size");
        let plane: Vec<f64> = image.pixels().iter().map(|&p| f64::from(p)).collect();
        let reference = direct_blur(&plane, w, h, 1.2);
        for (got, want) in blurred.pixels().iter().zip(&reference) {
            // f32 against f64: at most one grey level apart where the value is near a half.
            assert!(
                (f64::from(*got) - want.round()).abs() <= 1.0,
                "{got} vs {want}"
            );
        }
        let flat = GrayImage::new(8, 8, vec![77; 64]).expect("a size");
        assert_eq!(sharpen(&flat, 1.5, 2.0), Some(flat.clone()));
    }
}
