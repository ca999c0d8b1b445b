//! The `auto` strategy of [`crate::find_candidates`], bounded by a [`crate::Budget`].
//!
//! 1. **Find** (every effort): rxing reads the whole frame at full resolution, where small
//!    codes are, and (not `fast`) at half scale, where codes that fill the frame, moiré on
//!    screens and blur read better; a zxing-cpp build also reads it with zxing-cpp (first,
//!    but merged in only after every other pass, which then runs as in the default build:
//!    that build reads all the default build reads, and more). Every
//!    symbol is kept, however many (a shelf shows dozens), and every finder-pattern triple
//!    that did not read becomes a [`Region`]. At `balanced`, a full-resolution read that
//!    decoded codes and left no finder pattern or triple unexplained ends step 1. The
//!    reduced levels skip, unsampled, the triples whose finder patterns all lie in codes
//!    read already (a finder pattern belongs to one code): a shelf of 60 codes is not
//!    decoded again at half scale.
//!
//!    **Evidence** ([`Evidence`], `balanced`): on a frame of more than
//!    [`WHOLE_FRAME_MAX_PIXELS`], what step 1 saw decides what follows. A frame where it saw
//!    no symbol, no triple and no finder pattern gets none of the passes below, only the
//!    sharpened reads of the crops around its busiest tiles ([`find_sharpened_tiles`]), and
//!    stops. A smaller frame costs what a crop does and gets them, evidence or not.
//!
//!    When step 1 located nothing (no symbol, no triple; at `balanced`, on a frame of more
//!    than [`WHOLE_FRAME_MAX_PIXELS`], with a finder pattern seen), or when steps 1 and 2
//!    read two codes or more, one of at most
//!    [`sharpened::SHARPENED_TRIGGER_MAX_PX_PER_MODULE`] px per module, `balanced` and
//!    `thorough` read an unsharp-masked copy of frames up to [`UPSCALE_MAX_SIDE_PX`] once
//!    more ([`find_sharpened`], after step 2): small codes under blur lose their finder
//!    patterns' light ring to the binariser; small triples found only there, and the places
//!    of pairs of lone finder patterns found there ([`crate::search::pairs`]), get one double-scale
//!    sharpened read of their crop, then, for crops of at most [`passes::QUAD_MAX_SIDE_PX`],
//!    a quadruple-scale sharpened one. In a frame where a code was read, small finder
//!    patterns of the full-resolution read that no code used get the same crop reads
//!    ([`sharpened::find_lone`]). Symbols those crop reads locate but cannot decode are
//!    read again through their module grid ([`crate::search::reread()`]) and dropped if that fails.
//! 2. **Look closer** (`balanced`, `thorough`): only where a region is, never on the whole
//!    frame: a crop around it (halved while its finder patterns are
//!    [`REGION_HALVE_FINDER_PX`] or wider) goes through the other binariser, rqrr, and the
//!    image variants of [`crate::raster`] (global histogram, denoised, contrast-stretched,
//!    sharpened; double scale on crops of at most [`REGION_DOUBLE_MAX_SIDE_PX`]) until it
//!    reads. A frame with nothing code-like costs the
//!    reads of step 1 and the tile probes, nothing more.
//! 3. **Everything** (`thorough`, and `balanced` on a frame of at most
//!    [`WHOLE_FRAME_MAX_PIXELS`] where nothing was read): every backend and every variant on
//!    the whole frame, as long as the deadline allows (rqrr on frames of at most
//!    [`RQRR_WHOLE_FRAME_MAX_PIXELS`]).
//!
//! Before every pass after the first the deadline is checked ([`PassLog`]); symbols found on
//! the way are re-read through their module grid and merged ([`crate::search::merge_candidates`]).

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use crate::backends::rqrr;
use crate::backends::{auto_order, detector_for};
use crate::budget::{Effort, PassLog};
use crate::raster::GrayImage;
use crate::raster::downscale_half;
use crate::search::merge::merge_candidates;
use crate::search::merge::{any_decoded, reread_undecoded, same_symbol};
use crate::search::pairs::FinderPattern;
use crate::search::region::{Crop, Region, unread_regions};
use crate::{Backend, Candidate, Detector};
use qrpose_core::geometry::frames::PixelPoint;
use std::borrow::Cow;

mod find;
pub(in crate::search) mod passes;
mod sharpened;
pub(crate) use find::HALF_SCALE_FIRST_MIN_SIDE_PX;
use find::{find, precise};
use passes::{decoded, look_closer, read_crop, rescale, variants};
use sharpened::{find_lone, find_sharpened, find_sharpened_tiles, reads_small_codes};

/// Images up to this many px on their longer side get a double-scale second pass (the last
/// one: four times the pixels). Codes of 2-3 px per module under heavy blur, which every
/// backend misses at their own size, are found there.
pub(crate) const UPSCALE_MAX_SIDE_PX: usize = 1920;

/// rqrr searches the whole frame only up to this many pixels (thorough). Its grid search
/// cannot be interrupted and grows with the number of finder-like blobs, not only with the
/// pixels: 0.1-0.2 s on a 12 MP photo of one code, but 3 s on a 12 MP shelf photo with 55
/// codes and 43 s on the same shelf at 49 MP (measured, docs/detection.md), which no deadline
/// could stop. On larger frames rqrr still reads every region's crop.
pub(crate) const RQRR_WHOLE_FRAME_MAX_PIXELS: usize = 4_000_000;

/// What the passes so far have found.
struct Finds<'a> {
    image: &'a GrayImage,
    found: Vec<Candidate>,
    regions: Vec<Region>,
    /// Corners of undecoded candidates already re-read.
    tried: Vec<[PixelPoint; 4]>,
    /// Finder patterns of the full-resolution read that no decoded symbol used.
    patterns: Vec<FinderPattern>,
    /// A zxing-cpp build's read of the whole frame, merged in after every other pass: those
    /// then run exactly as in the default build (what they skip, and whether the sharpened
    /// read and step 3 run, depends on what was found), so this build reads everything the
    /// default build reads, and what zxing-cpp reads besides. Where both found a symbol,
    /// zxing-cpp's candidate is the one kept, as when its read was merged first.
    aside: Vec<Candidate>,
}

impl Finds<'_> {
    /// Re-reads the undecoded of `new` through their module grid (a pass of its own in
    /// `log`, `re-read`, when one is new) and merges them in.
    fn add(&mut self, mut new: Vec<Candidate>, log: &mut PassLog) {
        let untried = new
            .iter()
            .any(|c| c.payload.is_none() && !self.tried.contains(&c.corners_px));
        if untried {
            let before = decoded(&new);
            let (image, tried) = (self.image, &mut self.tried);
            new = log.run(
                "re-read",
                |v: &Vec<Candidate>| decoded(v).saturating_sub(before),
                || {
                    reread_undecoded(image, &mut new, tried);
                    new
                },
            );
        }
        merge_candidates(&mut self.found, new);
    }
}

/// Images of at most this many pixels are read by `balanced` as one crop: every pass runs
/// on them whatever step 1 saw (no [`Evidence`] gate), and where nothing was read they get
/// step 3 (every backend and variant on the whole frame) too. On a small frame that costs
/// what a crop does, and small, low-resolution photos are where the variants read what the
/// first reads miss (light-on-dark codes, which show step 1 no finder pattern, among them:
/// docs/measurements/detection.md, 2026-11-28).
pub(crate) const WHOLE_FRAME_MAX_PIXELS: usize = 400_000;

/// A region's crop whose finder patterns are this wide or wider (16 px per module) is
/// halved before step 2 reads it, until they are narrower: every pass over a large code's
/// crop (a triple of the small level of a 12 MP photo makes crops of millions of pixels)
/// then costs a quarter or less, and 8-16 px per module still read.
pub(crate) const REGION_HALVE_FINDER_PX: f64 = 112.0;
/// Step 2 reads a region's crop at double scale (plain and sharpened) only when the crop, as
/// read (after [`region_reduction`]), is at most this long on its longer side, px: the
/// doubled copy is then at most 1280 px. On the development photos, zxing-cpp's images and
/// the multi-code frames those reads decoded a code not read before only on crops of at
/// most 416 px; on the development photos, crops longer than 640 px took 84 % of their
/// time (20-70 ms a crop on 12 MP photos, most of the time of the photos over 150 ms:
/// docs/measurements/detection.md, 2026-11-28).
pub(crate) const REGION_DOUBLE_MAX_SIDE_PX: usize = 640;

/// How many times a region's crop is halved before step 2 reads it (a power of two; 1 for a
/// region whose finder size is unknown).
fn region_reduction(finder_px: f64) -> usize {
    let mut reduction = 1;
    while finder_px / reduction as f64 >= REGION_HALVE_FINDER_PX && reduction < 64 {
        reduction *= 2;
    }
    reduction
}

/// What the whole-frame reads of step 1 saw of codes: the evidence that decides whether
/// `balanced` looks any further.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Evidence {
    /// Symbols decoded (or found undecoded) so far by the default build's reads (a zxing-cpp
    /// build's own read is set aside: its other passes run as the default build's do).
    pub(crate) symbols: usize,
    /// Finder-pattern triples that did not read, at any level (the regions of step 2).
    pub(crate) triples: usize,
    /// Finder patterns of the full-resolution read that no decoded symbol used.
    pub(crate) patterns: usize,
}

impl Evidence {
    fn of(finds: &Finds<'_>) -> Self {
        Self {
            symbols: finds.found.len(),
            triples: finds.regions.len(),
            patterns: finds.patterns.len(),
        }
    }

    /// Whether anything code-like was seen: a symbol, a triple or a lone finder pattern.
    /// Most frames without a code show none of them (docs/measurements/detection.md,
    /// 2026-11-28).
    pub(crate) fn any(self) -> bool {
        self.symbols + self.triples + self.patterns > 0
    }

    /// Nothing located: no symbol and no triple (the sharpened read's first trigger, with
    /// finder patterns seen).
    fn unlocated(self) -> bool {
        self.symbols == 0 && self.triples == 0
    }
}

/// Step 2: more passes on each unread region's crop, until it reads or the deadline comes.
/// The crop of a region of large finder patterns is read halved ([`region_reduction`]);
/// what it decodes there is read again at full resolution ([`precise`]).
fn regions(finds: &mut Finds<'_>, best: Backend, log: &mut PassLog) {
    let image = finds.image;
    let regions = unread_regions(std::mem::take(&mut finds.regions), &finds.found);
    for (k, region) in regions.iter().enumerate() {
        let Some(crop) = Crop::of_region(image, region) else {
            continue;
        };
        let Some(full) = crop.image.as_ref() else {
            continue;
        };
        let (mut pixels, mut reduction) = (Cow::Borrowed(full), 1.0);
        for _ in 0..region_reduction(region.finder_px).ilog2() {
            let Some(half) = downscale_half(&pixels) else {
                break;
            };
            (pixels, reduction) = (Cow::Owned(half), 2.0 * reduction);
        }
        for pass in region_passes(&pixels, best) {
            let Some(read) = pass.run(&format!("region {k} "), log, |d, variant, scale| {
                let read = read_crop(&crop, d, variant, scale * reduction);
                if reduction > 1.0 {
                    read.into_iter()
                        .flat_map(|c| match c.payload {
                            Some(_) => precise(image, c),
                            None => vec![c],
                        })
                        .collect()
                } else {
                    read
                }
            }) else {
                return;
            };
            // Done when the crop read a code not read before: a region that also covers a
            // code already read (a triple of two neighbouring codes' finder patterns) is
            // not explained by reading that code again.
            let done = read.iter().any(|c| {
                c.payload.is_some()
                    && !finds
                        .found
                        .iter()
                        .any(|f| f.payload.is_some() && same_symbol(f, c))
            });
            finds.add(read, log);
            if done {
                break;
            }
        }
    }
}

/// The passes of step 2 on a region's crop ([`look_closer`]), but not the negative: a
/// light-on-dark code shows no finder pattern to the reads that make regions, so a region's
/// negative holds one only by chance (it read no code of the benchmark sets:
/// docs/measurements/detection.md, 2026-11-28); nor the double-scale copies of a crop
/// longer than [`REGION_DOUBLE_MAX_SIDE_PX`].
fn region_passes(crop: &GrayImage, best: Backend) -> Vec<passes::SecondPass<'_>> {
    let large = crop.width().max(crop.height()) > REGION_DOUBLE_MAX_SIDE_PX;
    look_closer(crop, best)
        .into_iter()
        .filter(|p| {
            p.name != "inverted" && !(large && matches!(p.name, "double" | "double sharpened"))
        })
        .collect()
}

/// Step 3: every variant, then every other backend (rxing read the frame in step 1), on
/// the whole frame.
fn everything(finds: &mut Finds<'_>, best: Backend, log: &mut PassLog) {
    let image = finds.image;
    for pass in variants(image, best) {
        let Some(read) = pass.run("whole ", log, |detector, variant, scale| {
            let mut more: Vec<Candidate> = detector
                .detect(variant)
                .into_iter()
                .map(|c| rescale(c, scale))
                .collect();
            if scale < 1.0 && !any_decoded(&more) {
                // rqrr finds blurred symbols on the enlarged copy that it cannot read;
                // their refined grids often can be (at full resolution).
                more.extend(
                    rqrr::RqrrDetector
                        .detect(variant)
                        .into_iter()
                        .map(|c| rescale(c, scale)),
                );
            }
            more
        }) else {
            return;
        };
        finds.add(read, log);
    }
    let rqrr_may_search = image.pixels().len() <= RQRR_WHOLE_FRAME_MAX_PIXELS;
    for backend in auto_order()
        .into_iter()
        .filter(|b| *b != Backend::Rxing && (*b != Backend::Rqrr || rqrr_may_search))
    {
        if !log.may_continue() {
            return;
        }
        let Ok(detector) = detector_for(backend) else {
            continue;
        };
        let read = log.run(
            format!("{} full", backend.as_str()),
            |v: &Vec<Candidate>| decoded(v),
            || detector.detect(image),
        );
        finds.add(read, log);
    }
}

/// Every candidate `auto` finds in `image` at `effort` before the deadline of `log` (see
/// the module doc).
pub(crate) fn find_candidates(
    image: &GrayImage,
    effort: Effort,
    log: &mut PassLog,
) -> Vec<Candidate> {
    let Some(&best) = auto_order().first() else {
        return Vec::new();
    };
    let mut finds = Finds {
        image,
        found: Vec::new(),
        regions: Vec::new(),
        tried: Vec::new(),
        patterns: Vec::new(),
        aside: Vec::new(),
    };
    find(&mut finds, effort, best, log);
    let evidence = Evidence::of(&finds);
    // A frame of at most WHOLE_FRAME_MAX_PIXELS costs what a crop does: `balanced` reads
    // it as one, evidence or not. A larger frame whose whole-frame reads saw no sign of a
    // code gets nothing more from `balanced` but the tile probes; `thorough` looks
    // everywhere.
    let small_frame = image.pixels().len() <= WHOLE_FRAME_MAX_PIXELS;
    let everywhere = effort == Effort::Thorough || (effort == Effort::Balanced && small_frame);
    let looks_on = everywhere || (effort == Effort::Balanced && evidence.any());
    if looks_on {
        regions(&mut finds, best, log);
        // Nothing located: the sharpened read is for small blurred codes whose finder
        // patterns lost their light ring, so on a large frame `balanced` wants one
        // pattern seen at least.
        let unlocated = evidence.unlocated() && (everywhere || evidence.patterns > 0);
        if unlocated || reads_small_codes(&finds.found) {
            find_sharpened(&mut finds, log);
        }
        find_lone(&mut finds, log);
    } else if effort == Effort::Balanced {
        find_sharpened_tiles(&mut finds, log);
    }
    let unread_small_frame = small_frame && !any_decoded(&finds.found);
    if effort == Effort::Thorough || (effort == Effort::Balanced && unread_small_frame) {
        everything(&mut finds, best, log);
    }
    // zxing-cpp's symbols first, as its read came first: where both backends found a
    // symbol, its candidate is kept (and refined), the others merged into its list.
    let aside = std::mem::take(&mut finds.aside);
    if !aside.is_empty() {
        let others = std::mem::take(&mut finds.found);
        finds.add(aside, log);
        merge_candidates(&mut finds.found, others);
    }
    finds.found
}

#[cfg(test)]
mod tests;
