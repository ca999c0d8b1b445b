//! Image to QR codes: decode the bytes, find every symbol with one or more backends, read
//! it, and refine its corners to a fraction of a pixel. No async, no HTTP.
//!
//! - [`decode`]: bytes → [`decode::GrayImage`], with [`decode::DecodeLimits`].
//! - Backends behind [`Detector`]: [`rqrr`] and [`rxing`] always; `zxing_cpp` with the
//!   `zxing-cpp` cargo feature. [`DetectorChoice::Auto`] reads the whole frame once or twice
//!   and then looks closer only where a finder-pattern triple was found but not read
//!   ([`region`]), within a [`Budget`] (effort and deadline, [`budget`]); results are
//!   merged by position. Symbols found but not read are read again through their refined
//!   module grid ([`reread`]).
//! - [`corners`]: sub-pixel corners and the twelve finder-pattern corners, whatever the
//!   backend ([`profile`] measures single edges, [`homography`] maps the module grid).
//!
//! Where things live: the backend registry and the shared types ([`Backend`],
//! [`Candidate`], [`Detector`], [`detector_for`]) in module `backend`; merging the
//! results of several passes ([`merge_candidates`]) and re-reading undecoded ones in
//! module `merge`; the `auto` strategy and its constants in module `auto` (all three
//! re-exported here); image filters in [`filters`]; the raster in [`gray`]; containing
//! panics of third-party code in [`contain`]; photo to poses in [`pipeline`].
//!
//! Conventions: corners in `"qr"` order (top-left, top-right, bottom-right, bottom-left of
//! the symbol), pixels with integer pixel centres (docs/conventions.md).

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

mod auto;
mod backend;
pub mod binarizer;
pub mod budget;
pub mod cancel;
pub mod contain;
pub mod corners;
pub mod decode;
pub mod filters;
mod finder_scan;
pub mod finders;
pub mod global_binarizer;
pub mod gray;
pub mod homography;
mod merge;
pub mod pairs;
pub mod pipeline;
pub mod profile;
pub mod region;
pub mod reread;
pub mod rqrr;
pub mod rxing;
#[cfg(feature = "zxing-cpp")]
pub mod zxing_cpp;

pub use auto::{
    DENOISE_SIGMA_PX, HALF_SCALE_FIRST_MIN_SIDE_PX, SHARPEN_AMOUNT, SHARPEN_DOUBLE_AMOUNT,
    SHARPEN_DOUBLE_SIGMA_PX, SHARPEN_SIGMA_PX, UPSCALE_MAX_SIDE_PX,
};
pub use backend::{
    Backend, Candidate, DetectError, Detector, DetectorChoice, auto_order, detector_for,
};
pub use budget::{Budget, Effort, PassLog, PassReport};
pub use filters::{downscale_half, invert, sharpen, stretch_contrast, upscale_double};
pub use merge::merge_candidates;

use corners::{RefineStatus, refine_corners};
use gray::GrayImage;
use merge::reread_undecoded;
use qrpose_core::geometry::frames::PixelPoint;

/// One detected symbol with refined corners.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedCode {
    /// What the backend reported.
    pub candidate: Candidate,
    /// Refined corners and finder corners.
    pub refinement: corners::Refinement,
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
/// again through the refined module grid ([`reread`]).
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
        DetectorChoice::Auto => Ok(auto::find_candidates(image, effort, log)),
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
