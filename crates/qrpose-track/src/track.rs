//! One track: identity, timing, status and its branch hypotheses.
//!
//! Time: a track's state has a time (ms, the caller's clock). A frame at t is predicted
//! from it with dt = (t − time)/1000 s; **dt ≤ 0** (a repeated or out-of-order time) is
//! taken as 0: no prediction, the measurement is fused at the track's time, which stays
//! the latest seen. Status after a frame: `new` (created by it), `tracking` (a measurement
//! fused or the track restarted), `coasting` (otherwise), `lost` when t − last update >
//! `coast_ms` or the predicted centre's largest standard deviation exceeds
//! `max_position_sigma_mm` (checked only for tracks not updated by the frame).
//!
//! The reported covariance is the filter's plus `frame_bias_share` × the latest fused
//! frame's own pose covariance: a frame's corner error is mostly a bias of the scene
//! (blur, print, the lens), the same in the next frame of a camera that has not moved,
//! which averaging frames does not remove. The filter's covariance shrinks with every frame
//! fused; the pose error of a still camera does not (docs/stream.md, Covariance).

use crate::branches::Branches;
use crate::filter::ProcessNoise;
use crate::imm::{AT_REST, MODES, STEADY};
use crate::measurement::Measurement;
use crate::params::TrackerParams;
use crate::report::{FilteredPose, Outcome, TrackReport, TrackStatus};
use nalgebra::{Matrix6, Vector3};
use qrpose_core::geometry::marker::Marker;

/// A track.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Track {
    pub id: String,
    pub payload: String,
    pub marker: Marker,
    pub branches: Branches,
    /// Time of the state, ms.
    pub time_ms: f64,
    pub last_update_ms: f64,
    pub frames_seen: u32,
    pub consecutive_gated: u32,
    /// Some fused frame was ambiguous alone, or the track took an alternative.
    pub history_decided: bool,
    pub status: TrackStatus,
    /// The latest fused frame's pose covariance (× `measurement_inflation` ×
    /// `frame_bias_share`): the error frames share, added to the reported covariance
    /// (module docs).
    pub frame_covariance: Matrix6<f64>,
}

/// The result of giving a track a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TrackFuse {
    pub outcome: Outcome,
    pub picked_alternative: bool,
    pub d2: Option<f64>,
}

/// The process noise of the three models (crate::imm): at rest (`steady_noise_factor`² ×
/// the densities), steady (`steady_noise_factor` ×) and manoeuvring.
pub(crate) fn noise_of(params: &TrackerParams) -> [ProcessNoise; MODES] {
    let manoeuvring = ProcessNoise {
        accel_psd: params.accel_psd_mm2_s3,
        angular_accel_psd: params.angular_accel_psd_rad2_s3,
    };
    let scaled = |factor: f64| ProcessNoise {
        accel_psd: manoeuvring.accel_psd * factor,
        angular_accel_psd: manoeuvring.angular_accel_psd * factor,
    };
    let f = params.steady_noise_factor;
    let mut noises = [manoeuvring; MODES];
    noises[AT_REST] = scaled(f * f);
    noises[STEADY] = scaled(f);
    noises
}

impl Track {
    /// A new track from its first measurement (decoded: `payload`).
    pub fn start(
        id: String,
        payload: String,
        m: &Measurement,
        t_ms: f64,
        params: &TrackerParams,
    ) -> Self {
        Self {
            id,
            payload,
            marker: m.marker,
            branches: Branches::start(m, params),
            time_ms: t_ms,
            last_update_ms: t_ms,
            frames_seen: 1,
            consecutive_gated: 0,
            history_decided: m.ambiguous,
            status: TrackStatus::New,
            frame_covariance: m.frame_covariance(params),
        }
    }

    /// Seconds from the state's time to `t_ms`, 0 when not later.
    fn dt_s(&self, t_ms: f64) -> f64 {
        ((t_ms - self.time_ms) / 1000.0).max(0.0)
    }

    /// Predicts the state to `t_ms` (no change when `t_ms` is not later).
    pub fn predict_to(&mut self, t_ms: f64, params: &TrackerParams) {
        self.branches.predict(
            self.dt_s(t_ms),
            &noise_of(params),
            params.mode_hold_ms / 1000.0,
        );
        self.time_ms = self.time_ms.max(t_ms);
        self.status = TrackStatus::Coasting;
    }

    /// The branches predicted to `t_ms`, without changing the track.
    pub fn predicted_branches(&self, t_ms: f64, params: &TrackerParams) -> Branches {
        self.branches.predicted(
            self.dt_s(t_ms),
            &noise_of(params),
            params.mode_hold_ms / 1000.0,
        )
    }

    /// Fuses a measurement already associated with this track; the state must have been
    /// predicted to `t_ms`.
    pub fn fuse(&mut self, m: &Measurement, t_ms: f64, params: &TrackerParams) -> TrackFuse {
        let before = self.branches.clone();
        let fused = self.branches.fuse(m, params);
        if !self.branches.is_finite() {
            // Numerically broken (not expected): keep the prediction, refuse the frame.
            self.branches = before;
            return self.gated(m, t_ms, params, fused.d2);
        }
        if !fused.any {
            return self.gated(m, t_ms, params, fused.d2);
        }
        self.consecutive_gated = 0;
        self.mark_updated(t_ms);
        self.frame_covariance = m.frame_covariance(params);
        self.history_decided |= m.ambiguous || fused.picked_alternative;
        TrackFuse {
            outcome: Outcome::Fused,
            picked_alternative: fused.picked_alternative,
            d2: fused.d2,
        }
    }

    fn mark_updated(&mut self, t_ms: f64) {
        self.frames_seen = self.frames_seen.saturating_add(1);
        self.last_update_ms = self.last_update_ms.max(t_ms);
        self.status = TrackStatus::Tracking;
    }

    /// A gated-out measurement: counted, and after `restart_after_gated` in a row the track
    /// restarts from it.
    fn gated(
        &mut self,
        m: &Measurement,
        t_ms: f64,
        params: &TrackerParams,
        d2: Option<f64>,
    ) -> TrackFuse {
        self.consecutive_gated += 1;
        if self.consecutive_gated < params.restart_after_gated {
            return TrackFuse {
                outcome: Outcome::GatedOut,
                picked_alternative: false,
                d2,
            };
        }
        self.branches = Branches::start(m, params);
        self.consecutive_gated = 0;
        self.frame_covariance = m.frame_covariance(params);
        self.history_decided = m.ambiguous;
        self.mark_updated(t_ms);
        TrackFuse {
            outcome: Outcome::Restarted,
            picked_alternative: false,
            d2,
        }
    }

    /// Whether the planar ambiguity is settled by the track's history.
    pub fn ambiguity_resolved(&self, params: &TrackerParams) -> bool {
        self.history_decided
            && 1.0 - self.branches.reported_probability() <= params.ambiguity_probability
    }

    /// Lost after a frame at `t_ms` that did not update it (module docs).
    pub fn is_lost(&self, t_ms: f64, params: &TrackerParams) -> bool {
        let p = self.branches.reported().pose_covariance();
        let largest_variance = p.fixed_view::<3, 3>(3, 3).symmetric_eigenvalues().max();
        t_ms - self.last_update_ms > params.coast_ms
            || largest_variance.sqrt() > params.max_position_sigma_mm
            || !largest_variance.is_finite()
    }

    /// The report of the track's current state.
    pub fn report(&self, params: &TrackerParams) -> TrackReport {
        let (f, covariance) = self.branches.reported_pose();
        TrackReport {
            id: self.id.clone(),
            payload: self.payload.clone(),
            marker: self.marker,
            status: self.status,
            frames_seen: self.frames_seen,
            confirmed: self.frames_seen >= params.confirm_frames,
            pose: FilteredPose {
                rotation: f.rotation,
                centre_mm: f.centre_mm,
                covariance: covariance + self.frame_covariance,
                velocity_mm_s: f.velocity_mm_s,
                angular_velocity_rad_s: f.angular_velocity_rad_s,
            },
            time_ms: self.time_ms,
            last_update_ms: self.last_update_ms,
            ambiguity_resolved: self.ambiguity_resolved(params),
            branch_probability: self.branches.reported_probability(),
            manoeuvre_probability: self.branches.manoeuvre_probability(),
        }
    }

    /// The reported centre and its covariance (for association).
    pub fn centre(&self) -> (Vector3<f64>, nalgebra::Matrix3<f64>) {
        let f = self.branches.reported();
        (
            f.centre_mm,
            f.covariance.fixed_view::<3, 3>(3, 3).into_owned(),
        )
    }
}
