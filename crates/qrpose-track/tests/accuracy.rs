//! The filter against single frames on simulated sequences (tests/support): a 50 mm code,
//! fx = 1000 px, 1280×720, corner noise σ = 0.5 px, 3 s at 30 fps, at 0.4-0.7, 0.7-1.1 and
//! 1.1-1.5 m, standing still (tilt up to 60°) or moving as a robot's camera passing it.
//! Seeds differ from those the defaults were chosen on (`examples/track_study.rs`).
//! `cargo run --release -p qrpose-track --example track_study` prints the same measures
//! on more sequences.

mod support;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::sync::OnceLock;
use support::{
    Motion, Record, Scene, WRONG_DEG, nees, position_spread_mm, rotation_errors_deg,
    rotation_spread_deg, run,
};

/// Sequences per distance band and kind of motion.
const SEQUENCES: u64 = 12;
/// Frames per sequence.
const FRAMES: usize = 90;
/// Measures start at a track's 5th frame.
const FROM_FRAME: u32 = 5;
/// Views at least this far off the code's normal, degrees (see `off_frontal`).
const OBLIQUE_DEG: f64 = 20.0;

/// Every simulated sequence, run once for all tests: (still, records) per sequence.
fn sequences() -> &'static [(bool, Vec<Record>)] {
    static RUNS: OnceLock<Vec<(bool, Vec<Record>)>> = OnceLock::new();
    RUNS.get_or_init(|| {
        let scene = Scene::standard();
        let mut out = Vec::new();
        for still in [true, false] {
            for (k, (lo, hi)) in [(400.0, 700.0), (700.0, 1100.0), (1100.0, 1500.0)]
                .into_iter()
                .enumerate()
            {
                for s in 0..SEQUENCES {
                    let seed = 7_000_000 + 10_000 * k as u64 + s + if still { 0 } else { 500 };
                    let mut rng = StdRng::seed_from_u64(seed);
                    let d = rng.gen_range(lo..hi);
                    let motion = if still {
                        Motion::still(&mut rng, d, 60.0)
                    } else {
                        Motion::moving(&mut rng, d, 50.0)
                    };
                    // The simulated corners err independently frame to frame: no
                    // shared bias to add to the reported covariance (tests/shared_bias.rs
                    // has corners that share one).
                    let params = qrpose_track::TrackerParams {
                        frame_bias_share: 0.0,
                        ..qrpose_track::TrackerParams::default()
                    };
                    out.push((still, run(&scene, &motion, FRAMES, seed, params)));
                }
            }
        }
        out
    })
}

/// Frames from a track's 5th frame on, of every sequence.
fn late_frames() -> impl Iterator<Item = &'static Record> {
    sequences()
        .iter()
        .flat_map(|(_, records)| records.iter())
        .filter(|r| r.track.frames_seen >= FROM_FRAME)
}

/// The angle between the line of sight to the code and its normal, degrees.
fn viewing_angle_deg(r: &Record) -> f64 {
    let normal = r.truth_rotation * nalgebra::Vector3::z();
    normal
        .dot(&r.truth_centre.normalize())
        .abs()
        .acos()
        .to_degrees()
}

/// (filtered, single-frame) shares of poses more than 5° off, and the frame count.
fn wrong_rates<'a>(frames: impl Iterator<Item = &'a Record>) -> (f64, f64, usize) {
    let (mut filtered, mut single, mut n) = (0, 0, 0);
    for r in frames {
        let (f, s) = rotation_errors_deg(r);
        filtered += usize::from(f > WRONG_DEG);
        single += usize::from(s > WRONG_DEG);
        n += 1;
    }
    (filtered as f64 / n as f64, single as f64 / n as f64, n)
}

#[test]
fn single_frames_in_these_sequences_are_as_ambiguous_as_the_issue_says() {
    let frames: Vec<&Record> = late_frames().collect();
    let flagged = frames.iter().filter(|r| r.single_ambiguous).count() as f64;
    let share = flagged / frames.len() as f64;
    eprintln!("flagged ambiguous: {share:.3} of {} frames", frames.len());
    assert!((0.45..0.65).contains(&share), "{share}");
}

#[test]
fn from_a_tracks_fifth_frame_wrong_poses_are_at_most_a_third_of_single_frames() {
    let (filtered, single, n) = wrong_rates(late_frames());
    eprintln!("wrong from the 5th frame: filtered {filtered:.4}, single {single:.4} ({n} frames)");
    assert!(n > 5000, "{n} frames");
    assert!(single > 0.15, "single frames wrong {single}");
    assert!(
        filtered <= single / 3.0,
        "filtered {filtered} vs single {single}"
    );
}

#[test]
fn off_frontal_views_have_at_most_one_percent_wrong_poses_from_the_fifth_frame() {
    // Within 20° of a frontal view a small distant code's tilt barely moves its corners
    // (README, Guarantees): there the filter's covariance, not its pose, tells the truth.
    let oblique = late_frames().filter(|r| viewing_angle_deg(r) >= OBLIQUE_DEG);
    let (filtered, single, n) = wrong_rates(oblique);
    eprintln!(
        "wrong, views ≥ 20° off normal: filtered {filtered:.4}, single {single:.4} ({n} frames)"
    );
    assert!(n > 3000, "{n} frames");
    assert!(filtered <= 0.01, "filtered {filtered} (single {single})");
    assert!(
        filtered <= single / 3.0,
        "filtered {filtered} vs single {single}"
    );
}

#[test]
fn standing_still_the_filtered_spread_is_at_most_half_the_single_frame_spread() {
    let (mut position, mut rotation, mut n) = (0.0, 0.0, 0.0);
    for (_, records) in sequences().iter().filter(|(still, _)| *still) {
        let late: Vec<&Record> = records
            .iter()
            .filter(|r| r.track.frames_seen >= FROM_FRAME)
            .collect();
        let fc: Vec<_> = late.iter().map(|r| r.track.pose.centre_mm).collect();
        let sc: Vec<_> = late.iter().map(|r| r.single_centre).collect();
        let fr: Vec<_> = late.iter().map(|r| r.track.pose.rotation).collect();
        let sr: Vec<_> = late.iter().map(|r| r.single_rotation).collect();
        position += position_spread_mm(&fc) / position_spread_mm(&sc);
        rotation += rotation_spread_deg(&fr) / rotation_spread_deg(&sr);
        n += 1.0;
    }
    let (position, rotation) = (position / n, rotation / n);
    eprintln!("still spread filtered / single: position {position:.3}, rotation {rotation:.3}");
    assert!(position <= 0.5, "position spread ratio {position}");
    assert!(rotation <= 0.5, "rotation spread ratio {rotation}");
}

#[test]
fn moving_the_filtered_position_error_is_at_most_one_and_a_half_single_frame_errors() {
    let (mut filtered, mut single) = (0.0, 0.0);
    for (_, records) in sequences().iter().filter(|(still, _)| !*still) {
        for r in records.iter().filter(|r| r.track.frames_seen >= FROM_FRAME) {
            filtered += (r.track.pose.centre_mm - r.truth_centre).norm();
            single += (r.single_centre - r.truth_centre).norm();
        }
    }
    eprintln!(
        "moving position error filtered / single: {:.3}",
        filtered / single
    );
    assert!(
        filtered <= 1.5 * single,
        "filtered {filtered} vs single {single}"
    );
}

#[test]
fn the_filtered_pose_covariance_is_consistent() {
    let values: Vec<f64> = late_frames().map(nees).collect();
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    eprintln!("mean NEES {mean:.2} over {} frames", values.len());
    assert!((3.0..=12.0).contains(&mean), "mean NEES {mean} (6 dof)");
}

#[test]
fn every_filtered_number_is_finite() {
    for r in sequences().iter().flat_map(|(_, records)| records) {
        let p = &r.track.pose;
        assert!(p.centre_mm.iter().all(|x| x.is_finite()));
        assert!(p.covariance.iter().all(|x| x.is_finite()));
        assert!(p.velocity_mm_s.iter().all(|x| x.is_finite()));
        assert!(p.angular_velocity_rad_s.iter().all(|x| x.is_finite()));
        assert!(p.rotation.matrix().iter().all(|x| x.is_finite()));
    }
}
