//! rxing's finder-pattern search (`FindFinderPatterns` with try-harder, itself ported from
//! zxing-cpp; both Apache-2.0, as this crate), with one change: the run lengths of each
//! scanned row are read from the bit matrix a machine word at a time. rxing copies the row
//! and walks it one bit at a time, which took about a tenth of the whole image path
//! (decode, find, refine) on a 1280 × 720 frame. The patterns found are the same, in the
//! same order (`tests::finds_what_rxing_finds`); the checks of each candidate are rxing's
//! own public functions.

use super::binarizer::WORD_BITS;
use rxing::Point;
use rxing::common::BitMatrix;
use rxing::common::cpp_essentials::{
    ConcentricPattern, FindLeftGuardBy, FixedPattern, IsPattern, LocateConcentricPattern,
    PatternType, PatternView,
};
use rxing::qrcode::cpp_port::detector::FindFinderPatterns;

/// Bars of a finder pattern's cross-section: 1:1:3:1:1.
const BARS: usize = 5;
/// Modules across a finder pattern.
const MODULES: usize = 7;
/// The 1:1:3:1:1 pattern, as rxing defines it.
const PATTERN: FixedPattern<BARS, MODULES, false> = FixedPattern::new([1, 1, 3, 1, 1]);
/// Rows scanned: every third, as rxing and zxing-cpp do when trying harder (a finder's
/// centre is at least 3 px tall at 1 px per module).
const ROW_STEP: usize = 3;

/// The finder patterns of `image`, as `FindFinderPatterns(image, true, 0)` returns them.
/// Rows wider than a run length can count (65 535 px) go to rxing's own search.
pub(crate) fn find_finder_patterns(image: &BitMatrix) -> Vec<ConcentricPattern> {
    let width = usize::try_from(image.getWidth()).unwrap_or(usize::MAX);
    let height = usize::try_from(image.getHeight()).unwrap_or(0);
    if width > usize::from(PatternType::MAX) {
        return FindFinderPatterns(image, true, 0);
    }
    let mut found: Vec<ConcentricPattern> = Vec::new();
    let mut runs: Vec<PatternType> = Vec::new();
    for y in (ROW_STEP - 1..height).step_by(ROW_STEP) {
        let Ok(y_u32) = u32::try_from(y) else {
            break;
        };
        run_lengths(image.getRow(y_u32).getBitArray(), width, &mut runs);
        scan_row(image, &runs, y, &mut found);
    }
    found
}

/// rxing's loop over one row's candidates: each 1:1:3:1:1 window whose centre is not inside
/// a pattern already found is located in two dimensions.
fn scan_row(image: &BitMatrix, runs: &[PatternType], y: usize, found: &mut Vec<ConcentricPattern>) {
    let mut next = PatternView::from_slice(runs);
    while let Ok(window) = find_pattern(next) {
        next = window;
        if !next.isValid() {
            break;
        }
        let x = f32::from(next.pixelsInFront())
            + f32::from(next[0])
            + f32::from(next[1])
            + f32::from(next[2]) / 2.0;
        #[allow(clippy::cast_precision_loss)] // rows are far below 2^24
        let p = Point::new(x, y as f32 + 0.5);
        if !found
            .iter()
            .any(|old| Point::distance(p, old.p) < old.size as f32 / 2.0)
        {
            // 3 for very skewed samples, as in rxing.
            let range = i32::from(next.iter().sum::<PatternType>()) * 3;
            if let Some(pattern) =
                LocateConcentricPattern::<true, BARS, MODULES>(image, &PATTERN.into(), p, range)
            {
                found.push(pattern);
            }
        }
        next.skipPair();
        next.skipPair();
        next.extend();
    }
}

/// rxing's `FindPattern` with no minimum module size: the next window of five bars that
/// passes a quick ratio test and rxing's `IsPattern`.
fn find_pattern(view: PatternView<'_>) -> rxing::common::Result<PatternView<'_>> {
    FindLeftGuardBy::<BARS, _>(view, BARS, |window: &PatternView, space: Option<f32>| {
        // A quick ratio test first; the doubling wraps as rxing's does in a release build.
        let bar = |k: usize| -> PatternType { window[k] };
        if bar(2) < 3 || bar(2) < bar(0).max(bar(4)).wrapping_mul(2) || bar(2) < bar(1).max(bar(3))
        {
            return false;
        }
        IsPattern::<true, BARS, MODULES, false>(window, &PATTERN, space, 0.1, 0.0, 0.0) != 0.0
    })
}

/// The run lengths of a row of `width` bits (bit x of word x / 64, low bit first; set =
/// black), white first, as rxing's pattern rows hold them: a leading white run of 0 when the
/// row starts black, and a trailing white run of 0 when it ends black. `width` must be at
/// most 65 535.
fn run_lengths(words: &[usize], width: usize, runs: &mut Vec<PatternType>) {
    runs.clear();
    let mut x = 0;
    let mut black = false;
    while x < width {
        let end = next_change(words, x, black, width);
        runs.push(PatternType::try_from(end - x).unwrap_or(PatternType::MAX));
        x = end;
        black = !black;
    }
    // `black` is now the colour a next run would have: the last run was black when it is not.
    if x > 0 && !black {
        runs.push(0);
    }
}

/// The first x' ≥ `x` whose bit is not `black`, or `width` when there is none.
fn next_change(words: &[usize], x: usize, black: bool, width: usize) -> usize {
    let mut index = x / WORD_BITS;
    // Bits of the colour sought set, those before x cleared.
    let mut word =
        words.get(index).map_or(0, |&w| seek(w, black)) & (usize::MAX << (x % WORD_BITS));
    loop {
        if word != 0 {
            return (index * WORD_BITS + word.trailing_zeros() as usize).min(width);
        }
        index += 1;
        let Some(&next) = words.get(index) else {
            return width;
        };
        if index * WORD_BITS >= width {
            return width;
        }
        word = seek(next, black);
    }
}

/// A word with the bits of the other colour than `black` set.
fn seek(word: usize, black: bool) -> usize {
    if black { !word } else { word }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backends::rxing::hybrid_binarizer::local_binarizer;
    use rxing::{Binarizer, Luma8Source};

    /// rxing's run lengths, bit by bit.
    fn runs_bit_by_bit(bits: &[bool]) -> Vec<PatternType> {
        let (mut runs, mut black, mut count) = (Vec::new(), false, 0);
        for &b in bits {
            if b != black {
                runs.push(count);
                count = 0;
                black = b;
            }
            count += 1;
        }
        if count != 0 {
            runs.push(count);
        }
        if black {
            runs.push(0);
        }
        runs
    }

    #[test]
    fn run_lengths_match_a_bit_by_bit_count() {
        let mut state: u32 = 11;
        for width in [1usize, 2, 63, 64, 65, 127, 128, 129, 200, 1000] {
            for density in [0u32, 3, 50, 200, 255] {
                let bits: Vec<bool> = (0..width)
                    .map(|_| {
                        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                        (state >> 24) < density
                    })
                    .collect();
                // Padding bits beyond the width are clear, as in rxing's matrices.
                let mut words = vec![0usize; width.div_ceil(WORD_BITS)];
                for (x, _) in bits.iter().enumerate().filter(|(_, b)| **b) {
                    words[x / WORD_BITS] |= 1 << (x % WORD_BITS);
                }
                let mut runs = Vec::new();
                run_lengths(&words, width, &mut runs);
                assert_eq!(
                    runs,
                    runs_bit_by_bit(&bits),
                    "width {width}, density {density}"
                );
            }
        }
    }

    /// Frames with finder patterns of several sizes, at rows and columns that do not
    /// fall on the scan's step, on a textured background.
    fn test_image(width: usize, height: usize) -> Vec<u8> {
        let finder = |x: usize, y: usize, x0: usize, y0: usize, module: usize| {
            let (dx, dy) = (x.checked_sub(x0)? / module, y.checked_sub(y0)? / module);
            // 7 × 7 modules and a light module around them.
            (dx < 9 && dy < 9).then(|| {
                let ring = dx.min(dy).min(8 - dx).min(8 - dy);
                ring == 1 || ring >= 3
            })
        };
        (0..width * height)
            .map(|k| {
                let (x, y) = (k % width, k / width);
                let placed = [
                    (17, 23, 2),
                    (140, 31, 5),
                    (61, 150, 3),
                    (230, 190, 1),
                    (300, 40, 9),
                ];
                for (x0, y0, m) in placed {
                    if let Some(dark) = finder(x, y, x0, y0, m) {
                        return if dark { 20 } else { 230 };
                    }
                }
                u8::try_from((x * 7 + y * 13 + (x / 9) * (y / 5)) % 97 + 100).unwrap_or(0)
            })
            .collect()
    }

    #[test]
    fn finds_what_rxing_finds() {
        for (w, h) in [(400, 260), (401, 259), (64, 64)] {
            let pixels = test_image(w, h);
            let (wu, hu) = (u32::try_from(w).unwrap_or(0), u32::try_from(h).unwrap_or(0));
            let source = Luma8Source::new_with_slice(&pixels, wu, hu).expect("source");
            let binary = local_binarizer(source)
                .get_black_matrix()
                .expect("matrix")
                .clone();
            let ours = find_finder_patterns(&binary);
            let theirs = FindFinderPatterns(&binary, true, 0);
            let centres: Vec<_> = ours.iter().map(|p| (p.p.x, p.p.y, p.size)).collect();
            assert!(w < 100 || ours.len() >= 4, "{w} × {h}: {centres:?}");
            assert_eq!(ours, theirs, "{w} × {h}");
        }
    }

    /// Every photo of a folder (`QRPOSE_FINDER_PHOTOS`, searched recursively for `.jpg` and
    /// `.png`), at full and half scale, through both binarisers: the same patterns as rxing.
    /// Run with `QRPOSE_FINDER_PHOTOS=../shared/data/qr-photos cargo test --release -p
    /// qrpose-detect finds_what_rxing_finds_on_photos -- --ignored`.
    #[test]
    #[ignore = "reads a folder of photos named by QRPOSE_FINDER_PHOTOS"]
    fn finds_what_rxing_finds_on_photos() {
        use crate::backends::rxing::global_binarizer::global_binarizer;
        use crate::decode::{DecodeLimits, decode_gray};
        use crate::raster::downscale_half;
        let root = std::env::var("QRPOSE_FINDER_PHOTOS").expect("QRPOSE_FINDER_PHOTOS");
        let mut stack = vec![std::path::PathBuf::from(root)];
        let (mut photos, mut patterns) = (0, 0);
        while let Some(dir) = stack.pop() {
            for entry in std::fs::read_dir(&dir).expect("a folder").flatten() {
                let path = entry.path();
                if path.is_dir() {
                    stack.push(path);
                    continue;
                }
                let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
                if !["jpg", "jpeg", "png"].contains(&ext.to_ascii_lowercase().as_str()) {
                    continue;
                }
                let bytes = std::fs::read(&path).expect("readable");
                let Ok(full) = decode_gray(&bytes, &DecodeLimits::default()) else {
                    continue;
                };
                photos += 1;
                for image in [Some(full.clone()), downscale_half(&full)]
                    .into_iter()
                    .flatten()
                {
                    let (w, h) = (image.width() as u32, image.height() as u32);
                    let source =
                        || Luma8Source::new_with_slice(image.pixels(), w, h).expect("source");
                    let matrices = [
                        local_binarizer(source()).get_black_matrix().ok().cloned(),
                        global_binarizer(source()).get_black_matrix().ok().cloned(),
                    ];
                    for binary in matrices.into_iter().flatten() {
                        let ours = find_finder_patterns(&binary);
                        patterns += ours.len();
                        assert_eq!(
                            ours,
                            FindFinderPatterns(&binary, true, 0),
                            "{}",
                            path.display()
                        );
                    }
                }
            }
        }
        assert!(photos > 0, "no photos");
        eprintln!("{photos} photos, {patterns} patterns, all as rxing finds them");
    }
}
