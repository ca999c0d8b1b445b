//! Step 1 of `auto`, **find**: rxing's reads of the whole frame, at full resolution and
//! (not `fast`) on the reduced levels (half scale; the smallest level, plain and
//! global-histogram), and a zxing-cpp build's own read first. Symbols new on a reduced level
//! are read again on a full-resolution crop; triples of codes read already are skipped there
//! unsampled. See the parent module for how the steps fit together.

use crate::backends::rxing;
#[cfg(feature = "zxing-cpp")]
use crate::backends::zxing_cpp;
use crate::budget::{Effort, PassLog};
use crate::raster::GrayImage;
use crate::raster::downscale_half;
use crate::search::merge::{same_symbol, shortest_side_px};
use crate::search::region::{Crop, Region};
use crate::{Backend, Candidate, Detector};
use qrpose_core::geometry::frames::PixelPoint;

use super::Finds;
use super::passes::{decoded, rescale};

/// Images whose shorter side has at least this many px are also read at half scale by
/// `balanced` and `thorough` (smaller ones are read at full resolution only): a quarter of
/// the pixels, where codes that fill the frame and moiré read better.
pub(crate) const HALF_SCALE_FIRST_MIN_SIDE_PX: usize = 700;

/// Step 1: the reads of the whole frame.
pub(super) fn find(finds: &mut Finds<'_>, effort: Effort, best: Backend, log: &mut PassLog) {
    let image = finds.image;
    if best == Backend::ZxingCpp {
        #[cfg(feature = "zxing-cpp")]
        {
            finds.aside = log.run(
                "zxing-cpp full",
                |v: &Vec<Candidate>| decoded(v),
                || zxing_cpp::ZxingCppDetector::fast().detect(image),
            );
        }
        if !log.may_continue() {
            return;
        }
    }
    let (read, regions, patterns) = log.run(
        "rxing full",
        |r: &(Vec<Candidate>, Vec<Region>, _)| decoded(&r.0),
        || rxing::RxingDetector::hybrid().detect_with_patterns(image),
    );
    // A read that decoded codes and left no finder pattern or triple unexplained has seen
    // everything the frame shows at full resolution: `balanced` takes that as the frame's
    // whole evidence and skips the reduced levels (`thorough` reads them anyway).
    let explained = decoded(&read) > 0 && regions.is_empty() && patterns.is_empty();
    finds.add(read, log);
    finds.regions.extend(regions);
    finds.patterns = patterns;
    let large = image.width().min(image.height()) >= HALF_SCALE_FIRST_MIN_SIDE_PX;
    let seen_all = explained && effort == Effort::Balanced;
    if effort == Effort::Fast || !large || seen_all || !log.may_continue() {
        return;
    }
    let Some(half) = downscale_half(image) else {
        return;
    };
    read_level(
        finds,
        &half,
        2.0,
        "rxing half",
        rxing::RxingDetector::hybrid(),
        log,
    );
    // The smallest level: codes whose modules are wider than the local binariser's
    // neighbourhood (a code that fills a 12 MP frame) and moiré read there, by the
    // global-histogram binariser as well.
    let (mut small, mut scale) = (half, 2.0);
    while small.width().max(small.height()) > SMALL_LEVEL_MAX_SIDE_PX
        || (scale < 4.0 && small.width().min(small.height()) >= 2 * SMALL_LEVEL_MIN_SIDE_PX)
    {
        let Some(next) = downscale_half(&small) else {
            return;
        };
        (small, scale) = (next, 2.0 * scale);
    }
    if scale > 2.0 && log.may_continue() {
        read_level(
            finds,
            &small,
            scale,
            "rxing small",
            rxing::RxingDetector::hybrid(),
            log,
        );
    }
    if log.may_continue() {
        let name = if scale > 2.0 {
            "rxing small global-histogram"
        } else {
            "rxing half global-histogram"
        };
        read_level(
            finds,
            &small,
            scale,
            name,
            rxing::RxingDetector::global_histogram(),
            log,
        );
    }
}

/// The longest side of the smallest level of step 1, px.
pub(crate) const SMALL_LEVEL_MAX_SIDE_PX: usize = 800;
/// The smallest level is at least quarter scale when its shorter side stays at least this
/// long there, px (screens photographed close: moiré at half scale).
pub(crate) const SMALL_LEVEL_MIN_SIDE_PX: usize = 300;

/// One read of a downscaled copy (`scale` source px per copy px). Whole-pixel corners at
/// that scale are `scale` pixels wide at full resolution, so a symbol new there is read
/// again on a full-resolution crop (the pass `{name} crop`) unless its modules are too wide
/// for that read ([`worth_a_crop_read`]); its unread triples become regions.
fn read_level(
    finds: &mut Finds<'_>,
    level: &GrayImage,
    scale: f64,
    name: &str,
    detector: rxing::RxingDetector,
    log: &mut PassLog,
) {
    let image = finds.image;
    let read_codes: Vec<[PixelPoint; 4]> = finds
        .found
        .iter()
        .filter(|c| c.payload.is_some())
        .map(|c| c.corners_px.map(|p| to_level(p, scale)))
        .collect();
    let (read, regions) = log.run(
        name,
        |r: &(Vec<Candidate>, Vec<Region>)| decoded(&r.0),
        || detector.detect_skipping(level, &read_codes),
    );
    for rough in read.into_iter().map(|c| rescale(c, scale)) {
        if finds.found.iter().any(|f| same_symbol(f, &rough)) {
            continue;
        }
        if worth_a_crop_read(&rough) {
            let precise = log.run(
                format!("{name} crop"),
                |v: &Vec<Candidate>| decoded(v),
                || precise(image, rough),
            );
            finds.add(precise, log);
        } else {
            finds.add(vec![rough], log);
        }
    }
    finds
        .regions
        .extend(regions.into_iter().map(|r| r.rescaled(scale)));
}

/// Whether a symbol read on a reduced copy is read again on a full-resolution crop
/// ([`precise`]): not when its modules are at least as wide as the local binariser's window
/// ([`rxing::LOCAL_WINDOW_PX`]) on every side. Such a module can fill a window, the crop is
/// binarised as the full-resolution read binarised the frame (which missed the symbol), and
/// the crop read, as large as the frame for a code that fills a 12 MP photo (5-13 ms),
/// never read one on the development photos (0 of 23 such crops; 8 of 41 narrower ones
/// read). The copy's corners, a copy pixel or so off, are then within a fraction of a
/// module, where the sub-pixel refinement starts anyway.
fn worth_a_crop_read(rough: &Candidate) -> bool {
    rough
        .module_count
        .is_none_or(|n| shortest_side_px(&rough.corners_px) < (rxing::LOCAL_WINDOW_PX * n) as f64)
}

/// A full-resolution point in the pixels of a copy reduced by `scale` (the inverse of
/// [`rescale`]'s mapping; pixel centres at integers).
fn to_level(p: PixelPoint, scale: f64) -> PixelPoint {
    PixelPoint::new((p.u() + 0.5) / scale - 0.5, (p.v() + 0.5) / scale - 0.5)
}

/// A symbol read on a reduced copy (corners whole pixels of that copy), read again on a
/// full-resolution crop around it for whole-pixel corners at full resolution; the rough
/// symbol itself when that read decodes nothing.
pub(super) fn precise(image: &GrayImage, rough: Candidate) -> Vec<Candidate> {
    let precise = Crop::around(image, &rough.corners_px).map(|crop| {
        let read = crop
            .image
            .as_ref()
            .map(|c| rxing::RxingDetector::hybrid().detect(c))
            .unwrap_or_default();
        read.into_iter()
            .filter(|c| c.payload.is_some())
            .map(|c| crop.to_source(c))
            .collect::<Vec<_>>()
    });
    match precise {
        Some(p) if !p.is_empty() => p,
        _ => vec![rough],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A decoded candidate of `modules` modules whose square sides are `side_px` long.
    fn square(modules: Option<usize>, side_px: f64) -> Candidate {
        Candidate {
            corners_px: [
                (0.0, 0.0),
                (side_px, 0.0),
                (side_px, side_px),
                (0.0, side_px),
            ]
            .map(|(u, v)| PixelPoint::new(u, v)),
            payload: Some(b"X".to_vec()),
            text: Some("X".into()),
            module_count: modules,
            backend: Backend::Rxing,
        }
    }

    /// Modules as wide as the local binariser's window get no full-resolution crop read;
    /// narrower ones, and symbols of unknown size, do.
    #[test]
    fn a_reduced_read_is_read_again_at_full_resolution_only_below_the_binarisers_window() {
        let window = rxing::LOCAL_WINDOW_PX as f64;
        assert!(!worth_a_crop_read(&square(Some(21), 21.0 * window)));
        assert!(!worth_a_crop_read(&square(Some(25), 25.0 * 1.5 * window)));
        assert!(worth_a_crop_read(&square(Some(21), 21.0 * (window - 1.0))));
        assert!(worth_a_crop_read(&square(Some(33), 33.0 * 6.0)));
        assert!(worth_a_crop_read(&square(None, 2000.0)));
    }
}
