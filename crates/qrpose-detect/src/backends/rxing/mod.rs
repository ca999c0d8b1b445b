//! The rxing backend: rxing's port of zxing-cpp's QR reader (`qrcode::cpp_port::QrReader`),
//! multi-symbol, try-harder, on rxing's hybrid (local) binariser, or on its global-histogram
//! one ([`RxingDetector::global_histogram`], for `auto`'s second passes). Corners are whole
//! pixels. The reader's steps are taken one by one (`read`) to keep the module count,
//! which rxing's results drop. rxing lists the corners as TL, TR, BL, BR (checked on
//! rendered ground truth); they are reordered here.
//!
//! The hybrid binariser is rxing's algorithm reimplemented ([`local_binarizer`]): the same
//! bits (a test compares them), faster: rxing sets the matrix one bit at a time, which was
//! the largest share of its read of a 1280 × 720 frame (3.3 ms with rxing's binariser,
//! about 1.6 ms with this one, one core). The global-histogram binariser is rxing's too,
//! rewritten the same way ([`global_binarizer`](global_binarizer::global_binarizer)).

pub mod binarizer;
mod finder_scan;
pub mod global_binarizer;

use crate::backends::{Backend, Candidate, Detector};
use crate::contain::contain;
use crate::raster::GrayImage;
use crate::search::pairs::FinderPattern;
use crate::search::region::Region;
use binarizer::Precomputed;
use finder_scan::find_finder_patterns;
use global_binarizer::global_binarizer;
use qrpose_core::geometry::frames::PixelPoint;
use rxing::common::cpp_essentials::concentric_finder::ConcentricPattern;
use rxing::common::{BitArray, BitMatrix, DetectorRXingResult};
use rxing::qrcode::cpp_port::decoder::Decode;
use rxing::qrcode::cpp_port::detector::{FinderPatternSet, GenerateFinderPatternSets, SampleQR};
use rxing::qrcode::detector::QRCodeDetectorResult;
use rxing::{BarcodeFormat, Binarizer, Luma8Source, LuminanceSource, Point, RXingResult};

/// rxing behind the [`Detector`] interface.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RxingDetector {
    /// The global-histogram binariser instead of the hybrid one.
    global_histogram: bool,
    /// Triples whose grid was sampled but did not decode come back as undecoded candidates
    /// (their sampled corners and module count), for the re-read through the refined grid.
    located: bool,
}

impl RxingDetector {
    /// On the hybrid (local block) binariser, rxing's default for 2-D codes.
    pub fn hybrid() -> Self {
        Self::default()
    }
    /// The hybrid binariser, returning also the symbols whose grid was sampled but did not
    /// decode (payload `None`): `auto`'s crop reads of small candidates hand them to the
    /// re-read through the refined grid ([`crate::search::reread`]).
    pub fn located() -> Self {
        Self {
            located: true,
            ..Self::default()
        }
    }
    /// On the global-histogram binariser (one threshold per row from the histogram).
    pub fn global_histogram() -> Self {
        Self {
            global_histogram: true,
            ..Self::default()
        }
    }
}

/// What one read found: the symbols it decoded, the regions of finder-pattern triples it
/// could not read, and the finder patterns that no decoded symbol used.
type Read = (Vec<Candidate>, Vec<Region>, Vec<FinderPattern>);

fn detect_unguarded(image: &GrayImage, detector: RxingDetector) -> Read {
    let (Ok(w), Ok(h)) = (u32::try_from(image.width()), u32::try_from(image.height())) else {
        return Read::default();
    };
    let Ok(source) = Luma8Source::new_with_slice(image.pixels(), w, h) else {
        return Read::default();
    };
    if detector.global_histogram {
        read(&global_binarizer(source), detector.located)
    } else {
        read(&local_binarizer(source), detector.located)
    }
}

/// rxing's multi-symbol QR read (`QrReader::decode_multiple_with_hints` with try-harder,
/// QR codes only), step by step through rxing's public parts so that the sampled grid's
/// size, the module count, is kept: the reader's own results drop it. Triples that do not
/// sample or decode are returned as [`Region`]s, where `auto` may look again, and so are
/// the finder patterns that no decoded symbol used (see [`crate::search::pairs`]).
fn read<B: Binarizer>(binarizer: &B, located: bool) -> Read {
    let Ok(binary) = binarizer.get_black_matrix() else {
        return Read::default();
    };
    let mut patterns = find_finder_patterns(binary);
    let mut used: Vec<ConcentricPattern> = Vec::new();
    let mut found = Vec::new();
    let mut unread = Vec::new();
    for set in GenerateFinderPatternSets(&mut patterns) {
        if [set.bl, set.tl, set.tr].iter().any(|p| used.contains(p)) {
            continue;
        }
        let sampled = SampleQR(binary, &set).ok();
        let decoded = sampled
            .as_ref()
            .and_then(|sampled| Decode(sampled.getBits()).ok().filter(|d| d.isValid()));
        let (Some(sampled), Some(decoded)) = (sampled.as_ref(), decoded) else {
            unread.extend(region_of(&set));
            if located {
                found.extend(sampled.as_ref().and_then(undecoded));
            }
            continue;
        };
        used.extend([set.bl, set.tl, set.tr]);
        let module_count = usize::try_from(sampled.getBits().getWidth()).ok();
        let result =
            RXingResult::with_decoder_result(decoded, sampled.getPoints(), BarcodeFormat::QR_CODE);
        let Some(corners_px) = qr_corners(result.getPoints()) else {
            continue;
        };
        found.push(Candidate {
            corners_px,
            payload: Some(result.getRawBytes().to_vec()),
            text: Some(result.getText().to_owned()),
            module_count,
            backend: Backend::Rxing,
        });
    }
    let lone = patterns
        .iter()
        .filter(|p| !used.contains(p))
        .map(|p| FinderPattern {
            centre: PixelPoint::new(f64::from(p.p.x), f64::from(p.p.y)),
            size_px: f64::from(p.size),
        })
        .collect();
    (found, unread, lone)
}

/// A symbol whose grid was sampled but did not decode: its sampled corners (qr order) and
/// module count, no payload.
fn undecoded(sampled: &QRCodeDetectorResult) -> Option<Candidate> {
    Some(Candidate {
        corners_px: qr_corners(sampled.getPoints())?,
        payload: None,
        text: None,
        module_count: usize::try_from(sampled.getBits().getWidth()).ok(),
        backend: Backend::Rxing,
    })
}

/// The corners of a quadrilateral as rxing lists them (top-left, top-right, bottom-left,
/// bottom-right, for decoded and sampled symbols alike) in qr order; `None` when fewer than
/// four.
fn qr_corners(points: &[Point]) -> Option<[PixelPoint; 4]> {
    let corner = |i: usize| {
        points
            .get(i)
            .map(|p| PixelPoint::new(f64::from(p.x), f64::from(p.y)))
    };
    Some([corner(0)?, corner(1)?, corner(3)?, corner(2)?])
}

/// The region of an unread finder-pattern triple.
fn region_of(set: &FinderPatternSet) -> Option<Region> {
    let centre = |p: &ConcentricPattern| PixelPoint::new(f64::from(p.p.x), f64::from(p.p.y));
    let finder_px = f64::from(set.tl.size.max(set.tr.size).max(set.bl.size));
    Region::from_finder_centres(centre(&set.tl), centre(&set.tr), centre(&set.bl), finder_px)
}

/// Side of the blocks of the local binariser, px.
const BLOCK_PX: usize = 8;
/// Blocks with at most this grey-level range get a threshold from their neighbours.
const MIN_DYNAMIC_RANGE: u8 = 24;
/// Bits per word of rxing's bit arrays.
pub(crate) const WORD_BITS: usize = usize::BITS as usize;

/// rxing's `HybridBinarizer` (ZXing's local block thresholding), bit for bit: a black point
/// per 8 × 8 block, each block thresholded at the mean black point of the 5 × 5 blocks
/// around it. rxing sets the matrix one bit at a time; here each block row's thresholds are
/// spread over the pixel columns once (the largest threshold of the blocks covering a pixel:
/// the last block of a row or column overlaps its neighbour, and a pixel that either block
/// calls black is black), and each pixel row is compared and packed a word at a time. Row
/// queries (1-D readers) and images under 40 px go to the global-histogram binariser, as in
/// rxing.
pub fn local_binarizer<LS: LuminanceSource>(source: LS) -> Precomputed<LS> {
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

/// A word of 0/1 bytes as bits (bit k = byte k), eight bytes per multiplication.
pub(crate) fn pack_flags(flags: &[u8]) -> usize {
    flags
        .chunks_exact(8)
        .enumerate()
        .fold(0usize, |acc, (k, eight)| {
            let mut le = [0u8; 8];
            le.copy_from_slice(eight);
            let byte = u64::from_le_bytes(le).wrapping_mul(0x0102_0408_1020_4080) >> 56;
            acc | (usize::try_from(byte).unwrap_or(0) << (8 * k))
        })
}

impl Detector for RxingDetector {
    fn backend(&self) -> Backend {
        Backend::Rxing
    }

    fn detect(&self, image: &GrayImage) -> Vec<Candidate> {
        self.detect_with_regions(image).0
    }
}

impl RxingDetector {
    /// The symbols read in `image`, and the regions of the finder-pattern triples that
    /// could not be read (for `auto`'s further passes).
    #[must_use]
    pub fn detect_with_regions(&self, image: &GrayImage) -> (Vec<Candidate>, Vec<Region>) {
        let (found, regions, _) = self.detect_with_patterns(image);
        (found, regions)
    }

    /// [`Self::detect_with_regions`], and the finder patterns that no decoded symbol used.
    #[must_use]
    pub fn detect_with_patterns(
        &self,
        image: &GrayImage,
    ) -> (Vec<Candidate>, Vec<Region>, Vec<FinderPattern>) {
        contain(|| detect_unguarded(image, *self)).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rxing::common::HybridBinarizer;

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
