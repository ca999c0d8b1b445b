//! The `auto` strategy of [`crate::find_candidates`]: a quick pass first (zxing-cpp's single
//! read when built, else rxing on a half-scale copy of a large image, then on full-resolution
//! crops around what it read), then every built backend at full resolution, best first,
//! then second passes of the best one on variants of the image made by [`crate::filters`]
//! (global-histogram binariser, blurred, contrast-stretched, inverted, sharpened, double
//! scale). It stops after the first step that reads a code; candidates found on the way are
//! re-read and merged ([`crate::merge_candidates`]).

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use crate::filters::{downscale_half, invert, sharpen, stretch_contrast, upscale_double};
use crate::gray::GrayImage;
use crate::merge::{any_decoded, reread_undecoded};
#[cfg(feature = "zxing-cpp")]
use crate::zxing_cpp;
use crate::{
    Backend, Candidate, DetectError, Detector, auto_order, detector_for, merge_candidates,
};
use crate::{rqrr, rxing};
use qrpose_core::geometry::frames::PixelPoint;

/// Images up to this many px on their longer side get a double-scale second pass (the last
/// one: four times the pixels). Codes of 2-3 px per module under heavy blur, which every
/// backend misses at their own size, are found there.
pub const UPSCALE_MAX_SIDE_PX: usize = 1920;

/// One second pass of `auto`: a detector on a variant of the image, and the scale that maps
/// the variant's pixels back (source px per variant px).
struct SecondPass {
    detector: Box<dyn Detector>,
    image: GrayImage,
    scale: f64,
}

/// Blur of the blurred global-histogram pass, px: it smooths halftone and sensor noise of
/// small photos before the single threshold.
pub const DENOISE_SIGMA_PX: f64 = 1.0;

/// The second passes of `auto`, cheapest first, each built only when reached:
/// 1. the best backend with the global-histogram binariser, on the image and on a copy
///    blurred by [`DENOISE_SIGMA_PX`] (small noisy photos that the local binariser breaks
///    up);
/// 2. the best backend on a contrast-stretched, an inverted (unless zxing-cpp, which reads
///    the negative itself, is the best) and a sharpened ([`sharpen`]) copy;
/// 3. on a double-scale copy, plain and sharpened (images of at most
///    [`UPSCALE_MAX_SIDE_PX`]).
///
/// zxing-cpp runs its single-read settings here: its thorough one would read each variant
/// again downscaled and inverted, which its own full pass has covered.
fn second_passes(image: &GrayImage, best: Backend) -> impl Iterator<Item = SecondPass> + '_ {
    type Make<'a> = Box<dyn Fn() -> Option<SecondPass> + 'a>;
    let local = move || -> Option<Box<dyn Detector>> {
        match best {
            #[cfg(feature = "zxing-cpp")]
            Backend::ZxingCpp => Some(Box::new(zxing_cpp::ZxingCppDetector::fast())),
            other => detector_for(other).ok(),
        }
    };
    let global = move || -> Option<Box<dyn Detector>> {
        match best {
            #[cfg(feature = "zxing-cpp")]
            Backend::ZxingCpp => Some(Box::new(zxing_cpp::ZxingCppDetector::global_histogram())),
            Backend::Rqrr => None,
            _ => Some(Box::new(rxing::RxingDetector::global_histogram())),
        }
    };
    let pass = |detector: Option<Box<dyn Detector>>, image: Option<GrayImage>, scale: f64| {
        Some(SecondPass {
            detector: detector?,
            image: image?,
            scale,
        })
    };
    let small = image.width().max(image.height()) <= UPSCALE_MAX_SIDE_PX;
    let makers: Vec<Make<'_>> = vec![
        Box::new(move || pass(global(), Some(image.clone()), 1.0)),
        Box::new(move || pass(global(), sharpen(image, DENOISE_SIGMA_PX, -1.0), 1.0)),
        Box::new(move || pass(local(), stretch_contrast(image), 1.0)),
        Box::new(move || {
            (best != Backend::ZxingCpp)
                .then(|| pass(local(), invert(image), 1.0))
                .flatten()
        }),
        Box::new(move || {
            pass(
                local(),
                sharpen(image, SHARPEN_SIGMA_PX, SHARPEN_AMOUNT),
                1.0,
            )
        }),
        Box::new(move || {
            small
                .then(|| pass(local(), upscale_double(image), 0.5))
                .flatten()
        }),
        Box::new(move || {
            let double = small.then(|| upscale_double(image)).flatten()?;
            let sharp = sharpen(
                &double,
                2.0 * SHARPEN_DOUBLE_SIGMA_PX,
                SHARPEN_DOUBLE_AMOUNT,
            );
            pass(local(), sharp, 0.5)
        }),
    ];
    makers.into_iter().filter_map(|make| make())
}

/// Unsharp mask of the sharpened second pass: Gaussian σ, source px.
pub const SHARPEN_SIGMA_PX: f64 = 1.5;
/// Unsharp mask of the sharpened second pass: amount (1 doubles the detail).
pub const SHARPEN_AMOUNT: f64 = 2.0;
/// Unsharp mask of the sharpened double-scale pass: Gaussian σ, source px.
pub const SHARPEN_DOUBLE_SIGMA_PX: f64 = 1.0;
/// Unsharp mask of the sharpened double-scale pass: amount.
pub const SHARPEN_DOUBLE_AMOUNT: f64 = 3.0;

/// Maps candidates found on a downscaled copy (`scale` source px per copy px) back to the
/// source: pixel centres scale about −0.5.
fn rescale(mut c: Candidate, scale: f64) -> Candidate {
    if scale != 1.0 {
        c.corners_px = c
            .corners_px
            .map(|p| PixelPoint::new((p.u() + 0.5) * scale - 0.5, (p.v() + 0.5) * scale - 0.5));
        // The module count measured on the copy is still right; whole-pixel corners are not.
    }
    c
}

/// Images whose shorter side has at least this many px are first searched at half scale by
/// the pure-Rust backends (`auto` in a build without zxing-cpp): a quarter of the pixels to
/// binarise and scan. Codes of at least about 4 px per module (2 px at half scale) are read
/// there; smaller ones fall through to the full-resolution pass.
pub const HALF_SCALE_FIRST_MIN_SIDE_PX: usize = 700;

/// Margin around a symbol found at half scale for the full-resolution read of its
/// surroundings: a share of the symbol's bounding box on each side, plus the quiet zone.
const CROP_MARGIN_SHARE: f64 = 0.25;
/// Fixed extra margin of that crop, px.
const CROP_MARGIN_PX: f64 = 8.0;

/// The quick first pass of `auto`: zxing-cpp's one read when it is built, otherwise rxing
/// on a half-scale copy of a large image and then again at full resolution on a crop around
/// each symbol it read (whole-pixel corners at full resolution, for the refinement, at the
/// cost of a few small images); `None` when there is no quick pass for this image.
fn quick_pass(image: &GrayImage, best: Backend) -> Option<Vec<Candidate>> {
    match best {
        #[cfg(feature = "zxing-cpp")]
        Backend::ZxingCpp => Some(zxing_cpp::ZxingCppDetector::fast().detect(image)),
        Backend::Rxing if image.width().min(image.height()) >= HALF_SCALE_FIRST_MIN_SIDE_PX => {
            let half = downscale_half(image)?;
            let mut found = Vec::new();
            for rough in rxing::RxingDetector::hybrid().detect(&half) {
                let rough = rescale(rough, 2.0);
                let Some(crop) = Crop::around(image, &rough.corners_px) else {
                    continue;
                };
                let precise = crop
                    .image
                    .as_ref()
                    .map(|c| rxing::RxingDetector::hybrid().detect(c));
                let precise: Vec<Candidate> = precise
                    .unwrap_or_default()
                    .into_iter()
                    .filter(|c| c.payload.is_some())
                    .map(|c| crop.to_source(c))
                    .collect();
                merge_candidates(&mut found, precise);
            }
            Some(found)
        }
        _ => None,
    }
}

/// A rectangle of an image, copied out, with its offset in the source.
struct Crop {
    image: Option<GrayImage>,
    x0: usize,
    y0: usize,
}

impl Crop {
    /// The bounding box of `corners_px` widened by the crop margins, clamped to the image.
    fn around(image: &GrayImage, corners_px: &[PixelPoint; 4]) -> Option<Self> {
        let (mut lo_u, mut lo_v, mut hi_u, mut hi_v) = (
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        );
        for p in corners_px {
            lo_u = lo_u.min(p.u());
            lo_v = lo_v.min(p.v());
            hi_u = hi_u.max(p.u());
            hi_v = hi_v.max(p.v());
        }
        if !(lo_u.is_finite() && lo_v.is_finite() && hi_u.is_finite() && hi_v.is_finite()) {
            return None;
        }
        let margin = CROP_MARGIN_SHARE * (hi_u - lo_u).max(hi_v - lo_v) + CROP_MARGIN_PX;
        let max_u = (image.width() - 1) as f64;
        let max_v = (image.height() - 1) as f64;
        let x0 = (lo_u - margin).clamp(0.0, max_u).floor() as usize;
        let y0 = (lo_v - margin).clamp(0.0, max_v).floor() as usize;
        let x1 = (hi_u + margin).clamp(0.0, max_u).ceil() as usize;
        let y1 = (hi_v + margin).clamp(0.0, max_v).ceil() as usize;
        let (w, h) = (x1.checked_sub(x0)? + 1, y1.checked_sub(y0)? + 1);
        let mut pixels = Vec::with_capacity(w * h);
        for row in image.pixels().chunks_exact(image.width()).skip(y0).take(h) {
            pixels.extend_from_slice(row.get(x0..x0 + w)?);
        }
        Some(Self {
            image: GrayImage::new(w, h, pixels),
            x0,
            y0,
        })
    }

    /// A candidate found in the crop, in source pixels.
    fn to_source(&self, mut c: Candidate) -> Candidate {
        let (dx, dy) = (self.x0 as f64, self.y0 as f64);
        c.corners_px = c
            .corners_px
            .map(|p| PixelPoint::new(p.u() + dx, p.v() + dy));
        c
    }
}

/// Every candidate `auto` finds in `image`, before refinement (see the module doc).
///
/// # Errors
/// [`DetectError::BackendNotBuilt`] only if a backend of [`auto_order`] is not built (it
/// lists built ones only).
pub(crate) fn find_candidates(image: &GrayImage) -> Result<Vec<Candidate>, DetectError> {
    let order = auto_order();
    let mut found: Vec<Candidate> = Vec::new();
    let mut tried = Vec::new();
    let Some(&best) = order.first() else {
        return Ok(found);
    };
    // Each step's candidates are re-read before they are merged, so that an unread
    // duplicate from an earlier step does not shadow a symbol this step can read.
    let mut add = |found: &mut Vec<Candidate>, mut new: Vec<Candidate>| {
        reread_undecoded(image, &mut new, &mut tried);
        merge_candidates(found, new);
        any_decoded(found)
    };
    if let Some(quick) = quick_pass(image, best)
        && add(&mut found, quick)
    {
        return Ok(found);
    }
    for backend in &order {
        if add(&mut found, detector_for(*backend)?.detect(image)) {
            return Ok(found);
        }
    }
    for pass in second_passes(image, best) {
        let mut more: Vec<Candidate> = pass
            .detector
            .detect(&pass.image)
            .into_iter()
            .map(|c| rescale(c, pass.scale))
            .collect();
        if pass.scale < 1.0 && !any_decoded(&more) {
            // rqrr finds blurred symbols on the enlarged copy that it cannot read;
            // their refined grids often can be (at full resolution).
            more.extend(
                rqrr::RqrrDetector
                    .detect(&pass.image)
                    .into_iter()
                    .map(|c| rescale(c, pass.scale)),
            );
        }
        if add(&mut found, more) {
            break;
        }
    }
    Ok(found)
}
