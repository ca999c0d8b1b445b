//! Pose of a square marker from its four image corners: three methods behind one call.
//!
//! - [`Method::Paper`]: the paper's iteration as printed (SPEC section 2, [`iterative`]),
//!   then a rigid (Kabsch) fit of the model onto the iterated corners ([`fit`]).
//! - [`Method::DepthNewton`]: the same unknowns and residuals solved by Levenberg-Marquardt
//!   ([`depth_newton`]), then the same fit.
//! - [`Method::Reprojection`] (default): both IPPE candidates of the planar ambiguity
//!   ([`ippe`]), each refined on pixel reprojection error ([`refine`]); the better is
//!   reported with the other's error, and a covariance for a given corner noise.
//!
//! Entry points: [`estimate_pose`] for validated image corners, [`estimate_from_rays`] for
//! corners already normalised.

pub mod depth_newton;
pub mod fit;
pub mod ippe;
pub mod iterative;
pub mod lm;
pub mod refine;

use crate::geometry::{
    camera::{Camera, CameraError, ImageUnit},
    euler::angle_between,
    frames::{CameraPoint, MarkerPoint, MarkerToCamera, NormalizedPoint, PixelPoint},
    marker::Marker,
    quad::ImageQuad,
};
use nalgebra::{Matrix6, Vector3};
use thiserror::Error;

/// Default starting depth of the paper method, mm (the paper's z_initial, Section 8).
pub const DEFAULT_INITIAL_Z_MM: f64 = 450.0;
/// Default gain k of Eq. 12.
pub const DEFAULT_GAIN: f64 = 1.0;
/// Default e_d of Eq. 13, mm.
pub const DEFAULT_TOLERANCE_MM: f64 = 1.0;
/// Default iteration limit (the paper's n_max).
pub const DEFAULT_MAX_ITERATIONS: u32 = 30;
/// Default corner noise for the covariance, px per coordinate.
pub const DEFAULT_CORNER_SIGMA_PX: f64 = 0.5;
/// Upper bound on `max_iterations`, so that no request can keep a worker busy for long
/// (10 000 paper iterations take about 0.3 ms).
pub const MAX_ITERATIONS_LIMIT: u32 = 10_000;
/// Largest accepted starting depth, mm (10 km).
pub const MAX_INITIAL_Z_MM: f64 = 1e7;
/// Largest accepted gain.
pub const MAX_GAIN: f64 = 10.0;
/// Largest accepted tolerance, mm.
pub const MAX_TOLERANCE_MM: f64 = 1e6;
/// Largest accepted corner noise, px.
pub const MAX_CORNER_SIGMA_PX: f64 = 100.0;

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

/// A reprojection RMS above this multiple of the stated corner noise raises
/// [`Warning::HighReprojectionError`].
pub const HIGH_RMS_SIGMAS: f64 = 4.0;

/// How the pose is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The paper's iteration (SPEC section 2).
    Paper,
    /// The paper's equations solved by Levenberg-Marquardt.
    DepthNewton,
    /// IPPE plus Levenberg-Marquardt on pixel error (the default).
    #[default]
    Reprojection,
}

impl Method {
    /// The wire name: "paper", "depth-newton", "reprojection".
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Paper => "paper",
            Method::DepthNewton => "depth-newton",
            Method::Reprojection => "reprojection",
        }
    }
}

/// Which solver parameter is at fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverParam {
    /// `initial_z_mm`.
    InitialZMm,
    /// `gain`.
    Gain,
    /// `tolerance_mm`.
    ToleranceMm,
    /// `max_iterations`.
    MaxIterations,
    /// `corner_sigma_px`.
    CornerSigmaPx,
}

impl SolverParam {
    /// The parameter's name as the API spells it.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::InitialZMm => "initial_z_mm",
            Self::Gain => "gain",
            Self::ToleranceMm => "tolerance_mm",
            Self::MaxIterations => "max_iterations",
            Self::CornerSigmaPx => "corner_sigma_px",
        }
    }
}

impl std::fmt::Display for SolverParam {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Solver settings. Build with [`EstimatorParams::default`] and the `with_*` setters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorParams {
    /// Which method.
    pub method: Method,
    /// Starting depth, mm: z0 for `paper` (default [`DEFAULT_INITIAL_Z_MM`]); for
    /// `depth-newton` the similar-triangles depth when `None`; unused by `reprojection`.
    pub initial_z_mm: Option<f64>,
    /// k of Eq. 12 (`paper` only).
    pub gain: f64,
    /// e_d of Eq. 13, mm (`paper` only).
    pub tolerance_mm: f64,
    /// Iteration limit of every method.
    pub max_iterations: u32,
    /// Record the per-iteration trace.
    pub trace: bool,
    /// Corner noise σ per coordinate, px, for the covariance (`reprojection` only).
    pub corner_sigma_px: f64,
}

impl Default for EstimatorParams {
    fn default() -> Self {
        Self {
            method: Method::default(),
            initial_z_mm: None,
            gain: DEFAULT_GAIN,
            tolerance_mm: DEFAULT_TOLERANCE_MM,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            trace: false,
            corner_sigma_px: DEFAULT_CORNER_SIGMA_PX,
        }
    }
}

impl EstimatorParams {
    /// With this method.
    pub fn with_method(self, method: Method) -> Self {
        Self { method, ..self }
    }
    /// With this starting depth, mm.
    pub fn with_initial_z_mm(self, initial_z_mm: f64) -> Self {
        Self {
            initial_z_mm: Some(initial_z_mm),
            ..self
        }
    }
    /// With this gain.
    pub fn with_gain(self, gain: f64) -> Self {
        Self { gain, ..self }
    }
    /// With this tolerance, mm.
    pub fn with_tolerance_mm(self, tolerance_mm: f64) -> Self {
        Self {
            tolerance_mm,
            ..self
        }
    }
    /// With this iteration limit.
    pub fn with_max_iterations(self, max_iterations: u32) -> Self {
        Self {
            max_iterations,
            ..self
        }
    }
    /// With or without the trace.
    pub fn with_trace(self, trace: bool) -> Self {
        Self { trace, ..self }
    }
    /// With this corner noise, px.
    pub fn with_corner_sigma_px(self, corner_sigma_px: f64) -> Self {
        Self {
            corner_sigma_px,
            ..self
        }
    }

    /// Checks every parameter against its range.
    ///
    /// # Errors
    /// [`EstimateError::ParamOutOfRange`] for the first parameter outside its range.
    pub fn validate(&self) -> Result<(), EstimateError> {
        let in_range = |value: f64, param: SolverParam, min_exclusive: f64, max: f64| {
            if value.is_finite() && value > min_exclusive && value <= max {
                Ok(())
            } else {
                Err(EstimateError::ParamOutOfRange {
                    param,
                    value,
                    min_exclusive,
                    max,
                })
            }
        };
        if let Some(z) = self.initial_z_mm {
            in_range(z, SolverParam::InitialZMm, 0.0, MAX_INITIAL_Z_MM)?;
        }
        in_range(self.gain, SolverParam::Gain, 0.0, MAX_GAIN)?;
        in_range(
            self.tolerance_mm,
            SolverParam::ToleranceMm,
            0.0,
            MAX_TOLERANCE_MM,
        )?;
        in_range(
            f64::from(self.max_iterations),
            SolverParam::MaxIterations,
            0.0,
            f64::from(MAX_ITERATIONS_LIMIT),
        )?;
        in_range(
            self.corner_sigma_px,
            SolverParam::CornerSigmaPx,
            0.0,
            MAX_CORNER_SIGMA_PX,
        )
    }
}

/// Why no pose could be produced.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum EstimateError {
    /// A solver parameter is outside its range (or not finite): refused rather than run.
    #[error("solver parameter {param} = {value} is outside ({min_exclusive}, {max}]")]
    ParamOutOfRange {
        /// The parameter.
        param: SolverParam,
        /// The value given.
        value: f64,
        /// Values must be greater than this.
        min_exclusive: f64,
        /// Values must be at most this.
        max: f64,
    },
    /// A corner could not be undistorted: the lens model has no inverse there.
    #[error("corner {index}: {source}")]
    Undistortion {
        /// The corner, as an index into the caller's list.
        index: usize,
        /// What the camera model said.
        source: CameraError,
    },
    /// Fewer than four plane points, or model and image lists of different lengths.
    #[error("need at least 4 matching points, got {model} model and {image} image points")]
    PointCount {
        /// Model points given.
        model: usize,
        /// Image points given.
        image: usize,
    },
    /// The corners admit no pose: the closed-form step or the rigid fit is degenerate (for
    /// `paper`, the iteration collapsed the corners onto a line or a point).
    #[error("no pose fits these corners ({reason})")]
    NoSolution {
        /// Which step failed.
        reason: &'static str,
    },
}

/// One iteration of the trace: corner depths and e_c (Σ|Δz|) after the update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceStep {
    /// 1-based iteration number.
    pub iteration: u32,
    /// z1..z4 after this iteration, mm.
    pub z_mm: [f64; 4],
    /// Σ_i |z_i(n) − z_i(n−1)|, mm (Eq. 13).
    pub convergence_error_mm: f64,
}

/// The other candidate of the planar ambiguity, after its own refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ambiguity {
    /// The alternative pose (translation: P2, mm).
    pub alternative: MarkerToCamera,
    /// Its reprojection RMS, image units.
    pub alternative_rms: f64,
    /// Best RMS / alternative RMS, in [0, 1]; near 1 when the two cannot be told apart.
    pub ratio: f64,
    /// Angle between the two rotations, radians.
    pub rotation_difference_rad: f64,
    /// Posterior probability that the alternative is the true pose, for the stated corner
    /// noise (pixel cameras only); 0 when the two candidates are one pose.
    pub alternative_probability: Option<f64>,
    /// The rotations differ by more than [`DISTINCT_ROTATION_DEG`] and the alternative's
    /// probability reaches [`AMBIGUITY_PROBABILITY_THRESHOLD`] (or, without pixel units, the
    /// ratio reaches [`AMBIGUITY_FALLBACK_RATIO`]).
    pub ambiguous: bool,
}

/// Conditions a caller should know about before trusting the pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Warning {
    /// The method stopped at its iteration limit.
    NotConverged,
    /// The two poses of the planar ambiguity fit about equally well.
    PoseAmbiguous,
    /// A solved corner lies at or behind the camera: the pose is not physical.
    BehindCamera,
    /// The reprojection RMS exceeds [`HIGH_RMS_SIGMAS`] × the stated corner noise.
    HighReprojectionError,
}

/// How the estimate was reached and how far to trust it.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostics {
    /// The method used.
    pub method: Method,
    /// Whether the method met its convergence criterion.
    pub converged: bool,
    /// Iterations run.
    pub iterations: u32,
    /// The last Σ|Δz| (e_c), mm (`paper`, `depth-newton`).
    pub convergence_error_mm: Option<f64>,
    /// e1..e6 = known − computed edge length at the final depths, mm (`paper`,
    /// `depth-newton`).
    pub side_residuals_mm: Option<[f64; 6]>,
    /// RMS corner reprojection error of the reported pose, image units; `None` when a
    /// corner of the pose is at or behind the camera.
    pub reprojection_rms: Option<f64>,
    /// The planar ambiguity (`reprojection`).
    pub ambiguity: Option<Ambiguity>,
    /// 6×6 covariance of (rx, ry, rz rad; x, y, z mm of the centre) for the stated corner
    /// noise (`reprojection` with a pixel camera).
    pub covariance: Option<Matrix6<f64>>,
    /// Per-iteration trace, when asked for.
    pub trace: Option<Vec<TraceStep>>,
    /// What deserves a caller's attention.
    pub warnings: Vec<Warning>,
}

/// A pose and how it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseEstimate {
    /// Marker-to-camera pose; its translation is P2 (the marker origin), mm.
    pub pose: MarkerToCamera,
    /// The marker centre in the camera frame, mm.
    pub centre_mm: Vector3<f64>,
    /// Corners P1..P4 in the camera frame, mm: as the iteration left them (`paper`,
    /// `depth-newton`) or the model under the pose (`reprojection`).
    pub corners_cam: [CameraPoint; 4],
    /// Diagnostics.
    pub diagnostics: Diagnostics,
}

/// Estimates the marker's pose from four validated image corners.
///
/// # Errors
/// [`EstimateError::ParamOutOfRange`] for bad parameters, [`EstimateError::Undistortion`]
/// when a corner cannot be undistorted, [`EstimateError::NoSolution`] when no pose fits.
/// Non-convergence is not an error: see [`Diagnostics::converged`].
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use qrpose::estimate::{estimate_pose, EstimatorParams};
/// use qrpose::geometry::{camera::Camera, euler::EulerXyz, frames::MarkerToCamera,
///                        marker::{CornerOrder, Marker}, quad::ImageQuad};
///
/// let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5)?;
/// let marker = Marker::try_new(50.0)?;
/// let truth = MarkerToCamera::new(EulerXyz::from_degrees(20.0, -10.0, 5.0).to_rotation(),
///                                 Vector3::new(60.0, -50.0, 400.0));
/// let corners = marker.object_points().map(|m| camera.project(&truth.transform(&m)).unwrap());
/// let quad = ImageQuad::try_new(corners, CornerOrder::Paper)?;
/// let estimate = estimate_pose(&quad, &camera, &marker, &EstimatorParams::default())?;
/// assert!((estimate.pose.translation_mm() - truth.translation_mm()).norm() < 1e-6);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn estimate_pose(
    quad: &ImageQuad,
    camera: &Camera,
    marker: &Marker,
    params: &EstimatorParams,
) -> Result<PoseEstimate, EstimateError> {
    params.validate()?;
    let mut rays = [NormalizedPoint::new(0.0, 0.0); 4];
    for (i, p) in quad.paper_order().iter().enumerate() {
        rays[i] = camera
            .normalize(p)
            .map_err(|source| EstimateError::Undistortion {
                index: quad.order().input_index(i),
                source,
            })?;
    }
    estimate_from_rays(&rays, camera, marker, params)
}

/// Estimates the pose from undistorted normalised corners P1..P4. The camera supplies the
/// pixel scale of the reprojection error; `params` must already be valid.
///
/// # Errors
/// [`EstimateError::NoSolution`] when no pose fits.
pub fn estimate_from_rays(
    rays: &[NormalizedPoint; 4],
    camera: &Camera,
    marker: &Marker,
    params: &EstimatorParams,
) -> Result<PoseEstimate, EstimateError> {
    let mut estimate = match params.method {
        Method::Paper => {
            let paper = iterative::PaperParams {
                initial_z_mm: params.initial_z_mm.unwrap_or(DEFAULT_INITIAL_Z_MM),
                gain: params.gain,
                tolerance_mm: params.tolerance_mm,
                max_iterations: params.max_iterations,
                trace: params.trace,
            };
            let it = iterative::iterate(rays, marker, &paper);
            from_depths(
                rays,
                camera,
                marker,
                Method::Paper,
                it.z_mm,
                it.converged,
                it.iterations,
                it.convergence_error_mm,
                it.trace,
            )?
        }
        Method::DepthNewton => {
            let dn = depth_newton::DepthNewtonParams {
                initial_z_mm: params.initial_z_mm,
                max_iterations: params.max_iterations,
                trace: params.trace,
            };
            let s = depth_newton::solve(rays, marker, &dn);
            from_depths(
                rays,
                camera,
                marker,
                Method::DepthNewton,
                s.z_mm,
                s.converged,
                s.iterations,
                s.convergence_error_mm,
                s.trace,
            )?
        }
        Method::Reprojection => by_reprojection(rays, camera, marker, params)?,
    };
    add_warnings(&mut estimate, camera, params);
    Ok(estimate)
}

/// Adds the [`Warning`]s an estimate deserves.
fn add_warnings(estimate: &mut PoseEstimate, camera: &Camera, params: &EstimatorParams) {
    let d = &mut estimate.diagnostics;
    if !d.converged {
        d.warnings.push(Warning::NotConverged);
    }
    if d.ambiguity.is_some_and(|a| a.ambiguous) {
        d.warnings.push(Warning::PoseAmbiguous);
    }
    let behind = estimate
        .corners_cam
        .iter()
        .any(|p| p.0.z.is_nan() || p.0.z <= 0.0);
    if behind || d.reprojection_rms.is_none() {
        d.warnings.push(Warning::BehindCamera);
    }
    let sigma = match camera.unit() {
        ImageUnit::Pixel => Some(params.corner_sigma_px),
        ImageUnit::ImagePlaneMm => None,
    };
    if let (Some(rms), Some(sigma)) = (d.reprojection_rms, sigma)
        && rms > HIGH_RMS_SIGMAS * sigma
    {
        d.warnings.push(Warning::HighReprojectionError);
    }
}

/// Builds the estimate of the depth-based methods: corners from Eq. 6 and a rigid fit.
#[allow(clippy::too_many_arguments)]
fn from_depths(
    rays: &[NormalizedPoint; 4],
    camera: &Camera,
    marker: &Marker,
    method: Method,
    z_mm: [f64; 4],
    converged: bool,
    iterations: u32,
    convergence_error_mm: Option<f64>,
    trace: Option<Vec<TraceStep>>,
) -> Result<PoseEstimate, EstimateError> {
    let corners_cam = iterative::corners_at_depths(rays, &z_mm);
    let pose = fit::fit_rigid(marker, &corners_cam).ok_or(EstimateError::NoSolution {
        reason: "the solved corners are collinear",
    })?;
    let centre_mm = pose.transform(&marker.centre()).0.coords;
    Ok(PoseEstimate {
        pose,
        centre_mm,
        corners_cam,
        diagnostics: Diagnostics {
            method,
            converged,
            iterations,
            convergence_error_mm,
            side_residuals_mm: Some(iterative::side_errors_mm(rays, &z_mm, marker)),
            reprojection_rms: fit::reprojection_rms(camera, marker, &pose, rays),
            ambiguity: None,
            covariance: None,
            trace,
            warnings: Vec::new(),
        },
    })
}

/// The four corners by IPPE from the closed-form square homography.
fn by_reprojection(
    rays: &[NormalizedPoint; 4],
    camera: &Camera,
    marker: &Marker,
    params: &EstimatorParams,
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
/// refined by Levenberg-Marquardt on pixel error. Always the `reprojection` method; the
/// corner-based methods need exactly the four corners.
///
/// `model` are the points in the marker frame (z = 0, mm) and `image` where they were seen
/// (px, or image-plane mm), in the same order.
///
/// # Errors
/// [`EstimateError::ParamOutOfRange`] for bad parameters, [`EstimateError::PointCount`] for
/// fewer than four points or lists of different lengths, [`EstimateError::Undistortion`]
/// for a point with no ray (indexed into `image`), [`EstimateError::NoSolution`] for
/// degenerate points.
pub fn estimate_planar_points(
    model: &[MarkerPoint],
    image: &[PixelPoint],
    camera: &Camera,
    marker: &Marker,
    params: &EstimatorParams,
) -> Result<PoseEstimate, EstimateError> {
    let params = params.with_method(Method::Reprojection);
    params.validate()?;
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
    let model_xy: Vec<nalgebra::Vector2<f64>> = centred.iter().map(|m| m.xy()).collect();
    let h = ippe::homography_dlt(&model_xy, &rays).ok_or(DEGENERATE_HOMOGRAPHY)?;
    let planar = PlanarModel {
        centred: &centred,
        origin_mm,
    };
    let mut estimate = solve_planar(&planar, &rays, &h, camera, marker, &params)?;
    add_warnings(&mut estimate, camera, &params);
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
    params: &EstimatorParams,
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
    #[rustfmt::skip]
    let minus_skew = nalgebra::Matrix3::new(
        0.0,  d.z,  -d.y,
        -d.z, 0.0,  d.x,
        d.y,  -d.x, 0.0,
    );
    j.fixed_view_mut::<3, 3>(3, 0).copy_from(&minus_skew);
    j * cov * j.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{euler::EulerXyz, marker::CornerOrder};
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
        let params = EstimatorParams::default().with_trace(true);
        let est =
            estimate_planar_points(&model, &image, &camera, &marker, &params).expect("solvable");
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
        let params = EstimatorParams::default();
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
        let err = estimate_planar_points(
            &model,
            &image,
            &camera,
            &marker,
            &EstimatorParams::default(),
        )
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
