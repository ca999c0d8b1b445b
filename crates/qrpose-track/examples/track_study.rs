//! The tracker on simulated sequences: wrong poses, jitter, lag and NEES against single
//! frames.
//!
//! `cargo run --release -p qrpose-track --example track_study [-- SEQUENCES [ACCEL_PSD ANGULAR_PSD [VELOCITY_SIGMA ANGULAR_VELOCITY_SIGMA [STEADY_FACTOR [CORNER_SIGMA_PX [MODE_HOLD_MS]]]]]]`
//!
//! A 50 mm code, 1280×720 camera with fx = 1000 px, corner noise σ = 0.5 px (seeded; or
//! CORNER_SIGMA_PX, the σ the corners are noised with and fused at),
//! 3 s at 30 fps per sequence, the code at 0.4-0.7, 0.7-1.1 and 1.1-1.5 m and:
//! `still` (tilt up to 60°), `moving` (a robot's camera passing: ±10/5/20 % of the
//! distance, ±8.6° about each axis, 0.1-0.2 Hz, base tilt up to 50°) or `swaying`
//! (±12/6/15 %, ±14°, 0.2-0.3 Hz, base tilt up to 45°). Per row: the share of single frames
//! flagged ambiguous; wrong poses (> 5° from the truth) from a track's 5th frame on,
//! filtered and single-frame on the same frames; while still, the mean over sequences of
//! the filtered / single-frame spread of position and of rotation; while moving, the mean
//! position error (filtered / single-frame); the mean NEES of the 6-dof filtered pose (6
//! when consistent). Wrong poses are also counted on the frames that view the code at
//! least 20° off its normal. `all` rows pool the three distance bands.

#[path = "../tests/support/mod.rs"]
mod support;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use support::{
    Motion, Record, Scene, WRONG_DEG, nees, position_spread_mm, rotation_errors_deg,
    rotation_spread_deg, run,
};

/// Frames per sequence.
const FRAMES: usize = 90;
/// Metrics start at a track's 5th frame.
const FROM_FRAME: u32 = 5;

#[derive(Default, Clone)]
struct Row {
    frames: usize,
    flagged: usize,
    wrong_filtered: usize,
    wrong_single: usize,
    oblique: usize,
    wrong_filtered_oblique: usize,
    wrong_single_oblique: usize,
    spread_ratio_pos: Vec<f64>,
    spread_ratio_rot: Vec<f64>,
    err_filtered_mm: f64,
    err_single_mm: f64,
    nees: Vec<f64>,
    update_us: Vec<f64>,
}

impl Row {
    fn add(&mut self, records: &[Record], still: bool) {
        let late: Vec<&Record> = records
            .iter()
            .filter(|r| r.track.frames_seen >= FROM_FRAME)
            .collect();
        for r in &late {
            let (filtered, single) = rotation_errors_deg(r);
            self.frames += 1;
            self.flagged += usize::from(r.single_ambiguous);
            self.wrong_filtered += usize::from(filtered > WRONG_DEG);
            self.wrong_single += usize::from(single > WRONG_DEG);
            if viewing_angle_deg(r) >= OBLIQUE_DEG {
                self.oblique += 1;
                self.wrong_filtered_oblique += usize::from(filtered > WRONG_DEG);
                self.wrong_single_oblique += usize::from(single > WRONG_DEG);
            }
            self.nees.push(nees(r));
            self.update_us.push(r.update_us);
            self.err_filtered_mm += (r.track.pose.centre_mm - r.truth_centre).norm();
            self.err_single_mm += (r.single_centre - r.truth_centre).norm();
        }
        if still && late.len() > 10 {
            let fc: Vec<_> = late.iter().map(|r| r.track.pose.centre_mm).collect();
            let sc: Vec<_> = late.iter().map(|r| r.single_centre).collect();
            let fr: Vec<_> = late.iter().map(|r| r.track.pose.rotation).collect();
            let sr: Vec<_> = late.iter().map(|r| r.single_rotation).collect();
            self.spread_ratio_pos
                .push(position_spread_mm(&fc) / position_spread_mm(&sc));
            self.spread_ratio_rot
                .push(rotation_spread_deg(&fr) / rotation_spread_deg(&sr));
        }
    }

    fn merge(&mut self, other: &Row) {
        self.frames += other.frames;
        self.flagged += other.flagged;
        self.wrong_filtered += other.wrong_filtered;
        self.wrong_single += other.wrong_single;
        self.oblique += other.oblique;
        self.wrong_filtered_oblique += other.wrong_filtered_oblique;
        self.wrong_single_oblique += other.wrong_single_oblique;
        self.spread_ratio_pos.extend(&other.spread_ratio_pos);
        self.spread_ratio_rot.extend(&other.spread_ratio_rot);
        self.err_filtered_mm += other.err_filtered_mm;
        self.err_single_mm += other.err_single_mm;
        self.nees.extend(&other.nees);
        self.update_us.extend(&other.update_us);
    }

    fn print(&self, kind: &str, band: &str) {
        let n = self.frames.max(1) as f64;
        let pct = |x: usize| 100.0 * x as f64 / n;
        let spread = if self.spread_ratio_pos.is_empty() {
            String::new()
        } else {
            format!(
                "{:.2} / {:.2}",
                mean(&self.spread_ratio_pos),
                mean(&self.spread_ratio_rot)
            )
        };
        let error = if kind == "still" {
            String::new()
        } else {
            format!(
                "{:.2} / {:.2} mm ({:.2})",
                self.err_filtered_mm / n,
                self.err_single_mm / n,
                self.err_filtered_mm / self.err_single_mm
            )
        };
        let o = self.oblique.max(1) as f64;
        println!(
            "| {kind} | {band} | {} | {:.1} % | {:.2} % | {:.2} % | {:.2} % / {:.2} % of {:.0} % | {spread} | {error} | {:.2} |",
            self.frames,
            pct(self.flagged),
            pct(self.wrong_filtered),
            pct(self.wrong_single),
            100.0 * self.wrong_filtered_oblique as f64 / o,
            100.0 * self.wrong_single_oblique as f64 / o,
            pct(self.oblique),
            mean(&self.nees),
        );
    }
}

/// Views at least this far off the code's normal are counted apart, degrees: nearer a
/// frontal view, a small distant code's tilt is barely observable (README).
const OBLIQUE_DEG: f64 = 20.0;

/// The angle between the line of sight to the code's centre and its normal, degrees.
fn viewing_angle_deg(r: &Record) -> f64 {
    let normal = r.truth_rotation * nalgebra::Vector3::z();
    normal
        .dot(&r.truth_centre.normalize())
        .abs()
        .acos()
        .to_degrees()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let sequences: u64 = args.first().map_or(Ok(60), |s| s.parse())?;
    // The simulated corners err independently frame to frame: no shared bias.
    let mut params = qrpose_track::TrackerParams {
        frame_bias_share: 0.0,
        ..qrpose_track::TrackerParams::default()
    };
    if let (Some(a), Some(b)) = (args.get(1), args.get(2)) {
        params.accel_psd_mm2_s3 = a.parse()?;
        params.angular_accel_psd_rad2_s3 = b.parse()?;
    }
    if let (Some(a), Some(b)) = (args.get(3), args.get(4)) {
        params.initial_velocity_sigma_mm_s = a.parse()?;
        params.initial_angular_velocity_sigma_rad_s = b.parse()?;
    }
    if let Some(f) = args.get(5) {
        params.steady_noise_factor = f.parse()?;
    }
    if let Some(ms) = args.get(7) {
        params.mode_hold_ms = ms.parse()?;
    }
    let scene = match args.get(6) {
        Some(s) => Scene::with_corner_sigma(s.parse()?),
        None => Scene::standard(),
    };
    println!(
        "{sequences} sequences of {FRAMES} frames per band; corner σ = {} px; q_a = {} mm²/s³, q_α = {} rad²/s³, steady factor {}, mode hold {} ms, initial σ_v = {} mm/s, σ_ω = {} rad/s",
        scene.sigma_px,
        params.accel_psd_mm2_s3,
        params.angular_accel_psd_rad2_s3,
        params.steady_noise_factor,
        params.mode_hold_ms,
        params.initial_velocity_sigma_mm_s,
        params.initial_angular_velocity_sigma_rad_s
    );
    println!(
        "| motion | distance (m) | frames | flagged | wrong filtered | wrong single | wrong filtered / single, viewed ≥ {OBLIQUE_DEG}° off the normal (share of frames) | still spread pos / rot | moving error filtered / single | NEES |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (m, kind) in ["still", "moving", "swaying"].into_iter().enumerate() {
        let mut all = Row::default();
        for (k, (lo, hi)) in [(400.0, 700.0), (700.0, 1100.0), (1100.0, 1500.0)]
            .into_iter()
            .enumerate()
        {
            let mut row = Row::default();
            for s in 0..sequences {
                let seed = 1000 * (k as u64 + 1) + s + 500_000 * m as u64;
                let mut rng = StdRng::seed_from_u64(seed);
                let d = rng.gen_range(lo..hi);
                let motion = match kind {
                    "still" => Motion::still(&mut rng, d, 60.0),
                    "moving" => Motion::moving(&mut rng, d, 50.0),
                    _ => Motion::swaying(&mut rng, d, 45.0),
                };
                row.add(&run(&scene, &motion, FRAMES, seed, params), kind == "still");
            }
            row.print(kind, &format!("{:.1}-{:.1}", lo / 1000.0, hi / 1000.0));
            all.merge(&row);
        }
        all.print(kind, "all");
        let mut us = all.update_us.clone();
        us.sort_by(f64::total_cmp);
        println!(
            "{kind}: tracker update per frame (one code): median {:.0} µs, mean {:.0} µs",
            us.get(us.len() / 2).copied().unwrap_or(f64::NAN),
            mean(&us)
        );
    }
    Ok(())
}
