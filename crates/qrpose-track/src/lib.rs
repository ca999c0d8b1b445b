//! qrpose-track: tracks of QR-code poses over video frames.
//!
//! Each code becomes a track with a stable id ("t1", "t2", … in order of creation),
//! associated frame to frame by payload and by position. Its state is the pose (rotation and
//! marker centre) and velocity (linear and angular) with covariance, estimated by an
//! error-state Kalman filter on SO(3) × ℝ³ with three interacting motion models (at rest,
//! steady and manoeuvring); the measurement is the code's four corners with the corner
//! noise the caller states (whose pose covariance σ²·(JᵀJ)⁻¹ is the same information to
//! first order). The planar ambiguity of single frames is resolved by the
//! track's history: up to two branch hypotheses per track, weighed by how well each
//! predicts the frames, the lighter dropped once negligible. The crate README has the
//! model, the parameters, the guarantees measured on simulated sequences, and what a client
//! should do with each status.
//!
//! | module | owns |
//! |---|---|
//! | [`so3`] | logarithm map, left Jacobian, angle between rotations |
//! | `filter` | the error-state Kalman filter of one motion model: prediction, update |
//! | `imm` | the three motion models (at rest, steady, manoeuvring) of one hypothesis, interacting |
//! | `branches` | the planar-branch hypotheses of one track: choice, weights, merge, prune |
//! | `track` | one track: timing, status, restart |
//! | `tracker` | association, the per-frame cycle ([`Tracker::update`]) |
//! | `region` | predicted image regions ([`Tracker::predict_regions`]) |
//! | [`measurement`] | what a frame gives ([`Measurement`]) |
//! | [`params`] | [`TrackerParams`], defaults, validation |
//! | `report` | what the tracker answers ([`FrameUpdate`], [`TrackReport`]) |
//!
//! Conventions are qrpose-core's (`docs/conventions.md`): camera frame x right, y down,
//! z forward, mm; `p_cam = R·p_marker + t`; a pose covariance is over (rx, ry, rz rad, a
//! small rotation about the camera axes on the left of R; x, y, z mm of the marker centre);
//! times in ms of the caller's clock. Nothing here is asynchronous or does I/O.
//!
//! The crate README's example (a doctest) shows one frame's cycle: `predict_regions`,
//! [`Measurement::from_estimate`], [`Tracker::update`].

#![warn(missing_docs)]

mod branches;
mod filter;
mod imm;
pub mod measurement;
pub mod params;
mod region;
mod report;
pub mod so3;
mod track;
mod tracker;

pub use measurement::{Alternative, Measurement, MeasurementError, PoseCandidate};
pub use params::{CHI2_3DOF_999, CHI2_8DOF_999, Param, ParamError, TrackerParams};
pub use region::PredictedRegion;
pub use report::{
    Assignment, FilteredPose, FrameUpdate, Outcome, TrackError, TrackReport, TrackStatus,
};
pub use tracker::Tracker;

/// The README example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
