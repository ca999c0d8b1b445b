//! Is the reported covariance right? Standard deviations it predicts against the spread of
//! 2000 seeded noisy estimates, for a few views (σ = 0.5 px, 1280×720, fx = 1000 px, 50 mm).
//!
//! The covariance describes the spread around the pose that was found. When the planar
//! ambiguity picks the mirror pose instead (a jump of many degrees, flagged by
//! `ambiguity.ambiguous` and priced by `alternative_probability`), no covariance describes
//! it; the spread is therefore measured over the draws that found the true candidate, and
//! the mirror picks are counted separately with how many of them were flagged.
//!
//! `cargo run --release --example covariance_check`

use nalgebra::{Matrix6, Vector3, Vector6};
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

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5)?;
    let marker = Marker::try_new(50.0)?;
    let sigma = 0.5;
    let views = [
        (
            "400 mm, tilted 30°",
            [30.0, -10.0, 15.0],
            [-10.0, 20.0, 400.0],
        ),
        (
            "800 mm, tilted 45°, off axis",
            [0.0, 45.0, 60.0],
            [150.0, -80.0, 800.0],
        ),
        (
            "250 mm, tilted 20°",
            [20.0, 5.0, -100.0],
            [30.0, 30.0, 250.0],
        ),
    ];
    println!("| view | parameter | predicted σ | observed σ | ratio |");
    println!("|---|---|---|---|---|");
    for (name, angles, p2) in views {
        let truth = MarkerToCamera::new(
            EulerXyz::from_degrees(angles[0], angles[1], angles[2]).to_rotation(),
            Vector3::from(p2),
        );
        let centre = truth.transform(&marker.centre()).0.coords;
        let exact = marker
            .object_points()
            .map(|m| camera.project(&truth.transform(&m)));
        let exact: Vec<PixelPoint> = exact
            .into_iter()
            .collect::<Option<_>>()
            .ok_or("behind the camera")?;
        let noise = Normal::new(0.0, sigma)?;
        let mut rng = StdRng::seed_from_u64(3);
        let params = Solver::Reprojection(ReprojectionParams {
            corner_sigma_px: sigma,
            ..ReprojectionParams::default()
        })
        .validate()
        .expect("a valid corner noise");
        let (mut errors, mut reported, n) = (Vec::new(), Matrix6::zeros(), 2000);
        let (mut mirror, mut mirror_flagged) = (0, 0);
        for _ in 0..n {
            let noisy: [PixelPoint; 4] = std::array::from_fn(|i| {
                PixelPoint::new(
                    exact[i].u() + noise.sample(&mut rng),
                    exact[i].v() + noise.sample(&mut rng),
                )
            });
            let e = estimate_pose(
                &ImageQuad::try_new(noisy, CornerOrder::Paper)?,
                &camera,
                &marker,
                &params,
            )?;
            let a = e.diagnostics.ambiguity.ok_or("no ambiguity")?;
            let own = qrpose::geometry::euler::angle_between(&e.pose.rotation(), &truth.rotation());
            if own
                > qrpose::geometry::euler::angle_between(
                    &a.alternative.rotation(),
                    &truth.rotation(),
                )
            {
                mirror += 1;
                mirror_flagged += usize::from(a.ambiguous);
                continue;
            }
            reported += e.diagnostics.covariance.ok_or("no covariance")?;
            let d = (e.pose.rotation() * truth.rotation().inverse()).scaled_axis();
            let c = e.centre_mm - centre;
            errors.push(Vector6::new(d.x, d.y, d.z, c.x, c.y, c.z));
        }
        let kept = errors.len() as f64;
        reported /= kept;
        let mean = errors.iter().sum::<Vector6<f64>>() / kept;
        let empirical = errors
            .iter()
            .map(|e| (e - mean) * (e - mean).transpose())
            .sum::<Matrix6<f64>>()
            / (kept - 1.0);
        println!(
            "| {name} | mirror picks | {mirror} of {n} draws | {mirror_flagged} of them flagged ambiguous | |"
        );
        for (i, label) in ["rx (°)", "ry (°)", "rz (°)", "x (mm)", "y (mm)", "z (mm)"]
            .iter()
            .enumerate()
        {
            let scale = if i < 3 {
                180.0 / std::f64::consts::PI
            } else {
                1.0
            };
            let (p, o) = (
                reported[(i, i)].sqrt() * scale,
                empirical[(i, i)].sqrt() * scale,
            );
            println!("| {name} | {label} | {p:.4} | {o:.4} | {:.2} |", o / p);
        }
    }
    Ok(())
}
