//! Step 1½ of `auto` (`balanced`, `thorough`): the sharpened read of the whole frame, its
//! trigger ([`reads_small_codes`]), and the small crops it looks at once more: finder
//! triples it found but could not read, and pairs of lone finder patterns
//! ([`crate::pairs`]) where the third pattern was lost to the blur.

use super::Finds;
use super::UPSCALE_MAX_SIDE_PX;
use super::passes::{
    SHARPEN_AMOUNT, SHARPEN_SIGMA_PX, SecondPass, decoded, double, double_sharpened, read_crop,
};
use crate::budget::PassLog;
use crate::filters::sharpen;
use crate::gray::GrayImage;
use crate::merge::any_decoded;
use crate::merge::shortest_side_px;
use crate::pairs::pair_regions;
use crate::region::{Crop, Region, same_place, unread_regions};
use crate::{Backend, Candidate, detector_for, rxing};
use std::time::Instant;

/// Step 1½ (`balanced`, `thorough`; run after step 2), on frames of at most
/// [`UPSCALE_MAX_SIDE_PX`], when step 1 found nothing at all (neither a symbol nor a
/// finder-pattern triple) or when two codes or more were read, one of at most
/// [`SHARPENED_TRIGGER_MAX_PX_PER_MODULE`] px per module ([`reads_small_codes`]): rxing on
/// an unsharp-masked copy ([`SHARPEN_SIGMA_PX`], [`SHARPEN_AMOUNT`]). Small codes under
/// blur (about 2-3 px per module, blur σ ≈ 1 px) lose the light ring of their finder
/// patterns to the binariser, so step 1 sees no triple and step 2 no region; sharpening
/// gives the ring back. The triples it finds but cannot read are not made regions for step
/// 2 (on textured frames without a code the sharpened noise yields spurious triples, whose
/// crops would take step 2's passes up to the deadline): the small ones among them get one
/// double-scale sharpened read of their crop, at most [`SHARPENED_REGIONS_MAX`] of them;
/// then so do the places of lone finder-pattern pairs ([`pair_regions`]) that no such
/// triple covers, at most [`SHARPENED_PAIRS_MAX`]. A frame with no finder-like structure
/// pays the sharpened read once.
pub(super) fn find_sharpened(finds: &mut Finds<'_>, log: &mut PassLog) {
    let image = finds.image;
    if image.width().max(image.height()) > UPSCALE_MAX_SIDE_PX || !log.may_continue() {
        return;
    }
    let started = Instant::now();
    let Some(sharp) = sharpen(image, SHARPEN_SIGMA_PX, SHARPEN_AMOUNT) else {
        return;
    };
    let (read, regions, patterns) = log.run_since(
        started,
        "rxing sharpened",
        |r: &(Vec<Candidate>, Vec<Region>, _)| decoded(&r.0),
        || rxing::RxingDetector::hybrid().detect_with_patterns(&sharp),
    );
    finds.add(read);
    drop(sharp);
    let small = regions
        .into_iter()
        .filter(|r| (r.hi_u - r.lo_u).max(r.hi_v - r.lo_v) <= SHARPENED_REGION_MAX_SIDE_PX);
    let triples: Vec<Region> = unread_regions(small.collect(), &finds.found)
        .into_iter()
        .take(SHARPENED_REGIONS_MAX)
        .collect();
    if !look_once_more(finds, &triples, "sharpened region", log, |_| None) {
        return;
    }
    let pairs: Vec<Region> = unread_regions(pair_regions(&patterns, &finds.found), &finds.found)
        .into_iter()
        .filter(|p| !triples.iter().any(|t| same_place(t, p)))
        .take(SHARPENED_PAIRS_MAX)
        .collect();
    look_once_more(finds, &pairs, "sharpened pair", log, |crop| {
        double(crop, detector_for(Backend::Rxing).ok())
    });
}

/// A double-scale sharpened read of each region's crop, logged as `name K double
/// sharpened`, then, where that read nothing, the pass that `then` makes of the crop, if
/// any; `false` when the deadline stopped it.
fn look_once_more(
    finds: &mut Finds<'_>,
    regions: &[Region],
    name: &str,
    log: &mut PassLog,
    then: impl for<'a> Fn(&'a GrayImage) -> Option<SecondPass<'a>>,
) -> bool {
    for (k, region) in regions.iter().enumerate() {
        let Some(crop) = Crop::of_region(finds.image, region) else {
            continue;
        };
        let Some(pixels) = crop.image.as_ref() else {
            continue;
        };
        let first = double_sharpened(pixels, detector_for(Backend::Rxing).ok());
        for pass in [first, then(pixels)].into_iter().flatten() {
            let Some(read) = pass.run(&format!("{name} {k} "), log, |d, variant, scale| {
                read_crop(&crop, d, variant, scale)
            }) else {
                return false;
            };
            let done = any_decoded(&read);
            finds.add(read);
            if done {
                break;
            }
        }
    }
    true
}

/// A frame in which a code of at most this many px per module was read (its shortest side
/// over its module count) also gets the sharpened read of [`find_sharpened`]. That read is
/// for codes of 2-3 px per module, whose finder rings blur away; a code of the same printed
/// size twice as far away as one read at 6 px per module is at 3, so a frame that shows
/// codes at this scale is one where such codes are likely, next to the ones read (a shelf
/// or a wall of labels at several distances). Frames of larger codes only do not pay for
/// it, and frames with no code pay nothing more than before. Measured 2026-11-24: on the
/// rendered multi-code frames of issue 12 (2-6 codes, 1280 × 720) reading every frame's
/// sharpened copy doubled `balanced`'s time and read 14 more codes (10 of ≥ 40 px); this
/// trigger reads 13 of them (all 10), while on the BoofCV development photos (one or a few
/// codes, mostly at more px per module) 34 more of 272 photos pay the read (68 with those
/// where nothing was found), where reading every frame ≤ 1920 px meant 150.
pub const SHARPENED_TRIGGER_MAX_PX_PER_MODULE: f64 = 6.0;

/// The small-code trigger of [`find_sharpened`] also wants this many codes read: a frame
/// showing one code is a robot camera's usual frame, whose latency is that of the first
/// reads (the sharpened read of a 1280 × 720 frame, 5 ms, would more than double it:
/// `docs/detection.md`, Speed), while two or more codes make a shelf or a wall of labels,
/// where codes the first reads miss are likely.
pub const SHARPENED_TRIGGER_MIN_CODES: usize = 2;

/// Whether `found` holds at least [`SHARPENED_TRIGGER_MIN_CODES`] decoded codes, one of
/// them of at most [`SHARPENED_TRIGGER_MAX_PX_PER_MODULE`] px per module. A code whose
/// module count is unknown counts as a version 1 code (21 modules, the fewest, so the most
/// px per module: the trigger errs towards not firing).
pub(super) fn reads_small_codes(found: &[Candidate]) -> bool {
    let decoded = || found.iter().filter(|c| c.payload.is_some());
    decoded().count() >= SHARPENED_TRIGGER_MIN_CODES
        && decoded().any(|c| {
            let modules = c.module_count.unwrap_or(MIN_MODULE_COUNT) as f64;
            shortest_side_px(&c.corners_px) <= SHARPENED_TRIGGER_MAX_PX_PER_MODULE * modules
        })
}

/// Modules per side of the smallest QR code (version 1).
const MIN_MODULE_COUNT: usize = 21;

/// Finder-pattern triples found only on the sharpened copy ([`find_sharpened`]) get one
/// more look, a double-scale sharpened read of their crop, when their box is at most this
/// long (px): the pass is there for small codes, and the bound keeps spurious triples in
/// the texture of a frame without a code from costing more than a few small reads.
pub const SHARPENED_REGION_MAX_SIDE_PX: f64 = 160.0;
/// At most this many such triples get that look.
pub const SHARPENED_REGIONS_MAX: usize = 4;
/// At most this many places of lone finder-pattern pairs found on the sharpened copy get
/// that look too (after the triples, and only where no triple looked).
pub const SHARPENED_PAIRS_MAX: usize = 2;
