//! Image filters: every whole-image transform of the workspace in one place.
//!
//! - On [`GrayImage`], for the second passes of `auto` ([`crate::find_candidates`]):
//!   [`stretch_contrast`], [`invert`], [`sharpen`] (an unsharp mask, or with amount −1 the
//!   Gaussian blur itself), [`upscale_double`] and [`downscale_half`].
//! - On a floating-point plane, for the renderer's lens blur (`qrpose_sim::render`):
//!   [`gaussian_blur_plane`].
//!
//! Both Gaussian blurs are one separable convolution (`separable_gaussian`) with the same
//! kernel ([`gaussian_kernel`]: radius ⌈3σ⌉, at least 1, normalised to sum 1) and borders
//! clamped to the nearest pixel; they differ only in the number type: `f32` for
//! [`sharpen`] (u8 in and out: speed), `f64` for the renderer's plane (before noise and
//! quantisation).

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

/// Separable Gaussian blur of a `height` × `width` plane whose row `y` the caller writes
/// into a buffer with `read_row(y, row)`, borders clamped to the nearest pixel: a horizontal
/// pass on an edge-padded copy of each row, then the vertical pass a whole row at a time
/// (both loops vectorise). Each blurred row is handed to `emit(y, row)` in order.
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
            // Tap by tap over the whole row (a loop the compiler vectorises): each output
            // still adds its taps in kernel order, as the direct convolution does.
            let row = &mut ring[slot..slot + w];
            row.fill(T::default());
            for (k, &kv) in kernel.iter().enumerate() {
                for (o, &p) in row.iter_mut().zip(&padded[k..k + w]) {
                    *o += kv * p;
                }
            }
            next += 1;
        }
        blurred.fill(T::default());
        for (k, &kv) in kernel.iter().enumerate() {
            let yy = (y + k).saturating_sub(radius).min(h - 1);
            let slot = (yy % slots) * w;
            for (b, &t) in blurred.iter_mut().zip(&ring[slot..slot + w]) {
                *b += kv * t;
            }
        }
        emit(y, &blurred);
    }
}

/// The photographic negative, for light-on-dark codes.
pub fn invert(image: &GrayImage) -> Option<GrayImage> {
    let pixels = image.pixels().iter().map(|p| 255 - p).collect();
    GrayImage::new(image.width(), image.height(), pixels)
}

/// Doubles the image by bilinear interpolation (pixel centres kept: copy pixel (x, y)
/// samples the source at ((x + 0.5) / 2 − 0.5, (y + 0.5) / 2 − 0.5), clamped to the image).
///
/// At that spacing every copy pixel lies a quarter pixel from its nearest source pixel in
/// each axis, so the weights are fixed (¾, ¼) per axis and the result is the integer
/// `(9a + 3b + 3c + d + 8) / 16`: exactly the rounded bilinear sample ([`GrayImage::sample`]
/// rounded half up), in integer arithmetic, a row pair at a time.
pub fn upscale_double(image: &GrayImage) -> Option<GrayImage> {
    let (w, h) = (image.width(), image.height());
    if w == 0 || h == 0 {
        return None;
    }
    let src = image.pixels();
    let mut pixels = vec![0u8; (2 * w).checked_mul(2 * h)?];
    // Horizontally doubled rows, weights ×4: [3·p(i) + p(i−1), 3·p(i) + p(i+1)].
    let widen = |y: usize, out: &mut [u16]| {
        let row = &src[y * w..(y + 1) * w];
        for (i, pair) in out.chunks_exact_mut(2).enumerate() {
            let here = 3 * u16::from(row[i]);
            pair[0] = here + u16::from(row[i.saturating_sub(1)]);
            pair[1] = here + u16::from(row[(i + 1).min(w - 1)]);
        }
    };
    let (mut this, mut other) = (vec![0u16; 2 * w], vec![0u16; 2 * w]);
    for y in 0..h {
        widen(y, &mut this);
        for (dy, neighbour) in [(0, y.saturating_sub(1)), (1, (y + 1).min(h - 1))] {
            widen(neighbour, &mut other);
            let out = &mut pixels[(2 * y + dy) * 2 * w..(2 * y + dy + 1) * 2 * w];
            for ((o, &a), &b) in out.iter_mut().zip(&this).zip(&other) {
                // (3·a + b) / 16 with a, b ≤ 4·255: at most 255 after the shift.
                *o = ((3 * u32::from(a) + u32::from(b) + 8) >> 4) as u8;
            }
        }
    }
    GrayImage::new(2 * w, 2 * h, pixels)
}

/// Stretches the 1st-99th percentile range to 0-255; `None` when it is already full.
pub fn stretch_contrast(image: &GrayImage) -> Option<GrayImage> {
    let mut hist = [0usize; 256];
    for &p in image.pixels() {
        hist[usize::from(p)] += 1;
    }
    let total = image.pixels().len();
    let pct = |q: f64| {
        let target = (q * total as f64) as usize;
        let mut acc = 0;
        for (value, count) in hist.iter().enumerate() {
            acc += count;
            if acc > target {
                return value;
            }
        }
        255
    };
    let (lo, hi) = (pct(0.01), pct(0.99));
    if hi <= lo || (lo < 10 && hi > 245) {
        return None;
    }
    let scale = 255.0 / (hi - lo) as f64;
    let pixels = image
        .pixels()
        .iter()
        .map(|&p| (((f64::from(p) - lo as f64) * scale).clamp(0.0, 255.0)).round() as u8)
        .collect();
    GrayImage::new(image.width(), image.height(), pixels)
}

/// Output pixels per block of [`downscale_half`]: fixed-size blocks let the compiler keep
/// the pairwise sums in vector registers, which a loop over `chunks_exact(2)` of a row of
/// sums did not (docs/detection.md, Speed: the find stage of `detect_speed`).
const DOWNSCALE_BLOCK_PX: usize = 16;

/// Halves the image by 2 × 2 box averaging (rounded); an odd last row or column is dropped.
pub fn downscale_half(image: &GrayImage) -> Option<GrayImage> {
    let (w, h) = (image.width() / 2, image.height() / 2);
    let stride = image.width();
    let mut pixels = vec![0u8; w * h];
    for (out, pair) in pixels
        .chunks_exact_mut(w.max(1))
        .zip(image.pixels().chunks_exact(2 * stride))
    {
        let (top, bottom) = pair.split_at(stride);
        let (blocks, rest) = out.as_chunks_mut::<DOWNSCALE_BLOCK_PX>();
        let (top_blocks, _) = top.as_chunks::<{ 2 * DOWNSCALE_BLOCK_PX }>();
        let (bottom_blocks, _) = bottom.as_chunks::<{ 2 * DOWNSCALE_BLOCK_PX }>();
        for ((o, t), b) in blocks.iter_mut().zip(top_blocks).zip(bottom_blocks) {
            // Vertical sums first, then each horizontal pair.
            let mut sums = [0u16; 2 * DOWNSCALE_BLOCK_PX];
            for ((s, &tp), &bp) in sums.iter_mut().zip(t).zip(b) {
                *s = u16::from(tp) + u16::from(bp);
            }
            for (k, o) in o.iter_mut().enumerate() {
                *o = box_mean(sums[2 * k] + sums[2 * k + 1]);
            }
        }
        let done = blocks.len() * DOWNSCALE_BLOCK_PX;
        for (x, o) in (done..).zip(rest) {
            let at = |row: &[u8], dx: usize| u16::from(row[2 * x + dx]);
            *o = box_mean(at(top, 0) + at(top, 1) + at(bottom, 0) + at(bottom, 1));
        }
    }
    GrayImage::new(w, h, pixels)
}

/// The rounded mean of four grey levels from their sum.
#[inline]
fn box_mean(sum_of_four: u16) -> u8 {
    // At most (4 · 255 + 2) / 4 = 255.
    ((sum_of_four + 2) >> 2) as u8
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

    #[test]
    fn invert_and_rescale_keep_sizes_and_values() {
        let image = GrayImage::new(4, 2, vec![0, 10, 20, 30, 40, 50, 60, 255]).expect("a size");
        assert_eq!(invert(&image).and_then(|i| invert(&i)), Some(image.clone()));
        let half = downscale_half(&image).expect("a size");
        assert_eq!(half.pixels(), &[25, 91]);
        let double = upscale_double(&image).expect("a size");
        assert_eq!((double.width(), double.height()), (8, 4));
        assert_eq!(double.get(0, 0), 0);
    }

    /// The blocked halving is the 2 × 2 rounded mean at every pixel, for widths that end on
    /// a whole block, inside one, or have no whole block at all, odd or even.
    #[test]
    fn downscale_half_is_the_rounded_two_by_two_mean_at_every_size() {
        let mut state: u32 = 7;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 24) as u8
        };
        for (w, h) in [
            (2, 2),
            (3, 3),
            (31, 4),
            (32, 5),
            (33, 6),
            (64, 7),
            (97, 9),
            (255, 3),
        ] {
            let image = GrayImage::new(w, h, (0..w * h).map(|_| next()).collect()).expect("size");
            let half = downscale_half(&image).expect("a size");
            assert_eq!((half.width(), half.height()), (w / 2, h / 2));
            for y in 0..h / 2 {
                for x in 0..w / 2 {
                    let sum: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .map(|&(dx, dy)| u32::from(image.get(2 * x + dx, 2 * y + dy)))
                        .sum();
                    assert_eq!(
                        u32::from(half.get(x, y)),
                        (sum + 2) / 4,
                        "{w}x{h} at ({x}, {y})"
                    );
                }
            }
        }
    }

    /// The integer doubling is the rounded bilinear sample at the doubled pixel centres,
    /// pixel for pixel (the definition it replaced), on odd, even and one-pixel sizes.
    #[test]
    fn upscale_double_is_the_rounded_bilinear_sample_exactly() {
        for (w, h) in [(1, 1), (1, 5), (6, 1), (2, 2), (7, 4), (31, 17)] {
            let pixels: Vec<u8> = (0..w * h).map(|k| ((k * 97 + k / 3) % 256) as u8).collect();
            let image = GrayImage::new(w, h, pixels).expect("a size");
            let double = upscale_double(&image).expect("a size");
            let (max_u, max_v) = ((w - 1) as f64, (h - 1) as f64);
            for y in 0..2 * h {
                for x in 0..2 * w {
                    let u = ((x as f64 + 0.5) / 2.0 - 0.5).clamp(0.0, max_u);
                    let v = ((y as f64 + 0.5) / 2.0 - 0.5).clamp(0.0, max_v);
                    let want = image.sample(u, v).expect("inside").round() as u8;
                    assert_eq!(double.get(x, y), want, "{w} × {h} at ({x}, {y})");
                }
            }
        }
    }
}
