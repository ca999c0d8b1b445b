//! The reported pose covariance against the actual spread of estimates (seeded Monte Carlo).
//!
//! A 50 mm code 400 mm away, tilted 30° (unambiguous at this noise), seen by a 1280×720
//! camera with fx = 1000 px; 1000 draws of Gaussian corner noise with σ = 0.5 px. The
//! covariance each estimate reports (for `corner_sigma_px` = σ) is averaged and compared,
//! diagonal by diagonal, with the empirical covariance of the errors: a small rotation about
//! the camera axes (left of R) and the centre's position, as the covariance is defined.

use nalgebra::{Matrix6, Rotation3, Vector3, Vector6};
use qrpose::estimate::{ReprojectionParams, Solver, estimate_pose};
use qrpose::geometry::{
    camera::Camera,
    euler::EulerXyz,
    frames::{MarkerToCamera, PixelPoint},
    marker::{CornerOrder, Marker},
    quad::ImageQuad,
};
use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};

const DRAWS: usize = 1000;
const SIGMA_PX: f64 = 0.5;
/// With 1000 draws a variance is known to about ±9 % (2σ); allow 20 %.
const VARIANCE_RATIO_TOL: f64 = 0.2;

#[test]
fn reported_covariance_matches_the_spread_of_estimates() {
    let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("camera");
    let marker = Marker::try_new(50.0).expect("marker");
    let truth = MarkerToCamera::new(
        EulerXyz::from_degrees(30.0, -10.0, 15.0).to_rotation(),
        Vector3::new(-10.0, 20.0, 400.0),
    );
    let centre = truth.transform(&marker.centre()).0.coords;
    let exact = marker
        .object_points()
        .map(|m| camera.project(&truth.transform(&m)).expect("in front"));
    let noise = Normal::new(0.0, SIGMA_PX).expect("valid sigma");
    let mut rng = StdRng::seed_from_u64(11);
    let params = Solver::Reprojection(ReprojectionParams {
        corner_sigma_px: SIGMA_PX,
        ..ReprojectionParams::default()
    })
    .validate()
    .expect("a valid corner noise");
    let mut errors = Vec::with_capacity(DRAWS);
    let mut reported = Matrix6::zeros();
    for _ in 0..DRAWS {
        let noisy = exact.map(|p| {
            PixelPoint::new(
                p.u() + noise.sample(&mut rng),
                p.v() + noise.sample(&mut rng),
            )
        });
        let quad = ImageQuad::try_new(noisy, CornerOrder::Paper).expect("valid quad");
        let e = estimate_pose(&quad, &camera, &marker, &params).expect("pose");
        reported += e.diagnostics.covariance.expect("covariance") / DRAWS as f64;
        // R_est = exp([δ]×)·R_true, so δ is the rotation vector of R_est·R_trueᵀ.
        let delta: Rotation3<f64> = e.pose.rotation() * truth.rotation().inverse();
        let d = delta.scaled_axis();
        let c = e.centre_mm - centre;
        errors.push(Vector6::new(d.x, d.y, d.z, c.x, c.y, c.z));
    }
    let mean = errors.iter().sum::<Vector6<f64>>() / DRAWS as f64;
    let empirical = errors
        .iter()
        .map(|e| (e - mean) * (e - mean).transpose())
        .sum::<Matrix6<f64>>()
        / (DRAWS - 1) as f64;
    for i in 0..6 {
        let ratio = empirical[(i, i)] / reported[(i, i)];
        assert!(
            (ratio - 1.0).abs() < VARIANCE_RATIO_TOL,
            "parameter {i}: empirical / reported variance = {ratio:.3}"
        );
    }
    // The strongest correlation (tilt against depth) must also come out right.
    let corr = |m: &Matrix6<f64>, i: usize, j: usize| m[(i, j)] / (m[(i, i)] * m[(j, j)]).sqrt();
    let (i, j) = (0..6)
        .flat_map(|i| (0..i).map(move |j| (i, j)))
        .max_by(|a, b| {
            corr(&reported, a.0, a.1)
                .abs()
                .total_cmp(&corr(&reported, b.0, b.1).abs())
        })
        .expect("pairs");
    assert!(
        (corr(&empirical, i, j) - corr(&reported, i, j)).abs() < 0.1,
        "correlation of {i} and {j}"
    );
}
