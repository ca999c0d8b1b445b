//! What the tracker answers: per measurement an [`Assignment`], per live track a
//! [`TrackReport`] with its [`TrackStatus`] and [`FilteredPose`], together a
//! [`FrameUpdate`]; and [`TrackError`].

use nalgebra::{Matrix6, Rotation3, Vector3};
use qrpose_core::geometry::{frames::MarkerToCamera, marker::Marker};
use thiserror::Error;

/// Why a frame was refused.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum TrackError {
    /// The capture time is NaN or infinite.
    #[error("capture time {0} ms is not finite")]
    NonFiniteTime(f64),
}

/// Where a track stands after a frame. Timing is in the crate README.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackStatus {
    /// Created by this frame (its first measurement).
    New,
    /// Updated (a measurement fused) by this frame.
    Tracking,
    /// Not updated by this frame: the pose is predicted to the frame's time.
    Coasting,
    /// Not updated for longer than `coast_ms`, or its prediction grew too uncertain:
    /// reported once, with its last prediction, then dropped.
    Lost,
}

impl TrackStatus {
    /// "new", "tracking", "coasting", "lost".
    pub fn as_str(self) -> &'static str {
        match self {
            TrackStatus::New => "new",
            TrackStatus::Tracking => "tracking",
            TrackStatus::Coasting => "coasting",
            TrackStatus::Lost => "lost",
        }
    }
}

/// A track's filtered pose at one time, in the per-frame pose's conventions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilteredPose {
    /// R, marker to camera.
    pub rotation: Rotation3<f64>,
    /// The marker centre in the camera frame, mm.
    pub centre_mm: Vector3<f64>,
    /// 6×6 covariance of (rx, ry, rz rad, a left rotation about the camera axes; x, y, z mm
    /// of the centre), including the spread of a planar ambiguity not yet resolved.
    pub covariance: Matrix6<f64>,
    /// Velocity of the marker centre, camera frame, mm/s.
    pub velocity_mm_s: Vector3<f64>,
    /// Angular velocity, camera axes, rad/s (Ṙ = [ω]×·R).
    pub angular_velocity_rad_s: Vector3<f64>,
}

impl FilteredPose {
    /// The pose as qrpose-core's `MarkerToCamera` (translation: corner P2, the marker
    /// frame's origin).
    pub fn marker_to_camera(&self, marker: &Marker) -> MarkerToCamera {
        marker.pose_centred_at(self.rotation, self.centre_mm)
    }
}

/// One live track after a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackReport {
    /// Stable id: "t1", "t2", … in order of creation.
    pub id: String,
    /// The payload that started the track.
    pub payload: String,
    /// The marker (its size) of the track's measurements.
    pub marker: Marker,
    /// Status after this frame.
    pub status: TrackStatus,
    /// Frames whose measurement was fused (the first one included).
    pub frames_seen: u32,
    /// `frames_seen` ≥ `confirm_frames`: more than one frame agrees on this code.
    pub confirmed: bool,
    /// The filtered pose at the frame's capture time (for a frame earlier than the track's
    /// latest, at the track's latest time).
    pub pose: FilteredPose,
    /// The time of `pose`, ms.
    pub time_ms: f64,
    /// The capture time of the last fused measurement, ms.
    pub last_update_ms: f64,
    /// The track, not the single frame, chose between the two planar poses: some fused
    /// frame was ambiguous alone (or the track took the frame's alternative), and the
    /// other branch now has probability below `ambiguity_probability`.
    pub ambiguity_resolved: bool,
    /// Probability, from the track's history, that the heavier of its planar-branch
    /// hypotheses is the right one (1 when only one is left). `pose` is that hypothesis,
    /// or, when the two overlap (one uncertain pose rather than two), their weighted mean.
    pub branch_probability: f64,
    /// Probability of the manoeuvring motion model (large process noise) against the
    /// steady one (at rest or at a constant velocity).
    pub manoeuvre_probability: f64,
}

/// What became of one measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// It started a new track.
    Created,
    /// It was fused into its track.
    Fused,
    /// It was associated with a track but fell outside the gate: not fused.
    GatedOut,
    /// Its track had gated out `restart_after_gated` measurements in a row: the track
    /// restarted from this one (same id).
    Restarted,
    /// Undecoded and near no track: no track.
    Unassigned,
    /// Decoded and near no track, but `max_tracks` tracks are live: no track.
    TrackLimit,
}

/// One measurement's fate, in the order the measurements were given.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// The track it went to (created, fused, gated out or restarted), if any.
    pub track_id: Option<String>,
    /// What happened.
    pub outcome: Outcome,
    /// The track fused this frame's alternative pose, not its best fit.
    pub picked_alternative: bool,
    /// The track's `ambiguity_resolved` after this measurement, and this frame was
    /// ambiguous alone or the track took its alternative.
    pub ambiguity_resolved: bool,
    /// Squared Mahalanobis distance of the four corners from the track's prediction (J at
    /// the update's optimum, 8 degrees of freedom; the least over its branches when gated
    /// out); `None` for a new track.
    pub innovation_d2: Option<f64>,
}

/// The answer to one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameUpdate {
    /// The frame's capture time, ms.
    pub time_ms: f64,
    /// Per measurement, in input order.
    pub assignments: Vec<Assignment>,
    /// Every live track after the frame, by id order of creation, plus those lost by this
    /// frame (status [`TrackStatus::Lost`], reported this once).
    pub tracks: Vec<TrackReport>,
}
