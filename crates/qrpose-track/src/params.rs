//! The tracker's parameters, their defaults and their ranges ([`TrackerParams`],
//! [`TrackerParams::validate`], [`ParamError`]).
//!
//! Units are in the names: `_mm`, `_ms`, `_px`, `_rad`; a spectral density of a white
//! acceleration is in (unit/s²)²·s = unit²/s³. The defaults were chosen with
//! `cargo run --release -p qrpose-track --example track_study` on simulated sequences of a
//! 50 mm code at 0.4-1.5 m (the crate README has the numbers).

use std::fmt;
use thiserror::Error;

/// χ² with 8 degrees of freedom at 99.9 %: the default gate on a frame's four corners.
pub const CHI2_8DOF_999: f64 = 26.124;
/// χ² with 3 degrees of freedom at 99.9 %: the default position gate of association.
pub const CHI2_3DOF_999: f64 = 16.266;

/// Every parameter of the tracker. Build with struct update syntax from
/// [`TrackerParams::default`]; [`crate::Tracker::new`] validates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerParams {
    /// Spectral density q_a of the white linear acceleration of a marker centre in the
    /// manoeuvring model, mm²/s³, per camera axis (constant velocity). After t seconds
    /// without measurements the velocity's standard deviation has grown by √(q_a·t) mm/s.
    /// Default 10⁵ (316 mm/s after one second).
    pub accel_psd_mm2_s3: f64,
    /// Spectral density q_α of the white angular acceleration in the manoeuvring model,
    /// rad²/s³, per camera axis. Default 1 (1 rad/s = 57°/s after one second).
    pub angular_accel_psd_rad2_s3: f64,
    /// The steady model (a constant velocity) has `steady_noise_factor` × both densities,
    /// the at-rest model (velocities held at zero) `steady_noise_factor`² × (crate::imm).
    /// Range (0, 1], default 0.01.
    pub steady_noise_factor: f64,
    /// Mean time the motion stays in one model (steady, or manoeuvring), ms: the switch
    /// probability over dt is 1 − exp(−dt / mode_hold_ms). Default 500.
    pub mode_hold_ms: f64,
    /// Factor on the measurement noise: the corners' variance σ² (σ the solver's
    /// `corner_sigma_px`) and the per-frame pose covariance a track starts from, which is
    /// σ²·(JᵀJ)⁻¹ of the same corners. 1 when the stated corner noise is right; default 1,
    /// range (0, 10⁴].
    pub measurement_inflation: f64,
    /// The share of a frame's pose covariance that is an error consecutive frames share (a
    /// bias of the scene: blur, print, lens), which fusing frames does not average away:
    /// the reported covariance is the filter's plus this share of the latest fused frame's
    /// covariance (crate::track). 0 when each frame's corners err independently (simulated
    /// corners); default 1, for corners found in camera images, whose error on the rendered
    /// videos is almost all shared (a still camera's corners move by about a sixth of
    /// their error from the truth; docs/stream.md). Range [0, 1].
    pub frame_bias_share: f64,
    /// A measurement whose four corners have a squared Mahalanobis distance from the
    /// prediction (J at the update's optimum, 8 degrees of freedom) above this is not
    /// fused. Default [`CHI2_8DOF_999`].
    pub gate_chi2: f64,
    /// A measurement can be a track's only if the squared Mahalanobis distance (3 degrees
    /// of freedom) of its marker centre from the track's predicted centre is at most this
    /// (or, when both carry the same payload, it is within
    /// [`association_distance_mm`](Self::association_distance_mm)). Default
    /// [`CHI2_3DOF_999`].
    pub association_gate_chi2: f64,
    /// A decoded measurement whose centre is this close to a predicted track with its
    /// payload belongs to it even outside the statistical gate; an undecoded measurement
    /// must be within this distance *and* the gate. mm, default 150.
    pub association_distance_mm: f64,
    /// A track not updated for more than this long is lost, ms. Default 500.
    pub coast_ms: f64,
    /// A coasting track whose predicted centre has a standard deviation above this (the
    /// largest axis) is lost, mm. Default 150.
    pub max_position_sigma_mm: f64,
    /// Live tracks at most; a new code beyond this starts no track. Default 64.
    pub max_tracks: usize,
    /// A track is `confirmed` (trusted) once this many frames updated it. Default 2.
    pub confirm_frames: u32,
    /// After this many consecutive frames whose measurement of the track fell outside the
    /// gate, the track restarts from the measurement (same id). Default 3.
    pub restart_after_gated: u32,
    /// Standard deviation of a new track's linear velocity (its mean is 0), mm/s.
    /// Default 300.
    pub initial_velocity_sigma_mm_s: f64,
    /// Standard deviation of a new track's angular velocity (its mean is 0), rad/s.
    /// Default 0.1 (5.7°/s): a larger one lets the first frames' rotation noise of a small
    /// distant code pass for a spin.
    pub initial_angular_velocity_sigma_rad_s: f64,
    /// A planar-branch hypothesis whose probability falls below this is dropped. Range
    /// (0, 0.1], default 10⁻⁶.
    pub branch_prune_probability: f64,
    /// The planar ambiguity counts as resolved when the other branch has at most this
    /// probability (qrpose-core's per-frame threshold). Range (0, 0.5), default 0.01.
    pub ambiguity_probability: f64,
    /// A predicted region whose corners have a standard deviation above this is not
    /// `confident`, px. Default 10.
    pub confident_corner_sigma_px: f64,
}

impl Default for TrackerParams {
    fn default() -> Self {
        Self {
            accel_psd_mm2_s3: 1e5,
            angular_accel_psd_rad2_s3: 1.0,
            steady_noise_factor: 0.01,
            mode_hold_ms: 500.0,
            measurement_inflation: 1.0,
            frame_bias_share: 1.0,
            gate_chi2: CHI2_8DOF_999,
            association_gate_chi2: CHI2_3DOF_999,
            association_distance_mm: 150.0,
            coast_ms: 500.0,
            max_position_sigma_mm: 150.0,
            max_tracks: 64,
            confirm_frames: 2,
            restart_after_gated: 3,
            initial_velocity_sigma_mm_s: 300.0,
            initial_angular_velocity_sigma_rad_s: 0.1,
            branch_prune_probability: 1e-6,
            ambiguity_probability: 0.01,
            confident_corner_sigma_px: 10.0,
        }
    }
}

/// A parameter, by its name in [`TrackerParams`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[allow(missing_docs)]
pub enum Param {
    AccelPsd,
    AngularAccelPsd,
    SteadyNoiseFactor,
    ModeHoldMs,
    MeasurementInflation,
    FrameBiasShare,
    GateChi2,
    AssociationGateChi2,
    AssociationDistance,
    CoastMs,
    MaxPositionSigma,
    MaxTracks,
    ConfirmFrames,
    RestartAfterGated,
    InitialVelocitySigma,
    InitialAngularVelocitySigma,
    BranchPruneProbability,
    AmbiguityProbability,
    ConfidentCornerSigma,
}

impl Param {
    /// The field's name in [`TrackerParams`].
    pub fn name(self) -> &'static str {
        match self {
            Param::AccelPsd => "accel_psd_mm2_s3",
            Param::AngularAccelPsd => "angular_accel_psd_rad2_s3",
            Param::SteadyNoiseFactor => "steady_noise_factor",
            Param::ModeHoldMs => "mode_hold_ms",
            Param::MeasurementInflation => "measurement_inflation",
            Param::FrameBiasShare => "frame_bias_share",
            Param::GateChi2 => "gate_chi2",
            Param::AssociationGateChi2 => "association_gate_chi2",
            Param::AssociationDistance => "association_distance_mm",
            Param::CoastMs => "coast_ms",
            Param::MaxPositionSigma => "max_position_sigma_mm",
            Param::MaxTracks => "max_tracks",
            Param::ConfirmFrames => "confirm_frames",
            Param::RestartAfterGated => "restart_after_gated",
            Param::InitialVelocitySigma => "initial_velocity_sigma_mm_s",
            Param::InitialAngularVelocitySigma => "initial_angular_velocity_sigma_rad_s",
            Param::BranchPruneProbability => "branch_prune_probability",
            Param::AmbiguityProbability => "ambiguity_probability",
            Param::ConfidentCornerSigma => "confident_corner_sigma_px",
        }
    }
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A parameter outside its range.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
#[error(
    "tracker parameter {param} = {value} is outside {}{min}, {max}]",
    if *min_included { "[" } else { "(" }
)]
pub struct ParamError {
    /// The parameter.
    pub param: Param,
    /// The value given (integers converted).
    pub value: f64,
    /// Values must be greater than this (or equal, when `min_included`).
    pub min: f64,
    /// Whether `min` itself is allowed.
    pub min_included: bool,
    /// Values must be at most this.
    pub max: f64,
}

/// The range (min exclusive, max inclusive) of each real parameter but
/// [`Param::FrameBiasShare`], whose range is [0, 1].
const RANGES: [(Param, f64, f64); 15] = [
    (Param::AccelPsd, 0.0, 1e12),
    (Param::AngularAccelPsd, 0.0, 1e6),
    (Param::SteadyNoiseFactor, 0.0, 1.0),
    (Param::ModeHoldMs, 0.0, 3.6e6),
    (Param::MeasurementInflation, 0.0, 1e4),
    (Param::GateChi2, 0.0, 1e6),
    (Param::AssociationGateChi2, 0.0, 1e6),
    (Param::AssociationDistance, 0.0, 1e6),
    (Param::CoastMs, 0.0, 3.6e6),
    (Param::MaxPositionSigma, 0.0, 1e6),
    (Param::InitialVelocitySigma, 0.0, 1e6),
    (Param::InitialAngularVelocitySigma, 0.0, 1e3),
    (Param::BranchPruneProbability, 0.0, 0.1),
    (Param::AmbiguityProbability, 0.0, 0.499),
    (Param::ConfidentCornerSigma, 0.0, 1e6),
];

/// Largest accepted `max_tracks`, `confirm_frames` and `restart_after_gated`.
pub const MAX_COUNT: u32 = 10_000;

impl TrackerParams {
    fn real(&self, param: Param) -> f64 {
        match param {
            Param::AccelPsd => self.accel_psd_mm2_s3,
            Param::AngularAccelPsd => self.angular_accel_psd_rad2_s3,
            Param::SteadyNoiseFactor => self.steady_noise_factor,
            Param::ModeHoldMs => self.mode_hold_ms,
            Param::MeasurementInflation => self.measurement_inflation,
            Param::FrameBiasShare => self.frame_bias_share,
            Param::GateChi2 => self.gate_chi2,
            Param::AssociationGateChi2 => self.association_gate_chi2,
            Param::AssociationDistance => self.association_distance_mm,
            Param::CoastMs => self.coast_ms,
            Param::MaxPositionSigma => self.max_position_sigma_mm,
            Param::InitialVelocitySigma => self.initial_velocity_sigma_mm_s,
            Param::InitialAngularVelocitySigma => self.initial_angular_velocity_sigma_rad_s,
            Param::BranchPruneProbability => self.branch_prune_probability,
            Param::AmbiguityProbability => self.ambiguity_probability,
            Param::ConfidentCornerSigma => self.confident_corner_sigma_px,
            Param::MaxTracks => self.max_tracks as f64,
            Param::ConfirmFrames => f64::from(self.confirm_frames),
            Param::RestartAfterGated => f64::from(self.restart_after_gated),
        }
    }

    /// Checks every parameter against its range: the real-valued ones first, then the
    /// counts.
    ///
    /// # Errors
    /// [`ParamError`] for the first parameter outside its range (or not finite); the
    /// counts `max_tracks`, `confirm_frames` and `restart_after_gated` must be in
    /// 1..=[`MAX_COUNT`].
    pub fn validate(&self) -> Result<(), ParamError> {
        for (param, min, max) in RANGES {
            let value = self.real(param);
            if !(value.is_finite() && value > min && value <= max) {
                return Err(ParamError {
                    param,
                    value,
                    min,
                    min_included: false,
                    max,
                });
            }
        }
        if !(0.0..=1.0).contains(&self.frame_bias_share) {
            return Err(ParamError {
                param: Param::FrameBiasShare,
                value: self.frame_bias_share,
                min: 0.0,
                min_included: true,
                max: 1.0,
            });
        }
        for param in [
            Param::MaxTracks,
            Param::ConfirmFrames,
            Param::RestartAfterGated,
        ] {
            let value = self.real(param);
            if !(value >= 1.0 && value <= f64::from(MAX_COUNT)) {
                return Err(ParamError {
                    param,
                    value,
                    min: 1.0,
                    min_included: true,
                    max: f64::from(MAX_COUNT),
                });
            }
        }
        Ok(())
    }
}
