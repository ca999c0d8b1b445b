//! Every code in a photo, with its pose: `POST /v1/pose/image` (and its annotated form),
//! `qrpose estimate --image`, and each frame of the stream.
//!
//! Decode, then [`locate_markers`] (find, read, refine, solve each code once at the size
//! the setup's [`super::SizeResolver`] gives it), then per code the prior and the site's
//! frames, then the fused localisation of the mapped codes.

use super::frames::{InFrames, Localization, SiteFrames, localize};
use super::prior::{Observed, with_prior};
use super::setup::ImageSetup;
use qrpose_core::estimate::PoseEstimate;
use qrpose_core::geometry::marker::Marker;
use qrpose_detect::cancel::CancelFlag;
use qrpose_detect::decode::{self, DecodeError, GrayImage};

use qrpose_detect::pipeline::{
    Located, LocatedMarker, MarkerError, Points, locate_markers, locate_markers_in_regions,
    observed_points,
};
use qrpose_detect::{DetectError, DetectedCode, PassReport, SearchRegion};
use qrpose_site::SizeSource;
use std::time::Instant;

/// Why a photo has no answer at all (a code without a pose is not one of these).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImageError {
    /// The bytes are not an image this service reads, or the image is over the limits.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// The detector asked for is not in this build.
    #[error(transparent)]
    Detect(#[from] DetectError),
}

/// Time per stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Timing {
    /// Decoding the image, ms.
    pub decode_ms: f64,
    /// Detection, reading and corner refinement, ms.
    pub detect_ms: f64,
    /// Solving every code's pose, with its prior and frames, ms.
    pub estimate_ms: f64,
    /// The detection passes that ran, in order.
    pub passes: Vec<PassReport>,
}

/// One code of the photo.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerAnswer {
    /// The code as detected: payload, corners, refinement.
    pub code: DetectedCode,
    /// Its size and where that came from; `None` when the site has none for it.
    pub marker: Option<(Marker, SizeSource)>,
    /// The points its pose was solved from.
    pub points_used: Points,
    /// Its pose (after the prior), or why there is none.
    pub pose: Result<PoseEstimate, MarkerError>,
    /// The prior decided the planar ambiguity.
    pub resolved_by_prior: bool,
    /// The pose in the robot's and the world's frames.
    pub frames: InFrames,
    /// Time spent solving this code, µs.
    pub estimate_us: f64,
}

/// Every code of a photo.
#[derive(Debug, Clone)]
pub struct ImageAnswer {
    /// The decoded image's width, px.
    pub width_px: usize,
    /// The decoded image's height, px.
    pub height_px: usize,
    /// The codes, in the detector's order.
    pub markers: Vec<MarkerAnswer>,
    /// The robot's pose fused over the mapped codes, when two or more have one.
    pub localization: Option<Localization>,
    /// The deadline stopped detection before every pass had run.
    pub budget_exhausted: bool,
    /// Time per stage.
    pub timing: Timing,
    /// Poses solved for this answer: one per code with a size (the detector asks each
    /// code's size before it solves), none for a code without one.
    pub solves: usize,
}

/// Decodes `bytes` and finds, reads and solves every QR code in it, as `setup` says;
/// `cancel` stops detection before its next pass (nobody waits for the answer any more).
///
/// # Errors
/// [`ImageError::Decode`] for bytes that are not a JPEG or PNG (or WebP) or an image over
/// the setup's limits; [`ImageError::Detect`] for a detector not in this build. Finding no
/// code is an answer with no markers.
pub fn estimate_image(
    setup: &ImageSetup,
    bytes: &[u8],
    cancel: CancelFlag,
) -> Result<ImageAnswer, ImageError> {
    let started = Instant::now();
    let image = decode::decode_gray(bytes, &setup.decode)?;
    let decode_ms = ms_since(started);
    estimate_decoded(setup, &image, decode_ms, cancel)
}

/// [`estimate_image`] for an image already decoded (in `decode_ms`).
///
/// # Errors
/// [`ImageError::Detect`] for a detector not in this build.
pub fn estimate_decoded(
    setup: &ImageSetup,
    image: &GrayImage,
    decode_ms: f64,
    cancel: CancelFlag,
) -> Result<ImageAnswer, ImageError> {
    let pose = &setup.pose;
    let options = setup.detect.options(image.pixels().len(), cancel);
    let detect_setup = qrpose_detect::pipeline::Setup {
        camera: pose.camera,
        sizes: pose.sizes(),
        solver: pose.solver,
    };
    let located = locate_markers(image, &detect_setup, &options)?;
    Ok(answer_of_located(setup, image, located, decode_ms))
}

/// The answer of what the detector located in `image`: each code with its prior and its
/// site frames, and the fused localisation.
fn answer_of_located(
    setup: &ImageSetup,
    image: &GrayImage,
    located: Located<SizeSource>,
    decode_ms: f64,
) -> ImageAnswer {
    let pose = &setup.pose;
    let started = Instant::now();
    let frames = SiteFrames {
        site: pose.site.as_deref(),
        camera: pose.site_camera.as_ref(),
        pick: pose.pick,
    };
    let markers: Vec<MarkerAnswer> = located
        .markers
        .into_iter()
        .map(|m| answer_of(m, setup, &frames))
        .collect();
    let mapped: Vec<_> = markers
        .iter()
        .enumerate()
        .filter_map(|(index, m)| {
            let in_world = m.frames.in_world?;
            let payload = m.code.candidate.text.clone()?;
            Some((index, payload, in_world))
        })
        .collect();
    let localization = localize(&mapped);
    ImageAnswer {
        width_px: image.width(),
        height_px: image.height(),
        markers,
        localization,
        budget_exhausted: located.budget_exhausted,
        solves: located.solves,
        timing: Timing {
            decode_ms,
            detect_ms: located.detect_ms,
            estimate_ms: located.estimate_ms + ms_since(started),
            passes: located.passes,
        },
    }
}

/// One located code with its prior applied and its pose carried into the site's frames.
fn answer_of(
    located: LocatedMarker<SizeSource>,
    setup: &ImageSetup,
    frames: &SiteFrames<'_>,
) -> MarkerAnswer {
    let payload = located.code.candidate.text.as_deref();
    let (pose, resolved_by_prior) = match (&located.pose, &located.marker) {
        (Ok(estimate), Some((marker, _))) => {
            let prior = setup.pose.prior.and_then(|p| p.for_code(frames, payload));
            match observed_points(&located) {
                Some((model, image)) if prior.is_some() => {
                    let observed = Observed {
                        model: &model,
                        image: &image,
                        camera: &setup.pose.camera,
                        marker,
                        corner_sigma_px: setup.pose.solver.as_reprojection().corner_sigma_px,
                    };
                    let (estimate, by_prior) = with_prior(estimate.clone(), prior, &observed);
                    (Ok(estimate), by_prior)
                }
                _ => (Ok(estimate.clone()), false),
            }
        }
        (pose, _) => (pose.clone(), false),
    };
    let in_frames = match &pose {
        Ok(estimate) => frames.of(estimate, payload),
        Err(_) => InFrames::default(),
    };
    MarkerAnswer {
        code: located.code,
        marker: located.marker,
        points_used: located.points_used,
        pose,
        resolved_by_prior,
        frames: in_frames,
        estimate_us: located.estimate_us,
    }
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Standard deviations of a track's predicted corners added around its region, on top of
/// the quiet zone: a code is inside its crop with a probability of 99.7 % per corner.
const REGION_SIGMAS: f64 = 3.0;

/// Room around a predicted code for its quiet zone (4 modules: a tenth or more of the side
/// of every version up to 10) and for the crop reads, which fail on a code cut at its edge,
/// as a share of the code's longest predicted side.
const REGION_QUIET_SHARE: f64 = 0.3;

/// The crop around a track's predicted corners ([`REGION_SIGMAS`], [`REGION_QUIET_SHARE`]).
fn search_region(region: &qrpose_track::PredictedRegion) -> SearchRegion {
    let c = &region.corners_px;
    let longest_side_px = (0..4)
        .map(|i| (c[i].0 - c[(i + 1) % 4].0).norm())
        .fold(0.0, f64::max);
    SearchRegion::Quad {
        corners_px: *c,
        margin_px: REGION_SIGMAS * region.corner_sigma_px + REGION_QUIET_SHARE * longest_side_px,
    }
}

/// [`estimate_decoded`] restricted to crops around `regions`, the predicted places of a
/// stream's tracks ([`qrpose_detect::detect_in_regions`]): nothing outside them is read.
///
/// # Errors
/// None today (the crop reads use `auto`'s backends, always built); the signature is
/// [`estimate_decoded`]'s.
pub(super) fn estimate_in_regions(
    setup: &ImageSetup,
    image: &GrayImage,
    decode_ms: f64,
    regions: &[qrpose_track::PredictedRegion],
    cancel: CancelFlag,
) -> Result<ImageAnswer, ImageError> {
    let pose = &setup.pose;
    let options = setup.detect.options(image.pixels().len(), cancel);
    let detect_setup = qrpose_detect::pipeline::Setup {
        camera: pose.camera,
        sizes: pose.sizes(),
        solver: pose.solver,
    };
    let crops: Vec<SearchRegion> = regions.iter().map(search_region).collect();
    let located = locate_markers_in_regions(image, &detect_setup, &crops, &options);
    Ok(answer_of_located(setup, image, located, decode_ms))
}
