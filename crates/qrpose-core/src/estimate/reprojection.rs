//! The `reprojection` method: IPPE's two closed-form candidates of the planar ambiguity
//! ([`ippe`](super::ippe)), each refined by Levenberg-Marquardt on pixel reprojection error
//! ([`refine`](super::refine)); the better is reported with the other's error, the
//! probability that the other is the true pose, and a covariance for the stated corner noise
//! (`docs/conventions.md`, Planar ambiguity and Covariance).
//!
//! It takes any four or more points of the marker plane ([`estimate_planar_points`]), e.g.
//! the twelve corners of the three finder patterns, as well as the four symbol corners.

use super::result::{Ambiguity, Diagnostics, EstimateError, PoseEstimate, TraceStep};
use super::solver::{
    DEFAULT_CORNER_SIGMA_PX, DEFAULT_MAX_ITERATIONS, Method, ValidSolver, check_common,
};
use super::{add_warnings, ippe, refine};
use crate::geometry::{
    camera::{Camera, ImageUnit},
    euler::angle_between,
    frames::{MarkerPoint, MarkerToCamera, NormalizedPoint, PixelPoint},
    homography::{fit_homography_dlt, with_unit_h33},
    marker::Marker,
};
use nalgebra::{Matrix6, Point2, Vector3};

/// `ambiguity.ambiguous` is set when the alternative pose has at least this posterior
/// probability of being the true one, given Gaussian corner noise of `corner_sigma_px` and
/// equal priors: P = 1 / (1 + exp((SSR_alt − SSR_best) / 2σ²)), SSR the sum of squared corner
/// residuals (px²). As a threshold on the ratio r = RMS_best / RMS_alt this reads
/// r ≥ RMS_best / √(RMS_best² + ½·σ²·ln 99). Chosen with `cargo run --release --example
/// ambiguity_study` (see `docs/accuracy.md`): the probability is calibrated (predicted and
/// observed wrong-pick rates agree per bin at σ = 0.25-2 px), and at 1 % the poses left
/// unflagged are wrong 0.05-0.13 % of the time, where a fixed ratio threshold flagging as
/// many poses leaves 0.7-7.6 %.
pub const AMBIGUITY_PROBABILITY_THRESHOLD: f64 = 0.01;

/// For cameras in image-plane millimetres without a pixel size the noise in pixels is
/// unknown, so `ambiguous` falls back to ratio ≥ this (from the same study: at σ = 0.5 px it
/// flags 47 % of poses and leaves 2.3 % wrong picks unflagged).
pub const AMBIGUITY_FALLBACK_RATIO: f64 = 0.3;

/// Two refined candidates whose rotations differ by less than this are one solution: picking
/// either costs less than the noise does.
pub const DISTINCT_ROTATION_DEG: f64 = 0.1;

/// The reprojection method's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReprojectionParams {
    /// Levenberg-Marquardt iteration limit per candidate, 1 to
    /// [`MAX_ITERATIONS_LIMIT`](super::MAX_ITERATIONS_LIMIT).
    pub max_iterations: u32,
    /// Record the corner depths of the chosen candidate at every iteration.
    pub trace: bool,
    /// Corner noise σ, px per coordinate: the covariance, the ambiguity probability and the
    /// scale of the high-reprojection-error warning.
    pub corner_sigma_px: f64,
}

impl Default for ReprojectionParams {
    fn default() -> Self {
        Self {
            max_iterations: DEFAULT_MAX_ITERATIONS,
            trace: false,
            corner_sigma_px: DEFAULT_CORNER_SIGMA_PX,
        }
    }
}

impl ReprojectionParams {
    /// Checks every parameter against its range.
    ///
    /// # Errors
    /// [`EstimateError::ParamOutOfRange`] for the first one outside its range.
    pub fn validate(&self) -> Result<(), EstimateError> {
        check_common(self.max_iterations, self.corner_sigma_px)
    }
}

/// The four corners by IPPE from the closed-form square homography.
pub(super) fn by_reprojection(
    rays: &[NormalizedPoint; 4],
    camera: &Camera,
    marker: &Marker,
    params: &ReprojectionParams,
) -> Result<PoseEstimate, EstimateError> {
    let h = ippe::homography_from_square(rays, marker).ok_or(DEGENERATE_HOMOGRAPHY)?;
    let model = PlanarModel {
        centred: &ippe::centred_model(marker),
        origin_mm: marker.centre().0.coords,
    };
    solve_planar(&model, rays, &h, camera, marker, params)
}

const DEGENERATE_HOMOGRAPHY: EstimateError = EstimateError::NoSolution {
    reason: "degenerate homography",
};

/// Model points for a reprojection solve: marker-frame points shifted by `origin_mm` (their
/// centroid) so that the homography and IPPE are well conditioned.
struct PlanarModel<'a> {
    centred: &'a [Vector3<f64>],
    origin_mm: Vector3<f64>,
}

/// Estimates the pose from any four or more points of the marker plane, e.g. the twelve
/// corners of the three finder patterns: IPPE from a DLT homography, both candidates
/// refined by Levenberg-Marquardt on pixel error. Always the `reprojection` method, with the
/// iteration limit, trace and corner noise of `solver` (see
/// [`ValidSolver::as_reprojection`]); the corner-based methods need exactly the four corners.
///
/// `model` are the points in the marker frame (z = 0, mm) and `image` where they were seen
/// (px, or image-plane mm), in the same order.
///
/// # Errors
/// [`EstimateError::PointCount`] for fewer than four points or lists of different lengths, [`EstimateError::Undistortion`]
/// for a point with no ray (indexed into `image`), [`EstimateError::NoSolution`] for
/// degenerate points.
pub fn estimate_planar_points(
    model: &[MarkerPoint],
    image: &[PixelPoint],
    camera: &Camera,
    marker: &Marker,
    solver: &ValidSolver,
) -> Result<PoseEstimate, EstimateError> {
    let params = solver.as_reprojection();
    if model.len() < 4 || model.len() != image.len() {
        return Err(EstimateError::PointCount {
            model: model.len(),
            image: image.len(),
        });
    }
    let rays = image
        .iter()
        .enumerate()
        .map(|(index, p)| {
            camera
                .normalize(p)
                .map_err(|source| EstimateError::Undistortion { index, source })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let origin_mm = model.iter().map(|m| m.0.coords).sum::<Vector3<f64>>() / model.len() as f64;
    let centred: Vec<Vector3<f64>> = model.iter().map(|m| m.0.coords - origin_mm).collect();
    let model_xy: Vec<Point2<f64>> = centred.iter().map(|m| Point2::new(m.x, m.y)).collect();
    let ray_xy: Vec<Point2<f64>> = rays.iter().map(|r| r.0).collect();
    let h = fit_homography_dlt(&model_xy, &ray_xy)
        .ok()
        .and_then(|h| with_unit_h33(&h))
        .ok_or(DEGENERATE_HOMOGRAPHY)?;
    let planar = PlanarModel {
        centred: &centred,
        origin_mm,
    };
    let mut estimate = solve_planar(&planar, &rays, &h, camera, marker, &params)?;
    add_warnings(&mut estimate, camera, params.corner_sigma_px);
    Ok(estimate)
}

/// IPPE's two candidates from `h`, each refined; the better reported, the other in
/// `ambiguity`.
fn solve_planar(
    model: &PlanarModel<'_>,
    rays: &[NormalizedPoint],
    h: &nalgebra::Matrix3<f64>,
    camera: &Camera,
    marker: &Marker,
    params: &ReprojectionParams,
) -> Result<PoseEstimate, EstimateError> {
    let scale = refine::PixelScale {
        fx: camera.fx(),
        fy: camera.fy(),
    };
    let starts =
        ippe::candidates_from_homography(h, rays, model.centred).ok_or(DEGENERATE_HOMOGRAPHY)?;
    let [a, b] = starts.map(|s| {
        refine::refine(
            s,
            model.centred,
            rays,
            scale,
            params.max_iterations,
            params.trace,
        )
    });
    let floor_rms = refine::RESIDUAL_FLOOR_NORMALISED * camera.fx().max(camera.fy());
    let (best, other, best_start) = if first_is_better(&a, &b, floor_rms) {
        (a, b, starts[0])
    } else {
        (b, a, starts[1])
    };
    if !best.rms.is_finite() {
        return Err(EstimateError::NoSolution {
            reason: "both candidates put the marker behind the camera",
        });
    }
    let rotation_difference_rad = angle_between(&best.pose.r, &other.pose.r);
    let distinct = rotation_difference_rad.to_degrees() > DISTINCT_ROTATION_DEG;
    let ratio = if other.rms > 0.0 {
        (best.rms / other.rms).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let alternative_probability = match camera.unit() {
        ImageUnit::Pixel if distinct => Some(alternative_probability(
            best.rms,
            other.rms,
            rays.len(),
            params.corner_sigma_px,
        )),
        ImageUnit::Pixel => Some(0.0),
        ImageUnit::ImagePlaneMm => None,
    };
    let ambiguous = distinct
        && match alternative_probability {
            Some(p) => p >= AMBIGUITY_PROBABILITY_THRESHOLD,
            None => ratio >= AMBIGUITY_FALLBACK_RATIO,
        };
    let pose_of =
        |p: &ippe::CentredPose| MarkerToCamera::new(p.r, p.centre_mm - p.r * model.origin_mm);
    let ambiguity = Ambiguity {
        alternative: pose_of(&other.pose),
        alternative_rms: other.rms,
        ratio,
        rotation_difference_rad,
        alternative_probability,
        ambiguous,
    };
    // The covariance is of the model origin; move it to the marker centre: c = o + R·(centre − origin).
    let to_centre = marker.centre().0.coords - model.origin_mm;
    let covariance = match camera.unit() {
        ImageUnit::Pixel => best.jtj.try_inverse().map(|inv| {
            centre_covariance(
                &(inv * params.corner_sigma_px.powi(2)),
                &(best.pose.r * to_centre),
            )
        }),
        ImageUnit::ImagePlaneMm => None,
    };
    let pose = pose_of(&best.pose);
    let corners_cam = marker.object_points().map(|m| pose.transform(&m));
    let trace = best.pose_trace.as_ref().map(|steps| {
        let depths =
            |p: &ippe::CentredPose| marker.object_points().map(|m| pose_of(p).transform(&m).0.z);
        let mut previous = depths(&best_start);
        steps
            .iter()
            .map(|(iteration, p)| {
                let z = depths(p);
                let e_c = z.iter().zip(&previous).map(|(a, b)| (a - b).abs()).sum();
                previous = z;
                TraceStep {
                    iteration: *iteration,
                    z_mm: z,
                    convergence_error_mm: e_c,
                }
            })
            .collect()
    });
    let reprojection_rms = Some(best.rms);
    Ok(PoseEstimate {
        pose,
        centre_mm: pose.transform(&marker.centre()).0.coords,
        corners_cam,
        diagnostics: Diagnostics {
            method: Method::Reprojection,
            converged: best.converged,
            iterations: best.iterations,
            convergence_error_mm: None,
            side_residuals_mm: None,
            reprojection_rms,
            ambiguity: Some(ambiguity),
            covariance,
            trace,
            warnings: Vec::new(),
        },
    })
}

/// Posterior probability that the alternative (RMS `alternative_rms`) rather than the best
/// candidate (RMS `best_rms`) is the true pose, for `points` points with Gaussian noise of
/// `sigma` per coordinate and equal priors: 1 / (1 + exp(ΔSSR / 2σ²)), SSR = points · RMS².
fn alternative_probability(best_rms: f64, alternative_rms: f64, points: usize, sigma: f64) -> f64 {
    let delta_ssr = points as f64 * (alternative_rms.powi(2) - best_rms.powi(2));
    1.0 / (1.0 + (delta_ssr / (2.0 * sigma * sigma)).exp())
}

/// Whether refined candidate `a` beats `b`: the lower RMS, except that RMS values within
/// `floor_rms` of each other are a tie (both fit exactly) and then the converged one wins.
fn first_is_better(a: &refine::Refined, b: &refine::Refined, floor_rms: f64) -> bool {
    let tie = (a.rms - b.rms).abs() <= floor_rms;
    if tie && a.converged != b.converged {
        return a.converged;
    }
    a.rms <= b.rms
}

/// Moves a covariance of (δ rotation, origin) to (δ rotation, p) for a point p = o + d with
/// d = R·(point − origin) in camera axes: under a left rotation δ, p moves by δ × d + δo,
/// so J = [[I, 0], [−[d]×, I]] and Σ' = J Σ Jᵀ.
fn centre_covariance(cov: &Matrix6<f64>, d: &Vector3<f64>) -> Matrix6<f64> {
    let mut j = Matrix6::identity();
    j.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(-d.cross_matrix()));
    j * cov * j.transpose()
}

#[cfg(test)]
mod tests {
    use super::super::{Solver, estimate_pose};
    use super::*;
    use crate::geometry::{euler::EulerXyz, marker::CornerOrder, quad::ImageQuad};
    use nalgebra::Point3;

    fn setup() -> (Camera, Marker, MarkerToCamera) {
        let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("valid camera");
        let marker = Marker::try_new(50.0).expect("valid size");
        let truth = MarkerToCamera::new(
            EulerXyz::from_degrees(25.0, -15.0, 40.0).to_rotation(),
            Vector3::new(-40.0, 30.0, 450.0),
        );
        (camera, marker, truth)
    }

    /// The twelve corners of the three finder patterns of a 25-module (version 2) symbol, in
    /// the marker frame: symbol (col, row) in modules maps to (−l + col·s, row·s).
    fn finder_corners(marker: &Marker) -> Vec<MarkerPoint> {
        let n = 25.0;
        let s = marker.size_mm() / n;
        let squares = [(0.0, 0.0), (n - 7.0, 0.0), (0.0, n - 7.0)];
        squares
            .iter()
            .flat_map(|&(c, r)| [(c, r), (c + 7.0, r), (c + 7.0, r + 7.0), (c, r + 7.0)])
            .map(|(c, r)| MarkerPoint(Point3::new(-marker.size_mm() + c * s, r * s, 0.0)))
            .collect()
    }

    #[test]
    fn recovers_the_pose_from_the_twelve_finder_corners() {
        let (camera, marker, truth) = setup();
        let model = finder_corners(&marker);
        let image: Vec<PixelPoint> = model
            .iter()
            .map(|m| camera.project(&truth.transform(m)).expect("in front"))
            .collect();
        let solver = Solver::Reprojection(ReprojectionParams {
            trace: true,
            ..ReprojectionParams::default()
        })
        .validate()
        .expect("valid");
        let est =
            estimate_planar_points(&model, &image, &camera, &marker, &solver).expect("solvable");
        assert!(angle_between(&est.pose.rotation(), &truth.rotation()) < 1e-9);
        assert!((est.pose.translation_mm() - truth.translation_mm()).norm() < 1e-6);
        let centre = truth.transform(&marker.centre()).0.coords;
        assert!((est.centre_mm - centre).norm() < 1e-6);
        assert!(est.diagnostics.covariance.is_some() && est.diagnostics.warnings.is_empty());
    }

    #[test]
    fn four_corners_give_the_same_pose_by_either_path() {
        let (camera, marker, truth) = setup();
        let corners = marker.object_points();
        let noise = [(0.3, -0.2), (-0.4, 0.1), (0.2, 0.5), (-0.1, -0.3)];
        let image: [PixelPoint; 4] = std::array::from_fn(|i| {
            let p = camera
                .project(&truth.transform(&corners[i]))
                .expect("in front");
            PixelPoint::new(p.u() + noise[i].0, p.v() + noise[i].1)
        });
        let params = ValidSolver::default();
        let quad = ImageQuad::try_new(image, CornerOrder::Paper).expect("valid quad");
        let by_quad = estimate_pose(&quad, &camera, &marker, &params).expect("solvable");
        let by_points =
            estimate_planar_points(&corners, &image, &camera, &marker, &params).expect("solvable");
        assert!(angle_between(&by_quad.pose.rotation(), &by_points.pose.rotation()) < 1e-9);
        assert!((by_quad.centre_mm - by_points.centre_mm).norm() < 1e-6);
        let (a, b) = (
            by_quad.diagnostics.covariance,
            by_points.diagnostics.covariance,
        );
        let (a, b) = (a.expect("covariance"), b.expect("covariance"));
        assert!(
            (a - b).norm() < 1e-6 * a.norm(),
            "covariance of the centre by either origin"
        );
    }

    #[test]
    fn refuses_too_few_or_mismatched_points() {
        let (camera, marker, _) = setup();
        let model = marker.object_points();
        let image = [PixelPoint::new(1.0, 1.0); 3];
        let err = estimate_planar_points(&model, &image, &camera, &marker, &ValidSolver::default())
            .expect_err("mismatched");
        assert_eq!(err, EstimateError::PointCount { model: 4, image: 3 });
    }

    #[test]
    fn covariance_moves_to_the_centre_like_the_exact_map_does() {
        // Sigma points of a small covariance, pushed through p = exp(δ)·d + o, must have the
        // covariance that centre_covariance predicts.
        #[rustfmt::skip]
        let l = Matrix6::new(
            2.0, 0.0, 0.0, 0.0, 0.0, 0.0,
            0.3, 1.0, 0.0, 0.0, 0.0, 0.0,
            -0.2, 0.1, 1.5, 0.0, 0.0, 0.0,
            0.5, -0.4, 0.2, 3.0, 0.0, 0.0,
            0.1, 0.6, -0.3, 0.2, 2.0, 0.0,
            -0.7, 0.2, 0.4, 0.1, -0.5, 4.0,
        ) * 1e-4;
        let cov = l * l.transpose();
        let d = Vector3::new(12.0, -30.0, 8.0);
        let mut sample = Matrix6::zeros();
        for k in 0..6 {
            for sign in [-1.0, 1.0] {
                let x: nalgebra::Vector6<f64> = l.column(k) * sign * 6f64.sqrt();
                let delta = Vector3::new(x[0], x[1], x[2]);
                let p = nalgebra::Rotation3::new(delta) * d - d + Vector3::new(x[3], x[4], x[5]);
                let y = nalgebra::Vector6::new(x[0], x[1], x[2], p.x, p.y, p.z);
                sample += y * y.transpose() / 12.0;
            }
        }
        let predicted = centre_covariance(&cov, &d);
        assert!(
            (predicted - sample).norm() < 1e-3 * predicted.norm(),
            "{predicted} vs {sample}"
        );
    }
}
