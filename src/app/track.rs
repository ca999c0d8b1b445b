//! One frame of a stream (`GET /v1/stream`, `qrpose track`): the photo's codes, as
//! [`super::estimate_image`] finds them, fed to the session's tracker (crate
//! `qrpose-track`), whose tracks resolve the planar ambiguity, smooth the poses and say
//! where to look in the next frame.
//!
//! Where to look: on a frame with live tracks the detector first reads crops around each
//! track's predicted corners ([`qrpose_detect::detect_in_regions`]); the whole frame is
//! searched on the first frame, every [`TrackSetup::full_search_every`] frames, on the frame
//! after a track was lost inside the image (not one that left the view), and on a frame whose crop reads missed a track not predicted
//! with confidence but predicted wholly inside the image. A code missed by its crop but
//! predicted with confidence, or predicted partly outside the image (leaving the view: no
//! search can read it), is `coasting`.
//! So a code that enters the view is found within `full_search_every` frames.
//!
//! **In the robot's frame** (`docs/pick.md`, Streams): with a camera whose pose in the robot
//! frame is known on each frame (a mount, and for a camera on the flange each frame's
//! `flange_pose`), a product stays still while the camera moves. Each track then also keeps
//! its code's last [`MAX_ROBOT_FRAMES`] poses in the robot frame and fuses them, weighted by
//! their covariances ([`qrpose_site::localize::fuse`], whose χ² gate flags a frame that
//! disagrees); the product and its grasps are planned from the fused pose, so a grasp
//! sharpens as the arm approaches. The fused pose is given the covariance of the sharpest
//! single frame, not the fusion's own: the frames of one approach share errors (the print,
//! the lens) that averaging does not remove, and a grasp's probability must not claim what
//! the frames cannot give.

use super::image::{ImageAnswer, ImageError, MarkerAnswer, estimate_decoded};
use super::prior::Prior;
use super::setup::ImageSetup;
use nalgebra::Matrix6;
use qrpose_core::estimate::reprojection::AMBIGUITY_PROBABILITY_THRESHOLD;
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::marker::CornerOrder;
use qrpose_core::geometry::quad::ImageQuad;
use qrpose_detect::cancel::CancelFlag;
use qrpose_detect::decode::{self, GrayImage};
use qrpose_site::localize::fuse;
use qrpose_site::pick::{ObjectPlan, PickOptions, camera_in_robot, plan_pick};
use qrpose_site::transform::{PoseWithCovariance, Rigid, fixed_then};
use qrpose_track::{
    Measurement, Outcome, PredictedRegion, TrackReport, TrackStatus, Tracker, TrackerParams,
};
use std::collections::{HashMap, VecDeque};
use std::time::Instant;

/// The default cadence of the full-frame search on frames with live tracks, frames: a new
/// code appears within this many frames (a third of a second at 30 fps).
pub const DEFAULT_FULL_SEARCH_EVERY: u32 = 10;

/// How many of a track's latest robot-frame poses are fused (module docs): a second at
/// 30 fps, and a bound on what a session keeps.
pub const MAX_ROBOT_FRAMES: usize = 30;

/// The corner noise the tracker fuses refined corners with, px per coordinate: the detector's
/// measured corner error on the rendered accuracy set (docs/detection.md, Current figures:
/// p90 0.129 px from the true corner), read as a 2-D Gaussian's radius at 90 %
/// (σ = 0.129 / √(2 ln 10)). Unrefined corners keep the solver's `corner_sigma_px`.
const REFINED_CORNER_SIGMA_PX: f64 = 0.06;

/// A validated stream setup: the image request of every frame and the tracker's parameters.
#[derive(Debug, Clone)]
pub struct TrackSetup {
    /// Camera, sizes, solver, detection: as for a photo.
    pub image: ImageSetup,
    /// The tracker's parameters, validated.
    pub tracker: TrackerParams,
    /// Search the whole frame at least every this many frames (≥ 1; 1: every frame).
    pub full_search_every: u32,
}

/// How a frame was searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Search {
    /// The whole frame, and why.
    Full(FullReason),
    /// Only the crops around the live tracks' predicted corners.
    Regions,
}

/// Why a frame was searched whole (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FullReason {
    /// No live track (the session's first frame, or every track lost).
    NoTracks,
    /// `full_search_every` frames since the last full-frame search.
    Cadence,
    /// A track was lost on the previous frame.
    TrackLost,
    /// No live track's predicted corners are in front of the camera.
    NoRegion,
    /// A crop read missed a track not predicted with confidence.
    MissedUnconfident,
}

/// One frame given to a session.
#[derive(Debug, Clone, Copy)]
pub struct FrameIn<'a> {
    /// JPEG or PNG bytes.
    pub bytes: &'a [u8],
    /// When the frame was captured, ms (the client's clock, or the session's).
    pub capture_time_ms: f64,
    /// This frame's prior; `None` for the setup's.
    pub prior: Option<Prior>,
    /// T_robot←flange when this frame was captured (`flange_pose`); `None`: the setup's.
    pub flange: Option<Rigid>,
}

/// A track's code in the robot frame, fused over its latest frames, and its product.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackInRobot {
    /// T_robot←marker: the fused pose, with the sharpest single frame's covariance.
    pub marker: PoseWithCovariance,
    /// Robot-frame poses fused.
    pub frames_fused: usize,
    /// The product the payload names, planned from the fused pose; `None` without a rule.
    pub object: Option<ObjectPlan>,
}

/// A frame's answer: the photo's answer, each code's track and every live track.
#[derive(Debug, Clone)]
pub struct TrackAnswer {
    /// As for a photo.
    pub image: ImageAnswer,
    /// Per marker of `image`, the track it went to.
    pub track_ids: Vec<Option<String>>,
    /// Every live track after this frame, and those lost by it (reported once).
    pub tracks: Vec<TrackReport>,
    /// How the frame was searched.
    pub search: Search,
    /// Per track id, its code in the robot frame (tracks whose camera is in the robot
    /// frame on this frame).
    pub in_robot: HashMap<String, TrackInRobot>,
}

/// A stream session's state: its setup and tracks.
#[derive(Debug)]
pub struct TrackSession {
    setup: TrackSetup,
    tracker: Tracker,
    /// Per track id, its code's latest robot-frame poses.
    robot_frames: HashMap<String, VecDeque<PoseWithCovariance>>,
    /// Frames since the last full-frame search.
    since_full: u32,
    /// The next frame searches the whole frame (the first one, or a track was lost).
    full_next: bool,
}

/// Why a session cannot start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackSetupError {
    /// A tracker parameter is out of its range.
    #[error(transparent)]
    Tracker(#[from] qrpose_track::ParamError),
    /// `full_search_every` is 0.
    #[error("full_search_every must be at least 1 frame")]
    FullSearchEvery,
}

impl TrackSession {
    /// A session with no tracks yet.
    ///
    /// # Errors
    /// [`TrackSetupError`] for parameters out of range.
    pub fn new(setup: TrackSetup) -> Result<Self, TrackSetupError> {
        if setup.full_search_every == 0 {
            return Err(TrackSetupError::FullSearchEvery);
        }
        let tracker = Tracker::new(setup.tracker)?;
        Ok(Self {
            setup,
            tracker,
            robot_frames: HashMap::new(),
            since_full: 0,
            full_next: true,
        })
    }

    /// The session's setup.
    pub fn setup(&self) -> &TrackSetup {
        &self.setup
    }

    /// Decodes one frame, finds its codes (in the predicted regions first, module docs),
    /// and updates the tracks; `cancel` stops detection before its next pass.
    ///
    /// # Errors
    /// [`ImageError`] for bytes that are not an image or are over the limits, or a detector
    /// not in this build; the tracks are untouched then (the frame does not count).
    pub fn frame(
        &mut self,
        input: &FrameIn<'_>,
        cancel: CancelFlag,
    ) -> Result<TrackAnswer, ImageError> {
        let started = Instant::now();
        let image = decode::decode_gray(input.bytes, &self.setup.image.decode)?;
        let decode_ms = started.elapsed().as_secs_f64() * 1e3;
        let mut setup = self.setup.image.clone();
        if input.prior.is_some() {
            setup.pose.prior = input.prior;
        }
        if input.flange.is_some() {
            setup.pose.pick.flange = input.flange;
        }
        let t_ms = input.capture_time_ms;
        let (answer, search) = self.search(&setup, &image, decode_ms, t_ms, cancel)?;
        let measurements: Vec<(usize, Measurement)> = answer
            .markers
            .iter()
            .enumerate()
            .filter_map(|(i, m)| measurement_of(m, &setup).map(|x| (i, x)))
            .collect();
        let only: Vec<Measurement> = measurements.iter().map(|(_, m)| m.clone()).collect();
        let update = match self.tracker.update(t_ms, &only) {
            Ok(update) => update,
            // A non-finite capture time: the frame's codes without tracking.
            Err(_) => {
                return Ok(TrackAnswer {
                    track_ids: vec![None; answer.markers.len()],
                    tracks: self.tracker.tracks(),
                    image: answer,
                    search,
                    in_robot: HashMap::new(),
                });
            }
        };
        let mut track_ids = vec![None; answer.markers.len()];
        for ((marker, _), assignment) in measurements.iter().zip(&update.assignments) {
            if assignment.outcome != Outcome::Unassigned
                && assignment.outcome != Outcome::TrackLimit
            {
                track_ids[*marker].clone_from(&assignment.track_id);
            }
        }
        self.since_full = if matches!(search, Search::Full(_)) {
            1
        } else {
            self.since_full + 1
        };
        let (width_px, height_px) = (image.width() as f64, image.height() as f64);
        self.full_next = update.tracks.iter().any(|t| {
            t.status == TrackStatus::Lost
                && lost_in_view(t, &setup.pose.camera, width_px, height_px)
        });
        let in_robot = self.fuse_in_robot(&setup, &answer, &track_ids, &update.tracks);
        Ok(TrackAnswer {
            image: answer,
            track_ids,
            tracks: update.tracks,
            search,
            in_robot,
        })
    }

    /// Adds each tracked code's robot-frame pose of this frame to its track's, forgets the
    /// lost tracks', and fuses each track's (module docs).
    fn fuse_in_robot(
        &mut self,
        setup: &ImageSetup,
        answer: &ImageAnswer,
        track_ids: &[Option<String>],
        tracks: &[TrackReport],
    ) -> HashMap<String, TrackInRobot> {
        for (marker, id) in answer.markers.iter().zip(track_ids) {
            let (Some(id), Some(pose)) = (id, marker.frames.in_robot) else {
                continue;
            };
            if pose.covariance.is_none() {
                continue;
            }
            let frames = self.robot_frames.entry(id.clone()).or_default();
            if frames.len() == MAX_ROBOT_FRAMES {
                frames.pop_front();
            }
            frames.push_back(pose);
        }
        for track in tracks {
            if track.status == TrackStatus::Lost {
                self.robot_frames.remove(&track.id);
            }
        }
        // The camera's pose in the robot frame now, taken as exact: the frames' poses carry
        // the mount's uncertainty already.
        let camera_now = setup.pose.site_camera.as_ref().and_then(|c| {
            camera_in_robot(c.camera_mount.as_ref(), setup.pose.pick.flange.as_ref())
        });
        tracks
            .iter()
            .filter(|t| t.status != TrackStatus::Lost)
            .filter_map(|track| {
                let frames = self.robot_frames.get(&track.id)?;
                let marker = fused(frames)?;
                let object = camera_now.and_then(|camera| {
                    let (_, rule) = setup.pose.site.as_deref()?.object_for(&track.payload)?;
                    let exact = PoseWithCovariance {
                        pose: camera.pose,
                        covariance: Some(Matrix6::zeros()),
                    };
                    let in_camera = fixed_then(&camera.pose.inverse(), &marker);
                    let mirror = (1.0 - track.branch_probability).clamp(0.0, 1.0);
                    let options = PickOptions {
                        min_grasp_probability: setup.pose.pick.min_grasp_probability,
                        pose_ambiguous: mirror >= AMBIGUITY_PROBABILITY_THRESHOLD,
                        not_converged: false,
                        high_reprojection_error: false,
                        alternative_probability: mirror,
                    };
                    plan_pick(&in_camera, rule, Some(&exact), &options).ok()
                });
                Some((
                    track.id.clone(),
                    TrackInRobot {
                        marker,
                        frames_fused: frames.len(),
                        object,
                    },
                ))
            })
            .collect()
    }

    /// Finds the frame's codes: in the live tracks' predicted regions, or in the whole
    /// frame (module docs).
    fn search(
        &self,
        setup: &ImageSetup,
        image: &GrayImage,
        decode_ms: f64,
        t_ms: f64,
        cancel: CancelFlag,
    ) -> Result<(ImageAnswer, Search), ImageError> {
        let due = if self.tracker.is_empty() {
            Some(FullReason::NoTracks)
        } else if self.full_next {
            Some(FullReason::TrackLost)
        } else if self.since_full >= self.setup.full_search_every {
            Some(FullReason::Cadence)
        } else {
            None
        };
        let regions = if due.is_some() {
            Vec::new()
        } else {
            self.tracker
                .predict_regions(t_ms, &setup.pose.camera)
                .unwrap_or_default()
        };
        if regions.is_empty() {
            let answer = estimate_decoded(setup, image, decode_ms, cancel)?;
            return Ok((answer, Search::Full(due.unwrap_or(FullReason::NoRegion))));
        }
        let answer =
            super::image::estimate_in_regions(setup, image, decode_ms, &regions, cancel.clone())?;
        if missed_unconfident(&regions, &answer, image) {
            let region_detect_ms = answer.timing.detect_ms;
            let mut answer = estimate_decoded(setup, image, decode_ms, cancel)?;
            // The frame's detection time counts both searches.
            answer.timing.detect_ms += region_detect_ms;
            return Ok((answer, Search::Full(FullReason::MissedUnconfident)));
        }
        Ok((answer, Search::Regions))
    }
}

/// Whether a region not predicted with confidence, and predicted wholly inside the image,
/// found no code of its payload: the whole frame must be searched for it. A code predicted
/// partly outside the image (leaving the view) cannot be read by any search; its track
/// coasts, and the cadence's full-frame search finds it if it stayed.
fn missed_unconfident(
    regions: &[PredictedRegion],
    answer: &ImageAnswer,
    image: &GrayImage,
) -> bool {
    let (width_px, height_px) = (image.width() as f64, image.height() as f64);
    regions.iter().any(|r| {
        !r.confident
            && r.predicted_inside(width_px, height_px)
            && !answer
                .markers
                .iter()
                .any(|m| m.code.candidate.text.as_deref() == Some(r.payload.as_str()))
    })
}

/// Whether a lost track's last pose puts its code wholly inside the image: lost there, it may
/// have been missed, and the next frame searches the whole frame for it; lost outside (it
/// left the view), no search can find it.
fn lost_in_view(track: &TrackReport, camera: &Camera, width_px: f64, height_px: f64) -> bool {
    let pose = track.pose.marker_to_camera(&track.marker);
    track.marker.object_points().iter().all(|m| {
        camera
            .project(&pose.transform(m))
            .is_some_and(|p| p.inside_image(width_px, height_px))
    })
}

/// The tracker's measurement of one code: its payload, corners and per-frame pose with
/// covariance (the `reprojection` method's); `None` for a code without one.
fn measurement_of(m: &MarkerAnswer, setup: &ImageSetup) -> Option<Measurement> {
    let (marker, _) = m.marker.as_ref()?;
    let estimate = m.pose.as_ref().ok()?;
    let quad = ImageQuad::try_new(*m.code.corners_px(), CornerOrder::Qr).ok()?;
    let sigma = if m.code.is_refined() {
        REFINED_CORNER_SIGMA_PX
    } else {
        setup.pose.solver.as_reprojection().corner_sigma_px
    };
    Measurement::from_estimate(
        m.code.candidate.text.clone(),
        marker,
        &quad,
        estimate,
        &setup.pose.camera,
        sigma,
    )
    .ok()
}

/// The fused pose of `frames` (each with a covariance) with the sharpest frame's covariance
/// (module docs); the frame itself when there is one.
fn fused(frames: &VecDeque<PoseWithCovariance>) -> Option<PoseWithCovariance> {
    let sharpest = frames
        .iter()
        .filter_map(|f| f.covariance)
        .min_by(|a, b| a.trace().total_cmp(&b.trace()))?;
    let poses: Vec<PoseWithCovariance> = frames.iter().copied().collect();
    let pose = match poses.as_slice() {
        [one] => one.pose,
        _ => fuse(&poses).ok()?.pose.pose,
    };
    Some(PoseWithCovariance {
        pose,
        covariance: Some(sharpest),
    })
}
