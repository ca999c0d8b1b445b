//! Image to QR codes: decode the bytes, find every symbol with one or more backends, read
//! it, and refine its corners to a fraction of a pixel. No async, no HTTP.
//!
//! The entry points are here: [`detect_within`] finds, reads and refines every code of an
//! image within a [`Budget`] (effort, deadline, [`CancelFlag`]) and reports the passes that
//! ran ([`PassLog`]); [`detect_codes`] does so at the default budget, [`find_candidates`]
//! stops before refinement; [`detect_in_regions`] reads only the regions a caller names
//! ([`SearchRegion`]: where a video stream's tracks predict their codes);
//! [`pipeline::locate_markers`] and [`pipeline::locate_markers_in_regions`] add each code's
//! pose.
//!
//! The crate is grouped by what each part does:
//!
//! - [`decode`]: bytes → [`decode::GrayImage`], within [`decode::DecodeLimits`].
//! - [`raster`]: the grey image and the whole-image filters (sharpen and blur, contrast
//!   stretch, negative, double and half scale).
//! - [`backends`]: the detector libraries behind [`Detector`] (rqrr, rxing, and zxing-cpp
//!   with the `zxing-cpp` cargo feature), chosen by [`DetectorChoice`]; beside rxing's,
//!   this crate's bit-for-bit rewrites of rxing's binarisers and finder-pattern search.
//! - [`search`]: the `auto` strategy (whole-frame reads, then closer looks only where a
//!   code may be), the crop reads of given regions, merging by position, reading again
//!   through the refined module grid.
//! - [`refine`]: sub-pixel corners and finder corners from edge profiles and the module
//!   grid, whatever the backend.
//! - [`budget`], [`cancel`]: what detection may spend, and the log of what it did.
//! - [`pipeline`]: photo to poses, each code solved once at its own size.
//! - [`contain`]: panics of third-party code turned into values.
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
#[cfg(test)]
mod test_frames;

pub use backends::{Backend, Candidate, DetectError, Detector, DetectorChoice};
pub use budget::{Budget, Effort, PassLog, PassReport};
pub use cancel::CancelFlag;
pub use search::SearchRegion;

use backends::detector_for;
use qrpose_core::geometry::frames::PixelPoint;
use raster::GrayImage;
use refine::{RefineStatus, refine_corners};
use search::merge::reread_undecoded;

/// One detected symbol with refined corners.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedCode {
    /// What the backend reported.
    pub candidate: Candidate,
    /// Refined corners and finder corners.
    pub refinement: refine::Refinement,
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
/// again through the refined module grid ([`search::reread()`]).
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
    Ok(Detection {
        codes: refined(image, candidates),
        log,
    })
}

/// Finds, reads and refines the QR symbols in the given `regions` of `image` only (a video
/// stream's tracks predict where their codes are), within `budget`; nothing outside them
/// is read. Each region is cut out (clipped to the image) and read until a pass decodes
/// there, at a higher effort than `auto`'s first read of a whole frame: rxing at the
/// crop's scale with the re-read through the refined module grid, then (`balanced`,
/// `thorough`) the global-histogram binariser, contrast-stretched, inverted, sharpened
/// and double-scale copies, and a quadruple-scale one of a small crop. The passes are
/// logged as `track crop K ...` (K: the region's index). Codes found twice (overlapping
/// regions) are merged; corners are refined on the whole image and given in its pixels.
///
/// The first read always runs; before each further one the deadline
/// ([`Budget::deadline_for`] the whole image) and the cancel flag are checked, so a spent
/// or cancelled budget stops between regions. With no region, or none in the image,
/// nothing is read.
#[must_use]
pub fn detect_in_regions(
    image: &GrayImage,
    regions: &[SearchRegion],
    budget: &Budget,
) -> Detection {
    let deadline = budget.deadline_for(image.pixels().len());
    let mut log = PassLog::with_cancel(deadline, budget.cancel.clone());
    let candidates = search::given::find_in_regions(image, regions, budget.effort, &mut log);
    Detection {
        codes: refined(image, candidates),
        log,
    }
}

/// `candidates` with their corners refined on `image`, in order.
fn refined(image: &GrayImage, candidates: Vec<Candidate>) -> Vec<DetectedCode> {
    candidates
        .into_iter()
        .map(|candidate| {
            let refinement = refine_corners(image, &candidate.corners_px, candidate.module_count);
            DetectedCode {
                candidate,
                refinement,
            }
        })
        .collect()
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
