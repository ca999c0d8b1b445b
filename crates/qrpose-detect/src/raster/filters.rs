//! Pixel-wise and resampling filters on [`GrayImage`], for the second passes of `auto`
//! ([`crate::find_candidates`]): [`stretch_contrast`], [`invert`], [`upscale_double`] and
//! [`downscale_half`] (the Gaussian blurs are in `blur`).

use crate::raster::GrayImage;

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
    // One entry per grey level: the same value as computing it per pixel, without a
    // float multiply and a call to `round` per pixel.
    let mut lut = [0u8; 256];
    for (value, out) in lut.iter_mut().enumerate() {
        *out = (((value as f64 - lo as f64) * scale).clamp(0.0, 255.0)).round() as u8;
    }
    let pixels = image
        .pixels()
        .iter()
        .map(|&p| lut[usize::from(p)])
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
