//! [`calibrate`]: the views in, a [`CameraCalibration`] out. Checks the input, finds each
//! view's homography (views without one are dropped), fits ([`crate::fit`]), drops the
//! worst view while one fits far worse than the rest and refits from the closed form
//! without it, then computes the standard deviations, the coverage and the warnings.
//!
//! A view "fits far worse" when its median residual length exceeds
//! max([`DROP_RATIO`] × the median over the views of that median, [`DROP_FLOOR_PX`]). The
//! median (not the RMS) judges the view as a whole: a few outlying points are the robust
//! loss's business and should not cost a good view.

use crate::covariance::{BLOCKS_PER_SIDE, intrinsic_covariance};
use crate::error::{CalibrationError, SolveFailure};
use crate::fit::{self, Fit};
use crate::input::{ImageSize, MIN_VIEWS, Options, View, validate};
use crate::lm::{self, ViewData};
use crate::result::{
    CameraCalibration, DropReason, ParameterStd, ViewFit, ViewOutcome, ViewReport,
};
use crate::robust::median;
use crate::warnings::{Coverage, Evidence, warnings};
use nalgebra::{Matrix3, Vector2};
use qrpose_core::geometry::frames::{MarkerToCamera, PixelPoint};
use qrpose_core::geometry::homography::fit_homography_dlt;

/// A view is dropped when its median residual exceeds this multiple of the views' median
/// (and [`DROP_FLOOR_PX`]): three times the typical view is no longer noise.
pub const DROP_RATIO: f64 = 3.0;

/// A view whose median residual is within this is never dropped, px: sub-pixel points from
/// blurred or compressed photos have medians up to about half a pixel, and a set of very
/// sharp photos should not shed its slightly softer ones.
pub const DROP_FLOOR_PX: f64 = 1.0;

/// Calibrates a camera from `views` of one planar target, all `image` in size.
///
/// # Errors
/// [`CalibrationError::InvalidImageSize`], [`CalibrationError::NonFinite`] and
/// [`CalibrationError::TooFewPoints`] for bad input; [`CalibrationError::TooFewViews`] when
/// fewer than [`MIN_VIEWS`] views are given or remain after dropping;
/// [`CalibrationError::SolveFailed`] when the closed form finds no focal length or the
/// refinement cannot proceed.
///
/// # Example
/// ```
/// use qrpose_calib::{calibrate, Correspondence, ImageSize, Options, View};
/// use qrpose_core::geometry::camera::Camera;
/// use qrpose_core::geometry::frames::{CameraPoint, MarkerPoint, MarkerToCamera};
/// use nalgebra::{Point3, Rotation3, Vector3};
///
/// let truth = Camera::from_pixels(800.0, 800.0, 330.0, 235.0)?;
/// let views: Vec<View> = [(0.3, -0.2), (-0.35, 0.1), (0.1, 0.4), (-0.2, -0.3)]
///     .iter()
///     .map(|&(ax, ay)| {
///         let pose = MarkerToCamera::new(
///             Rotation3::from_euler_angles(ax, ay, 0.2),
///             Vector3::new(-40.0, -30.0, 400.0),
///         );
///         let points = (0..64)
///             .map(|i| {
///                 let (x, y) = (f64::from(i % 8) * 12.0, f64::from(i / 8) * 12.0);
///                 let seen = truth.project(&pose.transform(&MarkerPoint(Point3::new(x, y, 0.0))));
///                 let px = seen.expect("in front");
///                 Correspondence::new(x, y, px.u(), px.v())
///             })
///             .collect();
///         View { points }
///     })
///     .collect();
/// let result = calibrate(&views, ImageSize::new(640, 480), &Options::default())?;
/// assert!((result.camera.fx() - 800.0).abs() < 1e-6);
/// assert!((result.camera.cy() - 235.0).abs() < 1e-6);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn calibrate(
    views: &[View],
    image: ImageSize,
    options: &Options,
) -> Result<CameraCalibration, CalibrationError> {
    validate(views, image)?;
    let data: Vec<ViewData> = views
        .iter()
        .map(|v| ViewData {
            target_mm: v.points.iter().map(|c| c.target_mm).collect(),
            pixel_px: v.points.iter().map(|c| c.pixel_px.0.coords).collect(),
        })
        .collect();
    let mut dropped: Vec<Option<(DropReason, Option<ViewFit>)>> = vec![None; views.len()];
    let mut homographies: Vec<(usize, Matrix3<f64>)> = Vec::with_capacity(views.len());
    for (i, view) in data.iter().enumerate() {
        let pixels: Vec<_> = view.pixel_px.iter().map(|p| (*p).into()).collect();
        match fit_homography_dlt(&view.target_mm, &pixels).ok() {
            Some(h) => homographies.push((i, h)),
            None => dropped[i] = Some((DropReason::HomographyFailed, None)),
        }
    }
    loop {
        let active: Vec<(usize, Matrix3<f64>)> = homographies
            .iter()
            .filter(|(i, _)| dropped[*i].is_none())
            .copied()
            .collect();
        if active.len() < MIN_VIEWS {
            return Err(CalibrationError::TooFewViews {
                given: views.len(),
                usable: active.len(),
                required: MIN_VIEWS,
            });
        }
        let active_data: Vec<ViewData> = active.iter().map(|(i, _)| data[*i].clone()).collect();
        let hs: Vec<Matrix3<f64>> = active.iter().map(|(_, h)| *h).collect();
        let fit = fit::fit(&active_data, &hs, image, options)?;
        let fits = view_fits(&fit, &active_data)?;
        if let Some((worst, reason)) = worst_view(&fits) {
            let index = active[worst].0;
            dropped[index] = Some((reason, fits.into_iter().nth(worst)));
            continue;
        }
        let mut fits = fits.into_iter();
        let mut outcomes: Vec<ViewOutcome> = Vec::with_capacity(views.len());
        for (i, drop) in dropped.into_iter().enumerate() {
            outcomes.push(match drop {
                Some((reason, fit)) => ViewOutcome::Dropped { reason, fit },
                None if active.iter().any(|(a, _)| *a == i) => {
                    ViewOutcome::Used(fits.next().ok_or(SolveFailure::InvalidCamera)?)
                }
                None => return Err(SolveFailure::InvalidCamera.into()),
            });
        }
        return assemble(&fit, &active_data, outcomes, views, image);
    }
}

/// Each view's pose, residuals and weights under `fit`.
fn view_fits(fit: &Fit, views: &[ViewData]) -> Result<Vec<ViewFit>, SolveFailure> {
    let residuals = lm::residuals(&fit.state, views).ok_or(SolveFailure::InvalidCamera)?;
    residuals
        .into_iter()
        .zip(&fit.state.poses)
        .zip(views)
        .map(|((residuals_px, pose), view)| {
            let lengths: Vec<f64> = residuals_px.iter().map(Vector2::norm).collect();
            let n = lengths.len() as f64;
            let rms_px = (lengths.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
            let median_px = median(&lengths).ok_or(SolveFailure::InvalidCamera)?;
            Ok(ViewFit {
                pose: MarkerToCamera::new(pose.r, pose.t_mm),
                rms_px,
                median_px,
                measured_px: view
                    .pixel_px
                    .iter()
                    .map(|p| PixelPoint::new(p.x, p.y))
                    .collect(),
                weights: lengths.iter().map(|e| fit.loss.weight(*e)).collect(),
                residuals_px,
            })
        })
        .collect()
}

/// The view to drop, if any (module doc), with its reason.
fn worst_view(fits: &[ViewFit]) -> Option<(usize, DropReason)> {
    let medians: Vec<f64> = fits.iter().map(|f| f.median_px).collect();
    let limit_px = (DROP_RATIO * median(&medians)?).max(DROP_FLOOR_PX);
    let (worst, &median_px) = medians
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    (median_px > limit_px).then(|| {
        let rms_px = fits[worst].rms_px;
        (
            worst,
            DropReason::PoorFit {
                median_px,
                rms_px,
                limit_px,
            },
        )
    })
}

/// The standard deviations of the intrinsics ([`ParameterStd`]): the square roots of the
/// diagonal of the cluster-robust covariance of [`crate::covariance`] (clusters: patches of
/// each view's target), infinite where the data leave a parameter undetermined (a singular
/// system, or no more residuals than unknowns).
fn parameter_std(fit: &Fit, views: &[ViewData]) -> ParameterStd {
    let n_a = fit.state.intrinsics.count();
    let points: usize = views.iter().map(|v| v.target_mm.len()).sum();
    let unknowns = n_a + 6 * views.len();
    let covariance = (2 * points > unknowns)
        .then(|| intrinsic_covariance(&fit.state, views, fit.loss, BLOCKS_PER_SIDE))
        .flatten();
    let std: Vec<f64> = match covariance {
        Some(c) => (0..n_a)
            .map(|i| {
                let v = c[(i, i)];
                if v >= 0.0 { v.sqrt() } else { f64::INFINITY }
            })
            .collect(),
        None => vec![f64::INFINITY; n_a],
    };
    ParameterStd {
        fx_px: std[0],
        fy_px: std[1],
        cx_px: std[2],
        cy_px: std[3],
        coefficients: std[4..].to_vec(),
    }
}

fn assemble(
    fit: &Fit,
    active: &[ViewData],
    outcomes: Vec<ViewOutcome>,
    views: &[View],
    image: ImageSize,
) -> Result<CameraCalibration, CalibrationError> {
    let camera = fit
        .state
        .intrinsics
        .camera()
        .ok_or(SolveFailure::InvalidCamera)?;
    let std = parameter_std(fit, active);
    let lengths = fit::residual_lengths(&fit.state, active).ok_or(SolveFailure::InvalidCamera)?;
    let reprojection_rms_px =
        (lengths.iter().map(|e| e * e).sum::<f64>() / lengths.len() as f64).sqrt();
    let coverage = Coverage::of(active.iter().flat_map(|v| v.pixel_px.iter()), image);
    let rotations: Vec<_> = fit.state.poses.iter().map(|p| p.r).collect();
    let warnings = warnings(&Evidence {
        used_views: active.len(),
        rotations: &rotations,
        coverage: &coverage,
        focal: (camera.fx(), std.fx_px, camera.fy(), std.fy_px),
        assumption: fit.assumption,
        not_converged_after: (!fit.converged).then_some(fit.iterations),
    });
    let views = outcomes
        .into_iter()
        .zip(views)
        .enumerate()
        .map(|(index, (outcome, view))| ViewReport {
            index,
            points: view.points.len(),
            outcome,
        })
        .collect();
    Ok(CameraCalibration {
        camera,
        std,
        reprojection_rms_px,
        views,
        warnings,
        coverage,
        image_size: image,
        robust_sigma_px: fit.sigma_px,
        iterations: fit.iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::Correspondence;
    use crate::result::PointFit;
    use nalgebra::{Point3, Rotation3, Vector3};
    use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
    use qrpose_core::geometry::frames::MarkerPoint;

    /// The point of the first view made a gross outlier, and by how much, px.
    const OUTLIER: usize = 27;
    const OUTLIER_PX: f64 = 6.0;

    fn truth() -> Camera {
        let lens = Distortion::from_coefficients(
            DistortionModel::PlumbBob,
            &[-0.15, 0.04, 0.0008, -0.0004, 0.0],
        )
        .expect("a lens");
        Camera::from_pixels(820.0, 815.0, 331.0, 242.0)
            .expect("a camera")
            .with_distortion(lens)
    }

    /// Six tilted views of an 8 × 8 grid of 12 mm pitch, with a deterministic ±0.1 px
    /// wobble on every point and one gross outlier in view 0.
    fn views(camera: &Camera) -> Vec<View> {
        [
            (0.4, -0.2),
            (-0.45, 0.15),
            (0.1, 0.5),
            (-0.25, -0.4),
            (0.35, 0.3),
            (-0.1, -0.5),
        ]
        .iter()
        .enumerate()
        .map(|(k, &(ax, ay))| {
            let pose = MarkerToCamera::new(
                Rotation3::from_euler_angles(ax, ay, 0.3 * k as f64),
                Vector3::new(-42.0, -40.0, 380.0 + 15.0 * k as f64),
            );
            let points = (0..64)
                .map(|i| {
                    let (x, y) = (f64::from(i % 8) * 12.0, f64::from(i / 8) * 12.0);
                    let target = MarkerPoint(Point3::new(x, y, 0.0));
                    let seen = camera.project(&pose.transform(&target)).expect("in front");
                    let phase = f64::from(i) * 1.7 + k as f64;
                    let mut u = seen.u() + 0.1 * phase.sin();
                    if k == 0 && i as usize == OUTLIER {
                        u += OUTLIER_PX;
                    }
                    Correspondence::new(x, y, u, seen.v() + 0.1 * phase.cos())
                })
                .collect();
            View { points }
        })
        .collect()
    }

    #[test]
    fn each_points_residual_is_its_reprojection_minus_its_measurement() {
        let given = views(&truth());
        let result =
            calibrate(&given, ImageSize::new(660, 480), &Options::default()).expect("calibrates");
        assert_eq!(result.used_views().count(), given.len());
        for (report, view) in result.views.iter().zip(&given) {
            let fit = report.fit().expect("used");
            let points: Vec<_> = fit.points().collect();
            assert_eq!(points.len(), view.points.len());
            for (point, c) in points.iter().zip(&view.points) {
                assert_eq!(point.measured_px, c.pixel_px);
                let target = MarkerPoint(Point3::new(c.target_mm.x, c.target_mm.y, 0.0));
                let projected = result
                    .camera
                    .project(&fit.pose.transform(&target))
                    .expect("in front");
                let expected = projected.0 - c.pixel_px.0;
                assert!(
                    (point.residual_px - expected).norm() < 1e-9,
                    "view {}: {} against {expected}",
                    report.index,
                    point.residual_px
                );
                assert!((point.projected_px().0 - projected.0).norm() < 1e-9);
            }
        }
        // The outlier is down-weighted and pulls back by most of its offset; the wobble is not.
        let first: Vec<_> = result.views[0].fit().expect("used").points().collect();
        let outlier = first[OUTLIER];
        assert!(!outlier.is_inlier() && outlier.weight < 0.2, "{outlier:?}");
        assert!(outlier.residual_px.x < -0.8 * OUTLIER_PX, "{outlier:?}");
        let inliers = result
            .views
            .iter()
            .flat_map(|v| v.fit().expect("used").points())
            .filter(PointFit::is_inlier)
            .count();
        assert!(inliers + 20 > 6 * 64, "{inliers} inliers");
    }
}
