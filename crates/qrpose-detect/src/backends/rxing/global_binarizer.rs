//! rxing's global-histogram binariser, bit for bit, faster ([`global_binarizer`]): one black
//! point for the whole image from the histogram of four sampled rows, as rxing's
//! `GlobalHistogramBinarizer`, but the image is thresholded a row at a time and packed a
//! word at a time, where rxing sets the matrix one bit at a time (the larger part of its
//! time on `auto`'s half-scale and crop reads). A test compares the bits with rxing's.

use super::binarizer::{WORD_BITS, pack_flags};
use crate::backends::rxing::binarizer::Precomputed;
use rxing::LuminanceSource;
use rxing::common::{BitArray, BitMatrix};

/// Bits per histogram bucket index (32 buckets), as in rxing.
const LUMINANCE_BITS: usize = 5;
/// Grey level to bucket: a shift by this many bits.
const LUMINANCE_SHIFT: usize = 8 - LUMINANCE_BITS;
/// Histogram buckets.
const LUMINANCE_BUCKETS: usize = 1 << LUMINANCE_BITS;

/// rxing's `GlobalHistogramBinarizer` with the bit matrix built at once.
pub(crate) fn global_binarizer<LS: LuminanceSource>(source: LS) -> Precomputed<LS> {
    Precomputed::new(source, global_threshold)
}

/// The histogram of rows `height · k / 5` (k = 1..4), columns `width / 5 .. 4 width / 5`.
fn sampled_histogram(lum: &[u8], width: usize, height: usize) -> [u32; LUMINANCE_BUCKETS] {
    let mut buckets = [0u32; LUMINANCE_BUCKETS];
    for k in 1..5 {
        let start = height * k / 5 * width;
        let row = lum
            .get(start + width / 5..start + width * 4 / 5)
            .unwrap_or_default();
        for &p in row {
            buckets[usize::from(p >> LUMINANCE_SHIFT)] += 1;
        }
    }
    buckets
}

/// rxing's black point: the valley between the two main peaks of the histogram, nearer the
/// light one; `None` when the peaks are too close (too little contrast), where rxing fails.
// The same integer arithmetic as rxing's (scores of at most a few hundred million).
#[allow(clippy::cast_possible_wrap)]
fn estimate_black_point(buckets: &[u32; LUMINANCE_BUCKETS]) -> Option<u32> {
    let (mut first_peak, mut first_peak_size, mut max_count) = (0usize, 0u32, 0u32);
    for (x, &b) in buckets.iter().enumerate() {
        if b > first_peak_size {
            (first_peak, first_peak_size) = (x, b);
        }
        max_count = max_count.max(b);
    }
    let (mut second_peak, mut second_peak_score) = (0usize, 0u32);
    for (x, &b) in buckets.iter().enumerate() {
        let d = u32::try_from(x.abs_diff(first_peak)).ok()?;
        let score = b.wrapping_mul(d).wrapping_mul(d);
        if score > second_peak_score {
            (second_peak, second_peak_score) = (x, score);
        }
    }
    if first_peak > second_peak {
        std::mem::swap(&mut first_peak, &mut second_peak);
    }
    if second_peak - first_peak <= LUMINANCE_BUCKETS / 16 {
        return None;
    }
    let (first, second) = (first_peak as isize, second_peak as isize);
    let (mut best_valley, mut best_score) = (second - 1, -1i32);
    for x in (first + 1..=second).rev() {
        let from_first = x - first;
        let count = buckets[x.unsigned_abs()];
        let score = from_first * from_first * (second - x) * (max_count - count) as isize;
        if score as i32 > best_score {
            (best_valley, best_score) = (x, score as i32);
        }
    }
    u32::try_from(best_valley)
        .ok()
        .map(|v| v << LUMINANCE_SHIFT)
}

/// The global-threshold bit matrix (black where the grey level is below the black point);
/// `None` where rxing's binariser fails (too little contrast, or an empty image).
pub(crate) fn global_threshold(lum: &[u8], width: usize, height: usize) -> Option<BitMatrix> {
    if width == 0 || height == 0 || lum.len() != width * height {
        return None;
    }
    let black_point = estimate_black_point(&sampled_histogram(lum, width, height))?;
    let mut matrix =
        BitMatrix::new(u32::try_from(width).ok()?, u32::try_from(height).ok()?).ok()?;
    let mut bits = BitArray::with_size(width);
    // 0/1 per pixel, padded with zeros to whole words.
    let mut black = vec![0u8; width.next_multiple_of(WORD_BITS)];
    for (y, row) in lum.chunks_exact(width).enumerate() {
        for (b, &p) in black.iter_mut().zip(row) {
            *b = u8::from(u32::from(p) < black_point);
        }
        for (w, flags) in black.chunks_exact(WORD_BITS).enumerate() {
            bits.setBulk(w * WORD_BITS, pack_flags(flags));
        }
        matrix.setRow(u32::try_from(y).ok()?, &bits);
    }
    Some(matrix)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rxing::common::GlobalHistogramBinarizer;
    use rxing::{Binarizer, Luma8Source};

    /// A textured, unevenly lit image (two grey populations), or (`flat`) a black one, where
    /// no black point is found.
    fn test_image(width: usize, height: usize, flat: bool) -> Vec<u8> {
        (0..width * height)
            .map(|k| {
                let (x, y) = (k % width, k / width);
                if flat {
                    return u8::try_from((x + y) % 3).unwrap_or(0);
                }
                let dark = (x / 7 + y / 5 + (x * y) / 97) % 3 == 0;
                let base = if dark { 40 } else { 190 };
                u8::try_from(base + (x * 13 + y * 29) % 50 + x / 40).unwrap_or(u8::MAX)
            })
            .collect()
    }

    #[test]
    fn global_binarizer_matches_rxings_bit_for_bit() {
        for (w, h, flat) in [
            (64, 48, false),
            (101, 77, false),
            (640, 360, false),
            (333, 517, false),
            (39, 80, false),
            (120, 90, true),
        ] {
            let pixels = test_image(w, h, flat);
            let (wu, hu) = (u32::try_from(w).unwrap_or(0), u32::try_from(h).unwrap_or(0));
            let source = || Luma8Source::new_with_slice(&pixels, wu, hu).expect("source");
            let ours = global_binarizer(source());
            let theirs = GlobalHistogramBinarizer::new(source());
            match (ours.get_black_matrix(), theirs.get_black_matrix()) {
                (Ok(a), Ok(b)) => {
                    assert!(!flat, "{w} × {h}: the flat image has no black point");
                    for y in 0..hu {
                        for x in 0..wu {
                            assert_eq!(a.get(x, y), b.get(x, y), "{w} × {h} at ({x}, {y})");
                        }
                    }
                }
                (Err(_), Err(_)) => assert!(flat, "{w} × {h}"),
                _ => panic!("{w} × {h}: one binariser failed, the other did not"),
            }
        }
    }
}
