//! rxing's `HybridBinarizer` (ZXing's local block thresholding), bit for bit, faster
//! ([`local_binarizer`]): rxing sets the matrix one bit at a time, which was the largest
//! share of its read of a 1280 × 720 frame (3.3 ms with rxing's binariser, about 1.6 ms
//! with this one, one core). A test compares the bits with rxing's.

use super::binarizer::{Precomputed, WORD_BITS, pack_flags};
use rxing::LuminanceSource;
use rxing::common::{BitArray, BitMatrix};

/// Side of the blocks of the local binariser, px.
const BLOCK_PX: usize = 8;
/// Side of the window whose blocks set a block's threshold (5 × 5 blocks), px: a module at
/// least this wide can fill the whole window, which is then thresholded against itself.
pub(crate) const LOCAL_WINDOW_PX: usize = 5 * BLOCK_PX;
/// Blocks with at most this grey-level range get a threshold from their neighbours.
const MIN_DYNAMIC_RANGE: u8 = 24;

/// rxing's `HybridBinarizer` (ZXing's local block thresholding), bit for bit: a black point
/// per 8 × 8 block, each block thresholded at the mean black point of the 5 × 5 blocks
/// around it. rxing sets the matrix one bit at a time; here each block row's thresholds are
/// spread over the pixel columns once (the largest threshold of the blocks covering a pixel:
/// the last block of a row or column overlaps its neighbour, and a pixel that either block
/// calls black is black), and each pixel row is compared and packed a word at a time. Row
/// queries (1-D readers) and images under 40 px go to the global-histogram binariser, as in
/// rxing.
pub(crate) fn local_binarizer<LS: LuminanceSource>(source: LS) -> Precomputed<LS> {
    Precomputed::new(source, local_threshold)
}

/// The black points of the blocks, row-major (`sub_w` × `sub_h`).
fn black_points(lum: &[u8], width: usize, height: usize, sub_w: usize, sub_h: usize) -> Vec<u32> {
    let (max_x, max_y) = (width - BLOCK_PX, height - BLOCK_PX);
    let mut points = vec![0u32; sub_w * sub_h];
    // Per pixel column of a block row: sum, min and max over its 8 pixel rows (a whole row
    // at a time, which vectorises), then per block over its 8 columns.
    let (mut sums, mut mins, mut maxs) = (vec![0u16; width], vec![0u8; width], vec![0u8; width]);
    for by in 0..sub_h {
        let y0 = (by * BLOCK_PX).min(max_y);
        sums.fill(0);
        mins.fill(u8::MAX);
        maxs.fill(u8::MIN);
        for row in lum[y0 * width..].chunks_exact(width).take(BLOCK_PX) {
            for (((s, lo), hi), &p) in sums.iter_mut().zip(&mut mins).zip(&mut maxs).zip(row) {
                *s += u16::from(p);
                *lo = (*lo).min(p);
                *hi = (*hi).max(p);
            }
        }
        for bx in 0..sub_w {
            let x0 = (bx * BLOCK_PX).min(max_x);
            let columns = x0..x0 + BLOCK_PX;
            let sum: u32 = sums[columns.clone()].iter().map(|&s| u32::from(s)).sum();
            let min = mins[columns.clone()].iter().fold(u8::MAX, |a, &b| a.min(b));
            let max = maxs[columns].iter().fold(u8::MIN, |a, &b| a.max(b));
            // rxing stops tracking min and max once the range exceeds the limit; the test
            // below only asks whether it did, so the full range decides the same.
            let mut average = sum >> 6;
            if max - min <= MIN_DYNAMIC_RANGE {
                average = u32::from(min) / 2;
                if by > 0 && bx > 0 {
                    let neighbours = (points[(by - 1) * sub_w + bx]
                        + 2 * points[by * sub_w + bx - 1]
                        + points[(by - 1) * sub_w + bx - 1])
                        / 4;
                    if u32::from(min) < neighbours {
                        average = neighbours;
                    }
                }
            }
            points[by * sub_w + bx] = average;
        }
    }
    points
}

/// The local-threshold bit matrix; `None` for images under 5 blocks on a side.
fn local_threshold(lum: &[u8], width: usize, height: usize) -> Option<BitMatrix> {
    if width < 5 * BLOCK_PX || height < 5 * BLOCK_PX || lum.len() != width * height {
        return None;
    }
    let (sub_h, max_y) = (height.div_ceil(BLOCK_PX), height - BLOCK_PX);
    let row_thresholds = block_row_thresholds(lum, width, height);
    let last_block_row = row_thresholds.chunks_exact(width).last()?;
    let mut matrix =
        BitMatrix::new(u32::try_from(width).ok()?, u32::try_from(height).ok()?).ok()?;
    let mut bits = BitArray::with_size(width);
    let mut overlap = vec![0u8; width];
    // 0/1 per pixel, padded with zeros to whole words.
    let mut black = vec![0u8; width.next_multiple_of(WORD_BITS)];
    for (y, lum_row) in lum.chunks_exact(width).enumerate() {
        let by = y / BLOCK_PX;
        let mut t_row = row_thresholds.get(by * width..(by + 1) * width)?;
        if y >= max_y && by + 1 < sub_h {
            // Rows that the last block row shares with its neighbour.
            for ((o, &a), &b) in overlap.iter_mut().zip(t_row).zip(last_block_row) {
                *o = a.max(b);
            }
            t_row = &overlap;
        }
        for ((b, &p), &t) in black.iter_mut().zip(lum_row).zip(t_row) {
            *b = u8::from(p <= t);
        }
        for (w, flags) in black.chunks_exact(WORD_BITS).enumerate() {
            bits.setBulk(w * WORD_BITS, pack_flags(flags));
        }
        matrix.setRow(u32::try_from(y).ok()?, &bits);
    }
    Some(matrix)
}

/// Each block row's threshold per pixel column (`sub_h` rows of `width`): the mean black
/// point of the 5 × 5 blocks around each block, the larger of two where the last block
/// column overlaps its neighbour (a pixel that either block calls black is black).
/// Each block row sums its five rows of black points per block column once, then slides a
/// five-column window along them (10 additions a block instead of 25).
fn block_row_thresholds(lum: &[u8], width: usize, height: usize) -> Vec<u8> {
    let (sub_w, sub_h) = (width.div_ceil(BLOCK_PX), height.div_ceil(BLOCK_PX));
    let max_x = width - BLOCK_PX;
    let points = black_points(lum, width, height, sub_w, sub_h);
    let mut thresholds = vec![0u8; sub_h * width];
    let (mut columns, mut windows) = (vec![0u32; sub_w], vec![0u32; sub_w]);
    for (by, row) in thresholds.chunks_exact_mut(width).enumerate() {
        let top = by.clamp(2, sub_h - 3);
        columns.fill(0);
        for points_row in points[(top - 2) * sub_w..(top + 3) * sub_w].chunks_exact(sub_w) {
            for (c, &p) in columns.iter_mut().zip(points_row) {
                *c += p;
            }
        }
        five_column_sums(&columns, &mut windows);
        for bx in 0..sub_w {
            let x0 = (bx * BLOCK_PX).min(max_x);
            let sum = windows[bx.clamp(2, sub_w - 3)];
            // Black points are grey levels, so is their mean; were one larger, every pixel
            // would be at or below it, as at 255.
            let t = u8::try_from(sum / 25).unwrap_or(u8::MAX);
            for v in &mut row[x0..x0 + BLOCK_PX] {
                *v = (*v).max(t);
            }
        }
    }
    thresholds
}

/// `windows[c]` = `columns[c − 2] + … + columns[c + 2]` for every c with a whole window
/// (2 ..= len − 3; the others are left alone), by a running sum.
fn five_column_sums(columns: &[u32], windows: &mut [u32]) {
    let Some(mut run) = columns.get(..5).map(|first| first.iter().sum::<u32>()) else {
        return;
    };
    for (c, w) in windows
        .iter_mut()
        .enumerate()
        .take(columns.len() - 2)
        .skip(2)
    {
        if c > 2 {
            run = run + columns[c + 2] - columns[c - 3];
        }
        *w = run;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rxing::common::HybridBinarizer;
    use rxing::{Binarizer, Luma8Source};

    /// A textured, unevenly lit image with flat patches (the neighbour rule) and sizes that
    /// are not multiples of the block (the overlapping last blocks).
    fn test_image(width: usize, height: usize) -> Vec<u8> {
        (0..width * height)
            .map(|k| {
                let (x, y) = (k % width, k / width);
                if (x / 13 + y / 17) % 5 == 0 {
                    return u8::try_from(60 + (x + y) % 7).unwrap_or(0);
                }
                let v = (x * 37 + y * 91 + (x / 5) * (y / 3) * 13) % 251;
                u8::try_from((v + x / 4) % 256).unwrap_or(0)
            })
            .collect()
    }

    #[test]
    fn local_binarizer_matches_rxings_hybrid_bit_for_bit() {
        for (w, h) in [
            (64, 48),
            (101, 77),
            (640, 360),
            (333, 517),
            (39, 80),
            (40, 40),
            (41, 47),
        ] {
            let pixels = test_image(w, h);
            let (wu, hu) = (u32::try_from(w).unwrap_or(0), u32::try_from(h).unwrap_or(0));
            let ours =
                local_binarizer(Luma8Source::new_with_slice(&pixels, wu, hu).expect("source"));
            let theirs =
                HybridBinarizer::new(Luma8Source::new_with_slice(&pixels, wu, hu).expect("source"));
            let (a, b) = (
                ours.get_black_matrix().expect("ours"),
                theirs.get_black_matrix().expect("theirs"),
            );
            for y in 0..hu {
                for x in 0..wu {
                    assert_eq!(a.get(x, y), b.get(x, y), "{w} × {h} at ({x}, {y})");
                }
            }
        }
    }
}
