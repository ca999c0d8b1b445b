//! Step 1½ of `auto` (`balanced`, `thorough`): the sharpened read of the whole frame, its
//! trigger ([`reads_small_codes`]), and the small crops it looks at once more: finder
//! triples it found but could not read, and pairs of lone finder patterns
//! ([`crate::search::pairs`]) where the third pattern was lost to the blur.

use super::Finds;
use super::UPSCALE_MAX_SIDE_PX;
use super::passes::{
    SHARPEN_AMOUNT, SHARPEN_SIGMA_PX, SecondPass, decoded, double, double_sharpened,
    quad_sharpened, read_crop,
};
use crate::backends::detector_for;
use crate::backends::rxing::RxingDetector;
use crate::budget::PassLog;
use crate::raster::GrayImage;
use crate::raster::sharpen;
use crate::refine::corners::{RefineStatus, refine_corners};
use crate::search::merge::any_decoded;
use crate::search::merge::shortest_side_px;
use crate::search::pairs::{lone_regions, pair_regions};
use crate::search::region::{Crop, Region, same_place, unread_regions};
use crate::search::reread::reread;
use crate::{Backend, Candidate, Detector};
use qrpose_core::geometry::frames::PixelPoint;
use std::time::Instant;

/// Step 1½ (`balanced`, `thorough`; run after step 2), on frames of at most
/// [`UPSCALE_MAX_SIDE_PX`], when step 1 located nothing (neither a symbol nor a
/// finder-pattern triple; at `balanced`, on a frame of more than
/// [`super::WHOLE_FRAME_MAX_PIXELS`], with a finder pattern seen) or when two codes or more
/// were read, one of at most
/// [`SHARPENED_TRIGGER_MAX_PX_PER_MODULE`] px per module ([`reads_small_codes`]): rxing on
/// an unsharp-masked copy ([`SHARPEN_SIGMA_PX`], [`SHARPEN_AMOUNT`]). Small codes under
/// blur (about 2-3 px per module, blur σ ≈ 1 px) lose the light ring of their finder
/// patterns to the binariser, so step 1 sees no triple and step 2 no region; sharpening
/// gives the ring back. The triples it finds but cannot read are not made regions for step
/// 2 (on textured frames without a code the sharpened noise yields spurious triples, whose
/// crops would take step 2's passes up to the deadline): the small ones among them get one
/// double-scale sharpened read of their crop, at most [`SHARPENED_REGIONS_MAX`] of them;
/// then so do the places of lone finder-pattern pairs ([`pair_regions`]) that no such
/// triple covers, at most [`SHARPENED_PAIRS_MAX`].
pub(super) fn find_sharpened(finds: &mut Finds<'_>, log: &mut PassLog) {
    let image = finds.image;
    if image.width().max(image.height()) <= UPSCALE_MAX_SIDE_PX {
        sharpened_read(finds, None, log);
    }
}

/// Step 1½ of `balanced` on a frame whose whole-frame reads saw nothing code-like (no
/// symbol, triple or finder pattern), of more than [`super::WHOLE_FRAME_MAX_PIXELS`] and at
/// most [`UPSCALE_MAX_SIDE_PX`] on its longer side: the sharpened read of
/// [`find_sharpened`] on the crops around the [`TILE_PROBES`] busiest tiles only
/// ([`busiest_tiles`]), logged as `sharpened tile K`. A small code under blur shows no
/// finder pattern to the first reads (that is why it needs the sharpened read), but its
/// modules make the strongest fine detail of a frame of smooth surfaces; on a textured
/// frame the probes cost two small crops, where the whole-frame sharpened read cost more
/// than every other pass together (docs/measurements/detection.md, 2026-11-28).
pub(super) fn find_sharpened_tiles(finds: &mut Finds<'_>, log: &mut PassLog) {
    let image = finds.image;
    if image.width().max(image.height()) > UPSCALE_MAX_SIDE_PX {
        return;
    }
    for (k, tile) in busiest_tiles(image).into_iter().enumerate() {
        if !sharpened_read(finds, Some((k, tile)), log) {
            return;
        }
    }
}

/// The sharpened read of the whole frame (`area` `None`) or of the crop of `area` (its
/// index and region), then the crop reads of the small triples and pairs it found; `false`
/// when the deadline stopped it.
fn sharpened_read(finds: &mut Finds<'_>, area: Option<(usize, Region)>, log: &mut PassLog) -> bool {
    let image = finds.image;
    if !log.may_continue() {
        return false;
    }
    let started = Instant::now();
    let crop = area.and_then(|(_, region)| Crop::with_margin(image, &region, 0.0));
    let (source, name) = match (&area, &crop) {
        (None, _) => (image, "rxing sharpened".to_owned()),
        (
            Some((k, _)),
            Some(Crop {
                image: Some(pixels),
                ..
            }),
        ) => (pixels, format!("sharpened tile {k}")),
        _ => return true,
    };
    let Some(sharp) = sharpen(source, SHARPEN_SIGMA_PX, SHARPEN_AMOUNT) else {
        return true;
    };
    let (read, regions, patterns) = log.run_since(
        started,
        name,
        |r: &(Vec<Candidate>, Vec<Region>, _)| decoded(&r.0),
        || {
            let (read, regions, patterns) = RxingDetector::located().detect_with_patterns(&sharp);
            let (mut read, regions, patterns) = match &crop {
                Some(c) => (
                    read.into_iter().map(|r| c.to_source(r)).collect(),
                    regions.into_iter().map(|r| c.region_to_source(r)).collect(),
                    patterns
                        .into_iter()
                        .map(|p| c.pattern_to_source(p))
                        .collect(),
                ),
                None => (read, regions, patterns),
            };
            reread_small_located(image, &mut read);
            (read, regions, patterns)
        },
    );
    finds.add(read, log);
    drop(sharp);
    let small = regions
        .into_iter()
        .filter(|r| (r.hi_u - r.lo_u).max(r.hi_v - r.lo_v) <= SHARPENED_REGION_MAX_SIDE_PX);
    let triples: Vec<Region> = unread_regions(small.collect(), &finds.found)
        .into_iter()
        .take(SHARPENED_REGIONS_MAX)
        .collect();
    if !look_once_more(finds, &triples, "sharpened region", log, |_| None) {
        return false;
    }
    let pairs: Vec<Region> = unread_regions(pair_regions(&patterns, &finds.found), &finds.found)
        .into_iter()
        .filter(|p| !triples.iter().any(|t| same_place(t, p)))
        .take(SHARPENED_PAIRS_MAX)
        .collect();
    look_once_more(finds, &pairs, "sharpened pair", log, |crop| {
        double(crop, detector_for(Backend::Rxing).ok())
    })
}

/// Side of the tiles of [`busiest_tiles`], px.
pub(crate) const TILE_PX: usize = 64;
/// At most this many tiles get the sharpened read of [`find_sharpened_tiles`].
pub(crate) const TILE_PROBES: usize = 2;
/// A tile is probed only when its pixels differ from their right and lower neighbours by at
/// least this much on average, grey levels: flat frames get no probe.
pub(crate) const TILE_MIN_DETAIL: u64 = 4;

/// The regions of at most [`TILE_PROBES`] tiles of [`TILE_PX`] with the most fine detail
/// (the sum of absolute differences of neighbouring pixels, on every other row), each
/// widened by one tile on every side (a code of up to two tiles across that reaches into
/// the tile is inside), busiest first; a tile next to one already chosen is skipped.
fn busiest_tiles(image: &GrayImage) -> Vec<Region> {
    let (w, h) = (image.width(), image.height());
    let (tw, th) = (w / TILE_PX, h / TILE_PX);
    let px = image.pixels();
    let mut detail = vec![0u64; tw * th];
    for y in (0..th * TILE_PX).step_by(2) {
        let row = &px[y * w..(y + 1) * w];
        let below = &px[(y + 1).min(h - 1) * w..((y + 1).min(h - 1) + 1) * w];
        for (t, sum) in detail[(y / TILE_PX) * tw..(y / TILE_PX + 1) * tw]
            .iter_mut()
            .enumerate()
        {
            let span = t * TILE_PX..(t + 1) * TILE_PX;
            let (here, next) = (&row[span.clone()], &below[span]);
            let across: u32 = here
                .windows(2)
                .map(|p| u32::from(p[0].abs_diff(p[1])))
                .sum();
            let down: u32 = here
                .iter()
                .zip(next)
                .map(|(a, b)| u32::from(a.abs_diff(*b)))
                .sum();
            *sum += u64::from(across + down);
        }
    }
    let samples = (TILE_PX / 2 * (2 * TILE_PX - 1)) as u64;
    let mut order: Vec<usize> = (0..detail.len())
        .filter(|&t| detail[t] >= TILE_MIN_DETAIL * samples)
        .collect();
    order.sort_by(|a, b| detail[*b].cmp(&detail[*a]));
    let mut chosen: Vec<(usize, usize)> = Vec::new();
    for t in order {
        let (tx, ty) = (t % tw, t / tw);
        if chosen
            .iter()
            .any(|&(cx, cy)| cx.abs_diff(tx) <= 1 && cy.abs_diff(ty) <= 1)
        {
            continue;
        }
        chosen.push((tx, ty));
        if chosen.len() == TILE_PROBES {
            break;
        }
    }
    let tile = TILE_PX as f64;
    chosen
        .into_iter()
        .filter_map(|(tx, ty)| {
            let (u, v) = (tx as f64 * tile, ty as f64 * tile);
            Region::around(
                &[
                    PixelPoint::new(u, v),
                    PixelPoint::new(u + tile - 1.0, v + tile - 1.0),
                ],
                tile,
            )
        })
        .collect()
}

/// Step 1¾ (`balanced`, `thorough`; after the sharpened read or in its place) in a frame
/// where a code was read: the places of small lone finder patterns of the full-resolution
/// read ([`lone_regions`]: patterns no decoded symbol used, off every code read), at most
/// [`LONE_PATTERNS_MAX`], get the crop reads of [`look_once_more`] (`lone K ...`). A code
/// of 1.5-2.5 px per module next to codes that read often shows that read one finder
/// pattern and the sharpened read none or two (the sharpened read runs only on frames of
/// two codes read); frames where nothing was read, and codes whose finder patterns were
/// all used, pay nothing.
pub(super) fn find_lone(finds: &mut Finds<'_>, log: &mut PassLog) {
    if !any_decoded(&finds.found) {
        return;
    }
    let lone: Vec<Region> =
        unread_regions(lone_regions(&finds.patterns, &finds.found), &finds.found)
            .into_iter()
            .take(LONE_PATTERNS_MAX)
            .collect();
    look_once_more(finds, &lone, "lone", log, |_| None);
}

/// At most this many lone finder patterns of the full-resolution read get crop reads.
pub(crate) const LONE_PATTERNS_MAX: usize = 2;

/// A double-scale sharpened read of each region's crop, logged as `name K double
/// sharpened`, then, where that read nothing, the pass that `then` makes of the crop, if
/// any, then a quadruple-scale sharpened read of a small crop ([`quad_sharpened`]);
/// `false` when the deadline stopped it.
fn look_once_more(
    finds: &mut Finds<'_>,
    regions: &[Region],
    name: &str,
    log: &mut PassLog,
    then: impl for<'a> Fn(&'a GrayImage) -> Option<SecondPass<'a>>,
) -> bool {
    let image = finds.image;
    for (k, region) in regions.iter().enumerate() {
        // A crop read before may have read the code this place belongs to.
        if unread_regions(vec![*region], &finds.found).is_empty() {
            continue;
        }
        let Some(crop) = Crop::of_region(finds.image, region) else {
            continue;
        };
        let Some(pixels) = crop.image.as_ref() else {
            continue;
        };
        let located = || -> Option<Box<dyn Detector>> { Some(Box::new(RxingDetector::located())) };
        let first = double_sharpened(pixels, located());
        let last = quad_sharpened(pixels, located());
        for pass in [first, then(pixels), last].into_iter().flatten() {
            let Some(mut read) = pass.run(&format!("{name} {k} "), log, |d, variant, scale| {
                let mut read = read_crop(&crop, d, variant, scale);
                // Symbols located but not decoded: read again through the refined grid at
                // full resolution, and dropped if that fails too (a place, not a code).
                reread_located(image, &mut read);
                read
            }) else {
                return false;
            };
            read.retain(|c| c.payload.is_some());
            let done = any_decoded(&read);
            finds.add(read, log);
            if done {
                break;
            }
        }
    }
    true
}

/// Reads the undecoded symbols of `read` (located by a crop read) again through their module
/// grid at full resolution: refined when refinement succeeds, else as sampled (at 1.5-2 px
/// per module the refinement's edge profiles often fail, and the corners of a
/// quadruple-scale read are within a quarter pixel).
fn reread_located(image: &GrayImage, read: &mut [Candidate]) {
    for c in read.iter_mut().filter(|c| c.payload.is_none()) {
        let refinement = refine_corners(image, &c.corners_px, c.module_count);
        let (corners, n) = match (refinement.status, refinement.module_count) {
            (RefineStatus::Refined, Some(n)) => (refinement.corners_px, Some(n)),
            _ => (c.corners_px, c.module_count),
        };
        if let Some(again) = n.and_then(|n| reread(image, &corners, n)) {
            c.payload = Some(again.payload);
            c.text = again.text;
            c.module_count = n;
        }
    }
}

/// [`reread_located`] on the small undecoded symbols of `read` (at most
/// [`SHARPENED_REGIONS_MAX`] of at most [`SHARPENED_REGION_MAX_SIDE_PX`]); every undecoded
/// symbol is dropped after.
fn reread_small_located(image: &GrayImage, read: &mut Vec<Candidate>) {
    let small = |c: &Candidate| {
        Region::around(&c.corners_px, 0.0)
            .is_some_and(|r| (r.hi_u - r.lo_u).max(r.hi_v - r.lo_v) <= SHARPENED_REGION_MAX_SIDE_PX)
    };
    read.retain(|c| c.payload.is_some() || small(c));
    let mut undecoded = 0;
    read.retain(|c| {
        undecoded += usize::from(c.payload.is_none());
        c.payload.is_some() || undecoded <= SHARPENED_REGIONS_MAX
    });
    reread_located(image, read);
    read.retain(|c| c.payload.is_some());
}

/// A frame in which a code of at most this many px per module was read (its shortest side
/// over its module count) also gets the sharpened read of [`find_sharpened`]. That read is
/// for codes of 2-3 px per module, whose finder rings blur away; a code of the same printed
/// size twice as far away as one read at 6 px per module is at 3, so a frame that shows
/// codes at this scale is one where such codes are likely, next to the ones read (a shelf
/// or a wall of labels at several distances). Frames of larger codes only do not pay for
/// it, and frames with no code pay nothing more than before. Measured 2026-11-24: on the rendered
/// multi-code frames of `scripts/multicode_bench.py` (2-6 codes, 1280 × 720) reading every frame's
/// sharpened copy doubled `balanced`'s time and read 14 more codes (10 of ≥ 40 px); this trigger
/// reads 13 of them (all 10), while on the BoofCV development photos (one or a few codes, mostly at
/// more px per module) 34 more of 272 photos pay the read (68 with those where nothing was found),
/// where reading every frame ≤ 1920 px meant 150.
pub(crate) const SHARPENED_TRIGGER_MAX_PX_PER_MODULE: f64 = 6.0;

/// The small-code trigger of [`find_sharpened`] also wants this many codes read: a frame
/// showing one code is a robot camera's usual frame, whose latency is that of the first
/// reads (the sharpened read of a 1280 × 720 frame, 5 ms, would more than double it:
/// `docs/detection.md`, Speed), while two or more codes make a shelf or a wall of labels,
/// where codes the first reads miss are likely.
pub(crate) const SHARPENED_TRIGGER_MIN_CODES: usize = 2;

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
pub(crate) const SHARPENED_REGION_MAX_SIDE_PX: f64 = 160.0;
/// At most this many such triples get that look.
pub(crate) const SHARPENED_REGIONS_MAX: usize = 4;
/// At most this many places of lone finder-pattern pairs found on the sharpened copy get
/// that look too (after the triples, and only where no triple looked).
pub(crate) const SHARPENED_PAIRS_MAX: usize = 2;
