//! Image to QR codes: decode the bytes, find every symbol with one or more backends, read
//! it, and refine its corners to a fraction of a pixel. No async, no HTTP.
//!
//! The crate is grouped by what each part does:
//!
//! | module | what it owns |
//! |---|---|
//! | [`decode`] | bytes → [`raster::GrayImage`], within [`decode::DecodeLimits`] |
//! | [`raster`] | the grey image and the whole-image filters (sharpen, blur, rescale) |
//! | [`backends`] | the detector libraries behind [`Detector`]: rqrr, rxing (with this crate's rewrites of rxing's binarisers and finder search), zxing-cpp with the `zxing-cpp` feature |
//! | [`search`] | the `auto` strategy: whole-frame reads, then closer looks only where a code may be (regions, finder pairs), merging, re-reading through the module grid |
//! | [`refine`] | sub-pixel corners and finder corners from edge profiles and the module grid |
//! | [`budget`], [`cancel`] | what detection may spend: effort, deadline, cancellation, and the log of the passes that ran |
//! | [`pipeline`] | photo to poses: detection, then each code's pose at its own size |
//! | [`contain`] | panics of third-party code turned into values |
//!
//! The entry points are here: [`detect_within`] (every code of an image within a
//! [`Budget`]), [`detect_codes`] and [`find_candidates`]; [`pipeline::locate_markers`]
//! adds the poses.
//!
//! Conventions: corners in `"qr"` order (top-left, top-right, bottom-right, bottom-left of
//! the symbol), pixels with integer pixel centres (docs/conventions.md).

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

pub mod backends;
pub mod budget;
pub mod cancel;
pub mod contain;
pub mod decode;
pub mod pipeline;
pub mod raster;
pub mod refine;
pub mod search;

pub use backends::{
    Backend, Candidate, DetectError, Detector, DetectorChoice, auto_order, detector_for,
};
pub use budget::{Budget, Effort, PassLog, PassReport};
pub use raster::filters::{downscale_half, invert, sharpen, stretch_contrast, upscale_double};
pub use search::auto::{
    DENOISE_SIGMA_PX, HALF_SCALE_FIRST_MIN_SIDE_PX, SHARPEN_AMOUNT, SHARPEN_DOUBLE_AMOUNT,
    SHARPEN_DOUBLE_SIGMA_PX, SHARPEN_SIGMA_PX, UPSCALE_MAX_SIDE_PX,
};
pub use search::merge::merge_candidates;
// The paths of the flat layout, until the callers move to the grouped one.
#[cfg(feature = "zxing-cpp")]
pub use backends::zxing_cpp;
pub use backends::{rqrr, rxing};
pub use raster::{filters, gray};
pub use refine::{corners, finders, homography, profile};
pub use search::{pairs, region, reread};

use qrpose_core::geometry::frames::PixelPoint;
use raster::GrayImage;
use refine::corners::{RefineStatus, refine_corners};
use search::merge::reread_undecoded;

/// One detected symbol with refined corners.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedCode {
    /// What the backend reported.
    pub candidate: Candidate,
    /// Refined corners and finder corners.
    pub refinement: refine::corners::Refinement,
}

impl DetectedCode {
    /// The corners to use, px, qr order: refined when refinement succeeded.
    pub fn corners_px(&self) -> &[PixelPoint; 4] {
        &self.refinement.corners_px
    }
    /// Whether the corners are refined.
    pub fn is_refined(&self) -> bool {
        self.refinement.status == RefineStatus::Refined
    }
}

/// Every candidate the choice finds in `image`, before refinement, at `balanced` effort with
/// its default deadline.
///
/// # Errors
/// [`DetectError::BackendNotBuilt`] when a single backend is asked for that is not built.
pub fn find_candidates(
    image: &GrayImage,
    choice: DetectorChoice,
) -> Result<Vec<Candidate>, DetectError> {
    let budget = Budget::default();
    let mut log = PassLog::with_cancel(budget.deadline_for(image.pixels().len()), budget.cancel);
    find_logged(image, choice, budget.effort, &mut log)
}

/// The candidates of `choice` at `effort`, passes recorded in `log` (whose deadline bounds
/// `auto`). A single backend runs one pass and reads what it found but could not decode
/// again through the refined module grid ([`search::reread`]).
fn find_logged(
    image: &GrayImage,
    choice: DetectorChoice,
    effort: Effort,
    log: &mut PassLog,
) -> Result<Vec<Candidate>, DetectError> {
    match choice {
        DetectorChoice::Only(backend) => {
            let detector = detector_for(backend)?;
            let mut found = log.run(
                backend.as_str(),
                |f: &Vec<Candidate>| f.iter().filter(|c| c.payload.is_some()).count(),
                || detector.detect(image),
            );
            reread_undecoded(image, &mut found, &mut Vec::new());
            Ok(found)
        }
        DetectorChoice::Auto => Ok(search::auto::find_candidates(image, effort, log)),
    }
}

/// What one detection found, and how.
#[derive(Debug, Clone)]
pub struct Detection {
    /// Every symbol, with refined corners.
    pub codes: Vec<DetectedCode>,
    /// The passes that ran, in order, and whether the deadline stopped further ones.
    pub log: PassLog,
}

/// Finds, reads and refines every QR symbol in `image` within `budget`.
///
/// # Errors
/// [`DetectError::BackendNotBuilt`] when a single backend is asked for that is not built.
pub fn detect_within(
    image: &GrayImage,
    choice: DetectorChoice,
    budget: &Budget,
) -> Result<Detection, DetectError> {
    let deadline = budget.deadline_for(image.pixels().len());
    let mut log = PassLog::with_cancel(deadline, budget.cancel.clone());
    let candidates = find_logged(image, choice, budget.effort, &mut log)?;
    let codes = candidates
        .into_iter()
        .map(|candidate| {
            let refinement = refine_corners(image, &candidate.corners_px, candidate.module_count);
            DetectedCode {
                candidate,
                refinement,
            }
        })
        .collect();
    Ok(Detection { codes, log })
}

/// Finds, reads and refines every QR symbol in `image` at `balanced` effort with its
/// default deadline.
///
/// # Errors
/// [`DetectError::BackendNotBuilt`] when a single backend is asked for that is not built.
pub fn detect_codes(
    image: &GrayImage,
    choice: DetectorChoice,
) -> Result<Vec<DetectedCode>, DetectError> {
    detect_within(image, choice, &Budget::default()).map(|d| d.codes)
}

/// The README example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
