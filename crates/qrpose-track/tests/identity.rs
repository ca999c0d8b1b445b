//! Track identity: one id per code over a sequence, codes with the same payload kept
//! apart, undecoded symbols given to the track they are near.

mod support;

use nalgebra::Vector3;
use qrpose_track::{Measurement, Outcome, TrackStatus, Tracker, TrackerParams};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::collections::BTreeMap;
use support::{FPS, Motion, Scene};

/// Two codes moving together (a camera passing a shelf), `offset_mm` apart.
fn pair(seed: u64, offset_mm: Vector3<f64>) -> (Motion, Motion) {
    let mut rng = StdRng::seed_from_u64(seed);
    let a = Motion::moving(&mut rng, 700.0, 40.0);
    let b = Motion {
        centre0: a.centre0 + offset_mm,
        ..a
    };
    (a, b)
}

/// Runs two codes for `frames` frames; each frame a code is read with probability
/// `read_share`. Returns, per code, the track ids its measurements went to.
fn run_pair(
    payloads: [&str; 2],
    offset_mm: Vector3<f64>,
    read_share: f64,
    seed: u64,
) -> [BTreeMap<String, usize>; 2] {
    let scene = Scene::standard();
    let (a, b) = pair(seed, offset_mm);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    let mut ids = [BTreeMap::new(), BTreeMap::new()];
    for i in 0..150 {
        let t_s = f64::from(i) / FPS;
        let mut ms: Vec<(usize, Measurement)> = Vec::new();
        for (k, motion) in [a, b].iter().enumerate() {
            let (r, c) = motion.truth(t_s);
            let read = rng.gen_bool(read_share);
            if let Some((_, m)) = scene.observe(&r, &c, Some(payloads[k]), &mut rng)
                && read
            {
                ms.push((k, m));
            }
        }
        // The order of the codes in a frame must not matter.
        if rng.gen_bool(0.5) {
            ms.reverse();
        }
        let list: Vec<Measurement> = ms.iter().map(|(_, m)| m.clone()).collect();
        let answer = tracker.update(t_s * 1000.0, &list).expect("finite");
        for ((k, _), assignment) in ms.iter().zip(&answer.assignments) {
            let id = assignment.track_id.clone().expect("every code has a track");
            *ids[*k].entry(id).or_default() += 1;
        }
        assert!(answer.tracks.iter().all(|t| t.status != TrackStatus::Lost));
    }
    ids
}

#[test]
fn each_code_keeps_one_id_over_a_sequence_read_in_three_frames_of_four() {
    for seed in 0..4 {
        let ids = run_pair(["A", "B"], Vector3::new(120.0, 10.0, 30.0), 0.75, seed);
        assert_eq!(ids[0].len(), 1, "{ids:?}");
        assert_eq!(ids[1].len(), 1, "{ids:?}");
        let mut both: Vec<&String> = ids.iter().flat_map(|m| m.keys()).collect();
        both.sort();
        assert_eq!(both, ["t1", "t2"], "{ids:?}");
    }
}

#[test]
fn two_codes_with_the_same_payload_stay_two_tracks() {
    for seed in 10..14 {
        let ids = run_pair(["SKU-1", "SKU-1"], Vector3::new(70.0, 0.0, 0.0), 0.9, seed);
        assert_eq!(ids[0].len(), 1, "{ids:?}");
        assert_eq!(ids[1].len(), 1, "{ids:?}");
        assert_ne!(ids[0].keys().next(), ids[1].keys().next(), "{ids:?}");
    }
}

#[test]
fn an_undecoded_symbol_near_a_track_is_that_tracks_measurement() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(20);
    let motion = Motion::moving(&mut rng, 800.0, 40.0);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    for i in 0..60 {
        let t_s = f64::from(i) / FPS;
        let (r, c) = motion.truth(t_s);
        // Decoded on every third frame only.
        let payload = (i % 3 == 0).then_some("A");
        let (_, m) = scene.observe(&r, &c, payload, &mut rng).expect("in view");
        let answer = tracker.update(t_s * 1000.0, &[m]).expect("finite");
        let a = &answer.assignments[0];
        assert_eq!(a.track_id.as_deref(), Some("t1"), "frame {i}");
        let expected = if i == 0 {
            Outcome::Created
        } else {
            Outcome::Fused
        };
        assert_eq!(a.outcome, expected, "frame {i}");
        assert_eq!(answer.tracks.len(), 1);
        assert_eq!(answer.tracks[0].frames_seen, i + 1);
    }
}

#[test]
fn an_undecoded_symbol_near_no_track_starts_nothing() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(21);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    let still = Motion::still(&mut rng, 600.0, 30.0);
    let (r, c) = still.truth(0.0);
    let (_, a) = scene.observe(&r, &c, Some("A"), &mut rng).expect("in view");
    tracker.update(0.0, &[a]).expect("finite");
    let far = c + Vector3::new(-200.0, 60.0, 0.0);
    let (_, unknown) = scene.observe(&r, &far, None, &mut rng).expect("in view");
    let answer = tracker.update(33.0, &[unknown]).expect("finite");
    assert_eq!(answer.assignments[0].outcome, Outcome::Unassigned);
    assert_eq!(answer.assignments[0].track_id, None);
    assert_eq!(answer.tracks.len(), 1);
    assert_eq!(answer.tracks[0].status, TrackStatus::Coasting);
}

#[test]
fn a_decoded_code_far_from_the_track_of_its_payload_starts_another() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(22);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    let still = Motion::still(&mut rng, 600.0, 30.0);
    let (r, c) = still.truth(0.0);
    let (_, near) = scene.observe(&r, &c, Some("A"), &mut rng).expect("in view");
    tracker.update(0.0, &[near]).expect("finite");
    let far = c + Vector3::new(-220.0, 0.0, 0.0);
    let (_, other) = scene
        .observe(&r, &far, Some("A"), &mut rng)
        .expect("in view");
    let answer = tracker.update(33.0, &[other]).expect("finite");
    assert_eq!(answer.assignments[0].outcome, Outcome::Created);
    assert_eq!(answer.assignments[0].track_id.as_deref(), Some("t2"));
    let ids: Vec<&str> = answer.tracks.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(ids, ["t1", "t2"]);
}
