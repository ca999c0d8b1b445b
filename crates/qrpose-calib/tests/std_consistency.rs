//! The reported standard deviations against the errors they describe, when the points'
//! errors are shared by neighbours as a QR code's are (each module corner is the crossing of
//! two line fits over four modules): over seeded synthetic sets, the errors of fx, fy, cx and
//! cy divided by their reported standard deviations have an RMS near 1. With these sets the
//! independent-errors covariance s²·(JᵀWJ)⁻¹ gave RMS 2.65, 2.82, 1.74 and 1.66 (fx, fy,
//! cx, cy) and fails; the cluster-robust one (`qrpose_calib`'s covariance module) gives
//! 1.28, 1.38, 0.90 and 0.85.

mod support;

use qrpose_calib::{Correspondence, Options, View, calibrate};
use rand::SeedableRng;
use rand::rngs::StdRng;
use std::collections::HashMap;
use support::{
    CODE_MM, GOOD_POSITIONS, IMAGE, MODULES, ViewSpec, barrel_camera, gaussian, project_all,
    qr_target_mm,
};

/// Sets, each of the views at the first [`VIEWS`] of the good positions.
const SETS: u64 = 16;
const VIEWS: usize = 10;
/// The error every point of a 4 × 4-module patch shares, px per axis.
const SHARED_PX: f64 = 0.08;
/// Each point's own error, px per axis.
const OWN_PX: f64 = 0.04;
/// Modules a side of a patch whose points share an error.
const PATCH_MODULES: f64 = 4.0;

/// One set: the good positions' views with errors shared within patches.
fn correlated_set(seed: u64) -> Vec<View> {
    let camera = barrel_camera();
    let target = qr_target_mm();
    let module_mm = CODE_MM / f64::from(MODULES);
    let mut rng = StdRng::seed_from_u64(seed);
    GOOD_POSITIONS[..VIEWS]
        .iter()
        .map(|&at| {
            let pose = ViewSpec::good(at).draw(&camera, &target, &mut rng);
            let pixels = project_all(&camera, &pose, &target, 2.0).expect("inside");
            let mut shared: HashMap<(i64, i64), (f64, f64)> = HashMap::new();
            let points = target
                .iter()
                .zip(pixels)
                .map(|(m, p)| {
                    // Module coordinates from the top-left corner, then the patch (0-8).
                    #[allow(clippy::cast_possible_truncation)]
                    let patch = |x: f64| ((x + 0.5 * CODE_MM) / module_mm / PATCH_MODULES) as i64;
                    let key = (patch(m.x), patch(m.y));
                    let &mut (su, sv) = shared.entry(key).or_insert_with(|| {
                        (
                            SHARED_PX * gaussian(&mut rng),
                            SHARED_PX * gaussian(&mut rng),
                        )
                    });
                    let (ou, ov) = (OWN_PX * gaussian(&mut rng), OWN_PX * gaussian(&mut rng));
                    Correspondence::new(m.x, m.y, p.u() + su + ou, p.v() + sv + ov)
                })
                .collect();
            View { points }
        })
        .collect()
}

#[test]
fn normalised_errors_of_the_intrinsics_have_an_rms_near_one_with_correlated_point_errors() {
    let truth = barrel_camera();
    let mut squares = [0.0_f64; 4];
    for seed in 0..SETS {
        let r = calibrate(&correlated_set(1000 + seed), IMAGE, &Options::default())
            .expect("calibrates");
        assert_eq!(r.used_views().count(), VIEWS, "set {seed}");
        let c = &r.camera;
        let z = [
            (c.fx() - truth.fx()) / r.std.fx_px,
            (c.fy() - truth.fy()) / r.std.fy_px,
            (c.cx() - truth.cx()) / r.std.cx_px,
            (c.cy() - truth.cy()) / r.std.cy_px,
        ];
        for (s, z) in squares.iter_mut().zip(z) {
            *s += z * z;
        }
    }
    let rms: Vec<f64> = squares.iter().map(|s| (s / SETS as f64).sqrt()).collect();
    // For right standard deviations each RMS is that of 16 standard normal draws: within
    // 0.66-1.33 with 95 % probability, within [0.6, 1.6] with over 99 %.
    for (name, value) in ["fx", "fy", "cx", "cy"].iter().zip(&rms) {
        assert!(
            (0.6..=1.6).contains(value),
            "normalised error RMS of {name}: {value:.2} (all: {rms:.2?})"
        );
    }
}
