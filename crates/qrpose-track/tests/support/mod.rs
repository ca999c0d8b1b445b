//! Simulated corner sequences for the tracker's tests and for `examples/track_study.rs`:
//! a 50 mm code seen by a 1280×720 camera with fx = fy = 1000 px, at 0.4-1.5 m, standing
//! still or moving smoothly; its corners projected exactly, then noised (σ = 0.5 px, a
//! seeded `StdRng`), and solved per frame by qrpose-core's `reprojection` method.

#![allow(dead_code)]

use nalgebra::{Matrix6, Rotation3, Vector3, Vector6};
use qrpose_core::estimate::{PoseEstimate, ReprojectionParams, Solver, ValidSolver, estimate_pose};
use qrpose_core::geometry::frames::PixelPoint;
use qrpose_core::geometry::{
    camera::Camera,
    marker::{CornerOrder, Marker},
    quad::ImageQuad,
};
use qrpose_track::so3::{angle_between, log};
use qrpose_track::{Measurement, TrackReport, Tracker, TrackerParams};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// Frames per second of the simulated video.
pub const FPS: f64 = 30.0;
/// A pose more than this far from the truth is wrong, degrees.
pub const WRONG_DEG: f64 = 5.0;

/// Camera, marker, solver and corner noise.
pub struct Scene {
    pub camera: Camera,
    pub marker: Marker,
    pub solver: ValidSolver,
    /// The corner noise the estimates and the tracker are told, px.
    pub sigma_px: f64,
    /// The standard deviation of the noise drawn for each corner of each frame, px.
    pub white_sigma_px: f64,
    /// An error added to every frame's corners (paper order), px: a bias the frames share.
    pub bias_px: [[f64; 2]; 4],
    pub image_px: (f64, f64),
}

impl Scene {
    /// The standard scene of the tests.
    pub fn standard() -> Self {
        Self::with_corner_sigma(0.5)
    }

    /// The standard scene with corners noised (and fused) at `sigma_px`.
    pub fn with_corner_sigma(sigma_px: f64) -> Self {
        Self {
            camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("camera"),
            marker: Marker::try_new(50.0).expect("marker"),
            solver: Solver::Reprojection(ReprojectionParams {
                corner_sigma_px: sigma_px,
                ..ReprojectionParams::default()
            })
            .validate()
            .expect("solver"),
            sigma_px,
            white_sigma_px: sigma_px,
            bias_px: [[0.0; 2]; 4],
            image_px: (1280.0, 720.0),
        }
    }

    /// The noisy corners (paper order) of the marker at (rotation, centre); `None` when a
    /// corner leaves the image.
    pub fn corners(
        &self,
        rotation: &Rotation3<f64>,
        centre: &Vector3<f64>,
        rng: &mut StdRng,
    ) -> Option<[PixelPoint; 4]> {
        let pose = self.marker.pose_centred_at(*rotation, *centre);
        let noise = Normal::new(0.0, self.white_sigma_px).expect("sigma");
        let mut out = [PixelPoint::new(0.0, 0.0); 4];
        for (i, m) in self.marker.object_points().iter().enumerate() {
            let p = self.camera.project(&pose.transform(m))?;
            let [bu, bv] = self.bias_px[i];
            let (u, v) = (
                p.u() + bu + noise.sample(rng),
                p.v() + bv + noise.sample(rng),
            );
            if !(0.0..self.image_px.0).contains(&u) || !(0.0..self.image_px.1).contains(&v) {
                return None;
            }
            out[i] = PixelPoint::new(u, v);
        }
        Some(out)
    }

    /// One frame's estimate and measurement of the marker at (rotation, centre).
    pub fn observe(
        &self,
        rotation: &Rotation3<f64>,
        centre: &Vector3<f64>,
        payload: Option<&str>,
        rng: &mut StdRng,
    ) -> Option<(PoseEstimate, Measurement)> {
        let corners = self.corners(rotation, centre, rng)?;
        let quad = ImageQuad::try_new(corners, CornerOrder::Paper).ok()?;
        let e = estimate_pose(&quad, &self.camera, &self.marker, &self.solver).ok()?;
        let m = Measurement::from_estimate(
            payload.map(str::to_owned),
            &self.marker,
            &quad,
            &e,
            &self.camera,
            self.sigma_px,
        )
        .ok()?;
        Some((e, m))
    }
}

/// A smooth path of the code in the camera frame: sinusoids about a base pose.
#[derive(Debug, Clone, Copy)]
pub struct Motion {
    pub centre0: Vector3<f64>,
    pub rotation0: Rotation3<f64>,
    pub centre_amp_mm: Vector3<f64>,
    pub rotation_amp_rad: Vector3<f64>,
    pub freq_hz: f64,
    pub phase: Vector3<f64>,
}

impl Motion {
    /// A random base pose: centre at `distance_mm`, near the optical axis; tilt up to
    /// `max_tilt_deg` about an axis in the image plane; any roll. Standing still.
    pub fn still(rng: &mut StdRng, distance_mm: f64, max_tilt_deg: f64) -> Self {
        let z = distance_mm;
        let centre0 = Vector3::new(
            rng.gen_range(-0.15..0.15) * z,
            rng.gen_range(-0.08..0.08) * z,
            z,
        );
        let psi: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
        let tilt = rng.gen_range(0.0..max_tilt_deg).to_radians();
        let roll = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
        let rotation0 = Rotation3::new(Vector3::new(psi.cos(), psi.sin(), 0.0) * tilt)
            * Rotation3::new(Vector3::new(0.0, 0.0, roll));
        Self {
            centre0,
            rotation0,
            centre_amp_mm: Vector3::zeros(),
            rotation_amp_rad: Vector3::zeros(),
            freq_hz: 0.0,
            phase: Vector3::zeros(),
        }
    }

    /// A random smooth motion of the kind a robot's camera makes passing a code: the
    /// centre swings ±(10, 5, 20) % of the distance (approaching and backing off) and the
    /// rotation ±0.15 rad (8.6°) about each camera axis, at 0.1-0.2 Hz (peak speeds up to
    /// ~380 mm/s and ~11°/s per axis at 1.5 m).
    pub fn moving(rng: &mut StdRng, distance_mm: f64, max_tilt_deg: f64) -> Self {
        let m = Self::with_amplitudes(rng, distance_mm, max_tilt_deg, [0.10, 0.05, 0.20], 0.15);
        Self {
            freq_hz: m.freq_hz - 0.1,
            ..m
        }
    }

    /// A faster sway: ±(12, 6, 15) % of the distance and ±0.25 rad (14°) about each axis at
    /// 0.2-0.3 Hz (peak ~27°/s per axis): harsher than a robot passing codes.
    pub fn swaying(rng: &mut StdRng, distance_mm: f64, max_tilt_deg: f64) -> Self {
        Self::with_amplitudes(rng, distance_mm, max_tilt_deg, [0.12, 0.06, 0.15], 0.25)
    }

    /// Sinusoids about a random base pose: centre amplitudes as fractions of the distance,
    /// rotation amplitude in rad about each axis, frequency 0.2-0.3 Hz.
    fn with_amplitudes(
        rng: &mut StdRng,
        distance_mm: f64,
        max_tilt_deg: f64,
        centre_frac: [f64; 3],
        rotation_rad: f64,
    ) -> Self {
        let still = Self::still(rng, distance_mm, max_tilt_deg);
        let z = distance_mm;
        let mut phase = Vector3::zeros();
        for p in phase.iter_mut() {
            *p = rng.gen_range(0.0..std::f64::consts::TAU);
        }
        Self {
            centre_amp_mm: Vector3::from(centre_frac) * z,
            rotation_amp_rad: Vector3::repeat(rotation_rad),
            freq_hz: rng.gen_range(0.2..0.3),
            phase,
            ..still
        }
    }

    /// The true (rotation, centre) at `t_s`.
    pub fn truth(&self, t_s: f64) -> (Rotation3<f64>, Vector3<f64>) {
        let w = std::f64::consts::TAU * self.freq_hz * t_s;
        let s = Vector3::new(
            (w + self.phase.x).sin(),
            (w + self.phase.y).sin(),
            (w + self.phase.z).sin(),
        );
        let r = Rotation3::new(self.rotation_amp_rad.component_mul(&s)) * self.rotation0;
        (r, self.centre0 + self.centre_amp_mm.component_mul(&s))
    }
}

/// One frame of a single-code sequence.
#[derive(Debug, Clone)]
pub struct Record {
    pub truth_rotation: Rotation3<f64>,
    pub truth_centre: Vector3<f64>,
    pub single_rotation: Rotation3<f64>,
    pub single_centre: Vector3<f64>,
    pub single_ambiguous: bool,
    pub track: TrackReport,
    /// Wall time of the tracker's update for this frame, µs.
    pub update_us: f64,
}

/// Runs `frames` frames of `motion` through a tracker; frames whose corners leave the
/// image are skipped. The code's track must be the only one.
pub fn run(
    scene: &Scene,
    motion: &Motion,
    frames: usize,
    seed: u64,
    params: TrackerParams,
) -> Vec<Record> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut tracker = Tracker::new(params).expect("valid params");
    let mut out = Vec::new();
    for i in 0..frames {
        let t_s = i as f64 / FPS;
        let (r, c) = motion.truth(t_s);
        let Some((e, m)) = scene.observe(&r, &c, Some("A"), &mut rng) else {
            continue;
        };
        let started = std::time::Instant::now();
        let answer = tracker.update(t_s * 1000.0, &[m]).expect("finite time");
        let update_us = started.elapsed().as_secs_f64() * 1e6;
        let track = answer.tracks.into_iter().next().expect("one track");
        out.push(Record {
            truth_rotation: r,
            truth_centre: c,
            single_rotation: e.pose.rotation(),
            single_centre: e.centre_mm,
            single_ambiguous: e.diagnostics.ambiguity.is_some_and(|a| a.ambiguous),
            track,
            update_us,
        });
    }
    out
}

/// Rotation error of the filtered and the single-frame pose, degrees.
pub fn rotation_errors_deg(r: &Record) -> (f64, f64) {
    (
        angle_between(&r.track.pose.rotation, &r.truth_rotation).to_degrees(),
        angle_between(&r.single_rotation, &r.truth_rotation).to_degrees(),
    )
}

/// NEES of the filtered pose: eᵀP⁻¹e, e = (Log(R_true·R̂ᵀ), c_true − ĉ).
pub fn nees(r: &Record) -> f64 {
    let mut e = Vector6::zeros();
    e.fixed_rows_mut::<3>(0)
        .copy_from(&log(&(r.truth_rotation * r.track.pose.rotation.inverse())));
    e.fixed_rows_mut::<3>(3)
        .copy_from(&(r.truth_centre - r.track.pose.centre_mm));
    let p: Matrix6<f64> = r.track.pose.covariance;
    e.dot(&p.cholesky().expect("positive definite").solve(&e))
}

/// Spread of positions: √(mean |c − mean c|²), mm.
pub fn position_spread_mm(cs: &[Vector3<f64>]) -> f64 {
    let n = cs.len() as f64;
    let mean = cs.iter().sum::<Vector3<f64>>() / n;
    (cs.iter().map(|c| (c - mean).norm_squared()).sum::<f64>() / n).sqrt()
}

/// Spread of rotations about their mean (one Karcher step from the first), RMS degrees.
pub fn rotation_spread_deg(rs: &[Rotation3<f64>]) -> f64 {
    let n = rs.len() as f64;
    let mut mean = rs[0];
    for _ in 0..5 {
        let step = rs
            .iter()
            .map(|r| log(&(r * mean.inverse())))
            .sum::<Vector3<f64>>()
            / n;
        mean = Rotation3::new(step) * mean;
    }
    (rs.iter()
        .map(|r| angle_between(r, &mean).powi(2))
        .sum::<f64>()
        / n)
        .sqrt()
        .to_degrees()
}
