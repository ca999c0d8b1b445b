//! From a photo to poses, as one library call: [`locate_markers`] finds and reads every QR
//! code in a decoded image, refines its corners, and solves each code's pose. This is what
//! `POST /v1/pose/image` and `qrpose estimate --image` run; the wire layer only turns its
//! result into JSON. [`locate_markers_in_regions`] does the same in the regions where a
//! video stream's tracks predict their codes, reading nothing else.
//!
//! A code whose pose cannot be solved is still returned, with a typed [`MarkerError`] in
//! place of the pose; it does not fail the other codes.
//!
//! Each code is solved once, at its own size: the caller's [`MarkerSizes`] gives the size of
//! a code from its payload (one [`Marker`] for every code, or a site's rules), and a code it
//! cannot size keeps its corners with [`MarkerError::UnknownSize`].
//!
//! The detector knows no camera, so it refines corners along straight sides. When the
//! setup's camera distorts, every code is refined again through its lens
//! ([`refine_corners_through`]; a fisheye bows the sides by pixels); without
//! distortion the detector's corners are used as they are.

use crate::refine::corners::{Lens, RefineStatus, refine_corners_through};
use crate::refine::finder_marker_points;
use crate::{
    Budget, DetectError, DetectedCode, Detection, DetectorChoice, PassReport, SearchRegion,
    decode::GrayImage, detect_in_regions, detect_within,
};
use qrpose_core::estimate::{
    EstimateError, PoseEstimate, ValidSolver, estimate_planar_points, estimate_pose,
};
use qrpose_core::geometry::{
    camera::Camera,
    frames::{MarkerPoint, PixelPoint},
    marker::{CornerOrder, Marker},
    quad::{ImageQuad, QuadError},
};
use std::time::Instant;
use thiserror::Error;

/// The size of each code, by its payload.
pub trait MarkerSizes {
    /// Where a size came from, reported with each code (`()` when there is one size).
    type Source: Copy + std::fmt::Debug + PartialEq;

    /// The printed code with `payload` (`None`: not decoded), and where its size came from;
    /// `None` when its size is unknown.
    fn marker_for(&self, payload: Option<&str>) -> Option<(Marker, Self::Source)>;
}

/// One size for every code.
impl MarkerSizes for Marker {
    type Source = ();

    fn marker_for(&self, _payload: Option<&str>) -> Option<(Marker, ())> {
        Some((*self, ()))
    }
}

/// What every code's pose is solved with: the camera of the photo, the printed codes' sizes
/// and the solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setup<S = Marker> {
    /// The camera that took the photo (pixel units).
    pub camera: Camera,
    /// The printed codes' sizes: a [`Marker`] when every code has the same one.
    pub sizes: S,
    /// The solver, validated.
    pub solver: ValidSolver,
}

/// Which image points a pose is solved from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Points {
    /// The symbol's four corners.
    #[default]
    Corners,
    /// The twelve outer corners of the three finder patterns, by the `reprojection` method
    /// with the solver's iteration limit, trace and corner noise; a code whose finder
    /// corners were not all measured falls back to its four corners.
    Finders,
}

/// How to look.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Options {
    /// Which detector backend(s).
    pub detector: DetectorChoice,
    /// Which points to solve from.
    pub points: Points,
    /// Effort and deadline of the detection.
    pub budget: Budget,
}

/// Why one code has no pose.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum MarkerError {
    /// The caller's [`MarkerSizes`] has no size for the code's payload: it is located and
    /// read, not solved.
    #[error("no marker size for this code")]
    UnknownSize,
    /// The code's four corners do not form a usable quadrilateral.
    #[error(transparent)]
    Corners(QuadError),
    /// The solver refused the points.
    #[error("{source}")]
    Estimate {
        /// The points it was given.
        points: Points,
        /// Why it refused.
        source: EstimateError,
    },
}

/// One code found in the photo.
#[derive(Debug, Clone, PartialEq)]
pub struct LocatedMarker<Src = ()> {
    /// The code as detected: payload, corners, refinement.
    pub code: DetectedCode,
    /// The code's size and where it came from; `None` when unknown (the pose is then
    /// [`MarkerError::UnknownSize`]).
    pub marker: Option<(Marker, Src)>,
    /// The points the pose was solved from.
    pub points_used: Points,
    /// The pose, or why there is none.
    pub pose: Result<PoseEstimate, MarkerError>,
    /// Time spent solving this code's pose, µs.
    pub estimate_us: f64,
}

/// Every code in the photo and the time each stage took.
#[derive(Debug, Clone, PartialEq)]
pub struct Located<Src = ()> {
    /// The codes, in the detector's order.
    pub markers: Vec<LocatedMarker<Src>>,
    /// Detection, reading and corner refinement, ms.
    pub detect_ms: f64,
    /// The detection passes that ran, in order.
    pub passes: Vec<PassReport>,
    /// The deadline stopped detection before every pass had run.
    pub budget_exhausted: bool,
    /// Pose estimation of every code, ms.
    pub estimate_ms: f64,
    /// Poses solved: one per code with a size, none for a code without one.
    pub solves: usize,
}

/// Finds, reads and refines every QR code in `image` and solves each one's pose, once, at
/// the size `setup.sizes` gives it.
///
/// # Errors
/// [`DetectError`] when the chosen detector is not in this build. Finding no code is not
/// an error (no markers), and neither is a code without a pose (its own [`MarkerError`]).
pub fn locate_markers<S: MarkerSizes>(
    image: &GrayImage,
    setup: &Setup<S>,
    options: &Options,
) -> Result<Located<S::Source>, DetectError> {
    let started = Instant::now();
    let detection = detect_within(image, options.detector, &options.budget)?;
    Ok(located(image, setup, options.points, detection, started))
}

/// [`locate_markers`] restricted to `regions` of `image` ([`detect_in_regions`]: crops of
/// the places where a stream's tracks predict their codes, read at a higher effort there,
/// nothing outside them), within `options.budget`, solving from `options.points`. The
/// regions are read by `auto`'s backends whatever `options.detector` says.
#[must_use]
pub fn locate_markers_in_regions<S: MarkerSizes>(
    image: &GrayImage,
    setup: &Setup<S>,
    regions: &[SearchRegion],
    options: &Options,
) -> Located<S::Source> {
    let started = Instant::now();
    let detection = detect_in_regions(image, regions, &options.budget);
    located(image, setup, options.points, detection, started)
}

/// The codes of `detection` (begun at `started`) refined through the camera's lens when it
/// has one, each solved at its size from `points`.
fn located<S: MarkerSizes>(
    image: &GrayImage,
    setup: &Setup<S>,
    points: Points,
    detection: Detection,
    started: Instant,
) -> Located<S::Source> {
    let (codes, log) = (detection.codes, detection.log);
    let codes = refined_through_lens(image, codes, &setup.camera);
    let detect_ms = ms_since(started);
    let started = Instant::now();
    let mut solves = 0;
    let markers = codes
        .into_iter()
        .map(|code| {
            let solving = Instant::now();
            let marker = setup.sizes.marker_for(code.candidate.text.as_deref());
            let (points_used, pose) = match &marker {
                Some((size, _)) => {
                    solves += 1;
                    solve(&code, setup, size, points)
                }
                None => (Points::Corners, Err(MarkerError::UnknownSize)),
            };
            LocatedMarker {
                code,
                marker,
                points_used,
                pose,
                estimate_us: solving.elapsed().as_secs_f64() * 1e6,
            }
        })
        .collect();
    Located {
        markers,
        detect_ms,
        passes: log.passes,
        budget_exhausted: log.budget_exhausted,
        estimate_ms: ms_since(started),
        solves,
    }
}

/// `codes` with their corners refined again through the lens of `camera`, when it has one;
/// a code whose refinement through the lens fails keeps the detector's straight-sided one.
/// Unchanged for a camera without distortion.
fn refined_through_lens(
    image: &GrayImage,
    codes: Vec<DetectedCode>,
    camera: &Camera,
) -> Vec<DetectedCode> {
    if Lens::of(camera).is_none() {
        return codes;
    }
    codes
        .into_iter()
        .map(|mut code| {
            // The detector's N (its own estimate when the backend gave none), not estimated
            // again.
            let n = code.refinement.module_count.or(code.candidate.module_count);
            let through_lens = refine_corners_through(image, &code.candidate.corners_px, n, camera);
            if through_lens.status == RefineStatus::Refined {
                code.refinement = through_lens;
            }
            code
        })
        .collect()
}

/// The pose of one code of size `marker` from the requested points (falling back to the
/// corners when the finder corners are incomplete), and the points used.
fn solve<S>(
    code: &DetectedCode,
    setup: &Setup<S>,
    marker: &Marker,
    points: Points,
) -> (Points, Result<PoseEstimate, MarkerError>) {
    let r = &code.refinement;
    if let (Points::Finders, Some(image), Some(n)) = (points, r.finder_corners_px, r.module_count) {
        let model = finder_marker_points(marker, n);
        let pose = estimate_planar_points(&model, &image, &setup.camera, marker, &setup.solver)
            .map_err(|source| MarkerError::Estimate {
                points: Points::Finders,
                source,
            });
        return (Points::Finders, pose);
    }
    let pose = ImageQuad::try_new(*code.corners_px(), CornerOrder::Qr)
        .map_err(MarkerError::Corners)
        .and_then(|quad| {
            estimate_pose(&quad, &setup.camera, marker, &setup.solver).map_err(|source| {
                MarkerError::Estimate {
                    points: Points::Corners,
                    source,
                }
            })
        });
    (Points::Corners, pose)
}

/// The model points and the measured image points of `located`'s pose: the twelve finder
/// corners or the four corners (in the paper's order P1..P4), as [`Points`] says; `None`
/// when the code was not solved from them (no size, or corners that are not a quadrilateral).
#[must_use]
pub fn observed_points<Src>(
    located: &LocatedMarker<Src>,
) -> Option<(Vec<MarkerPoint>, Vec<PixelPoint>)> {
    let (marker, _) = located.marker.as_ref()?;
    let r = &located.code.refinement;
    match located.points_used {
        Points::Finders => {
            let image = r.finder_corners_px?;
            let model = finder_marker_points(marker, r.module_count?);
            Some((model, image.to_vec()))
        }
        Points::Corners => {
            let quad = ImageQuad::try_new(*located.code.corners_px(), CornerOrder::Qr).ok()?;
            Some((marker.object_points().to_vec(), quad.paper_order().to_vec()))
        }
    }
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
