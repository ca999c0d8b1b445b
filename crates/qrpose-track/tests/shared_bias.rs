//! Corners whose error is mostly a bias the frames share, as the detector's corners on a
//! camera's images are (a still camera's corners move by a fraction of their error from the
//! truth): a code standing still at 0.4-1.5 m, each corner offset by a bias drawn once per
//! sequence (σ 0.06 px, the detector's measured corner error) plus a little noise drawn per
//! frame (σ 0.01 px), fused at σ 0.06 px. Averaging frames removes the noise, not the
//! bias: the reported covariance must not shrink below the bias's (crate::track,
//! `frame_bias_share`), or the filtered pose claims a precision it does not have.

mod support;

use qrpose_track::TrackerParams;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use support::{Motion, Record, Scene, nees, run};

const SEQUENCES: u64 = 12;
const FRAMES: usize = 90;
const FROM_FRAME: u32 = 5;
const BIAS_SIGMA_PX: f64 = 0.06;
const WHITE_SIGMA_PX: f64 = 0.01;

/// Every still sequence's records under `params`.
fn still_sequences(params: TrackerParams) -> Vec<Vec<Record>> {
    let mut out = Vec::new();
    for (k, (lo, hi)) in [(400.0, 700.0), (700.0, 1100.0), (1100.0, 1500.0)]
        .into_iter()
        .enumerate()
    {
        for s in 0..SEQUENCES {
            let seed = 9_100_000 + 10_000 * k as u64 + s;
            let mut rng = StdRng::seed_from_u64(seed);
            let bias = Normal::new(0.0, BIAS_SIGMA_PX).expect("sigma");
            let mut scene = Scene::with_corner_sigma(BIAS_SIGMA_PX);
            scene.white_sigma_px = WHITE_SIGMA_PX;
            for corner in &mut scene.bias_px {
                *corner = [bias.sample(&mut rng), bias.sample(&mut rng)];
            }
            let d = rng.gen_range(lo..hi);
            let motion = Motion::still(&mut rng, d, 60.0);
            out.push(run(&scene, &motion, FRAMES, seed, params));
        }
    }
    out
}

fn mean_nees(sequences: &[Vec<Record>]) -> f64 {
    let values: Vec<f64> = sequences
        .iter()
        .flatten()
        .filter(|r| r.track.frames_seen >= FROM_FRAME)
        .map(nees)
        .collect();
    values.iter().sum::<f64>() / values.len() as f64
}

#[test]
fn with_a_shared_corner_bias_the_reported_covariance_stays_consistent() {
    let defaults = mean_nees(&still_sequences(TrackerParams::default()));
    let without_floor = mean_nees(&still_sequences(TrackerParams {
        frame_bias_share: 0.0,
        ..TrackerParams::default()
    }));
    eprintln!(
        "mean NEES (6 dof): default {defaults:.2}, without the shared share {without_floor:.2}"
    );
    assert!((3.0..=12.0).contains(&defaults), "mean NEES {defaults}");
    assert!(
        without_floor > 12.0,
        "the filter's covariance alone would be consistent too: {without_floor}"
    );
}
