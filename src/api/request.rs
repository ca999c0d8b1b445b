//! Request bodies of `POST /v1/pose/corners` (and the CLI's `estimate`), and their
//! validation into core types.
//!
//! Validation happens once, here, and every refusal is a [`Problem`] with a stable code and
//! the JSON pointer of the field at fault. Unknown fields are refused rather than ignored, so
//! that a typo (`max_iteration`) cannot silently fall back to a default.

use super::problem::{ErrorCode, Problem};
use crate::estimate::{
    DEFAULT_CORNER_SIGMA_PX, DEFAULT_GAIN, DEFAULT_MAX_ITERATIONS, DEFAULT_TOLERANCE_MM,
    EstimateError, EstimatorParams, MAX_ITERATIONS_LIMIT, Method,
};
use crate::geometry::{
    camera::{Camera, CameraError, CameraParam, Distortion},
    frames::PixelPoint,
    marker::{CornerOrder, Marker, MarkerError},
    quad::{ImageQuad, QuadError},
};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// How the four corners are listed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum CornerOrderDto {
    /// Top-left, top-right, bottom-right, bottom-left of the symbol (OpenCV, zxing, rqrr).
    #[default]
    Qr,
    /// The paper's P1, P2, P3, P4 (bottom-right, top-right, top-left, bottom-left).
    Paper,
}

impl From<CornerOrderDto> for CornerOrder {
    fn from(o: CornerOrderDto) -> Self {
        match o {
            CornerOrderDto::Qr => CornerOrder::Qr,
            CornerOrderDto::Paper => CornerOrder::Paper,
        }
    }
}

/// The pose solver.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "kebab-case")]
pub enum MethodDto {
    /// The paper's iterative estimator as printed (Teoh et al. 2022, Eqs. 6-13).
    Paper,
    /// The paper's unknowns and residuals solved by Levenberg-Marquardt.
    DepthNewton,
    /// IPPE closed form, both candidates refined on pixel error (default; most accurate).
    #[default]
    Reprojection,
}

impl From<MethodDto> for Method {
    fn from(m: MethodDto) -> Self {
        match m {
            MethodDto::Paper => Method::Paper,
            MethodDto::DepthNewton => Method::DepthNewton,
            MethodDto::Reprojection => Method::Reprojection,
        }
    }
}

/// Brown-Conrady lens distortion, OpenCV's coefficients and meaning. Omitted terms are 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DistortionDto {
    /// Radial r² coefficient.
    #[serde(default)]
    #[schema(example = -0.12)]
    pub k1: f64,
    /// Radial r⁴ coefficient.
    #[serde(default)]
    #[schema(example = 0.03)]
    pub k2: f64,
    /// Tangential coefficient p1.
    #[serde(default)]
    pub p1: f64,
    /// Tangential coefficient p2.
    #[serde(default)]
    pub p2: f64,
    /// Radial r⁶ coefficient.
    #[serde(default)]
    pub k3: f64,
}

/// Camera intrinsics, in exactly one of three forms:
/// pixels (`fx_px, fy_px, cx_px, cy_px`); sensor (`focal_length_mm, pixel_size_um, cx_px,
/// cy_px`, so fx = fy = focal length / pixel size); or, with `corners_mm` only, the paper's
/// image plane (`focal_length_mm`, plus optionally `pixel_size_um` to get pixel diagnostics).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraDto {
    /// Horizontal focal length, px.
    #[schema(example = 1000.0)]
    pub fx_px: Option<f64>,
    /// Vertical focal length, px.
    #[schema(example = 1000.0)]
    pub fy_px: Option<f64>,
    /// Principal point, horizontal, px (pixel centres are integers: the image centre of a
    /// 1280-px-wide image is 639.5).
    #[schema(example = 639.5)]
    pub cx_px: Option<f64>,
    /// Principal point, vertical, px.
    #[schema(example = 359.5)]
    pub cy_px: Option<f64>,
    /// Lens focal length, mm (sensor or paper form).
    pub focal_length_mm: Option<f64>,
    /// Pixel pitch, µm (sensor form).
    pub pixel_size_um: Option<f64>,
    /// Lens distortion of the corner pixels; none when omitted.
    pub distortion: Option<DistortionDto>,
}

/// The printed code.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MarkerDto {
    /// Side of the QR symbol, mm: outer edge of one finder pattern to the outer edge of the
    /// other, quiet zone excluded.
    #[schema(example = 50.0)]
    pub size_mm: f64,
}

fn default_gain() -> f64 {
    DEFAULT_GAIN
}
fn default_tolerance_mm() -> f64 {
    DEFAULT_TOLERANCE_MM
}
fn default_max_iterations() -> u64 {
    u64::from(DEFAULT_MAX_ITERATIONS)
}
fn default_corner_sigma_px() -> f64 {
    DEFAULT_CORNER_SIGMA_PX
}

/// Solver choice and parameters. Every field is optional.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SolverDto {
    /// The solver (default `reprojection`).
    #[serde(default)]
    pub method: MethodDto,
    /// Starting depth of every corner, mm, in (0, 1e7]. `paper`: z0 (default 450, as in the
    /// paper). `depth-newton`: replaces its closed-form start. Unused by `reprojection`.
    #[schema(example = 450.0)]
    pub initial_z_mm: Option<f64>,
    /// `paper` only: updating coefficient k of Eq. 12, in (0, 10]. Default 1.
    #[serde(default = "default_gain")]
    #[schema(example = 1.0)]
    pub gain: f64,
    /// `paper` only: convergence threshold e_d on Σ|Δz| (Eq. 13), mm, in (0, 1e6]. Default 1.
    #[serde(default = "default_tolerance_mm")]
    #[schema(example = 1.0)]
    pub tolerance_mm: f64,
    /// Iteration limit of every method, 1 to 10000. Default 30.
    #[serde(default = "default_max_iterations")]
    #[schema(example = 30, minimum = 1, maximum = 10000)]
    pub max_iterations: u64,
    /// Return the per-iteration trace (corner depths and Σ|Δz|). Default false.
    #[serde(default)]
    pub trace: bool,
    /// `reprojection` only: corner noise σ per coordinate, px, in (0, 100], for the pose
    /// covariance. Default 0.5.
    #[serde(default = "default_corner_sigma_px")]
    #[schema(example = 0.5)]
    pub corner_sigma_px: f64,
}

impl Default for SolverDto {
    fn default() -> Self {
        Self {
            method: MethodDto::default(),
            initial_z_mm: None,
            gain: DEFAULT_GAIN,
            tolerance_mm: DEFAULT_TOLERANCE_MM,
            max_iterations: default_max_iterations(),
            trace: false,
            corner_sigma_px: DEFAULT_CORNER_SIGMA_PX,
        }
    }
}

/// `POST /v1/pose/corners`: four corners of one QR code, the camera and the marker size.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({
    "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
    "corner_order": "qr",
    "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
    "marker": {"size_mm": 50.0},
    "solver": {"method": "reprojection"}
}))]
pub struct CornersRequest {
    /// Four corners in pixels, `[u, v]` each (u right, v down, integer = pixel centre), in
    /// `corner_order`. Give this or `corners_mm`.
    #[schema(value_type = Option<Vec<[f64; 2]>>)]
    pub corners_px: Option<Vec<Vec<f64>>>,
    /// Four corners in image-plane millimetres (the paper's form, x' = x_n · f), with
    /// `camera.focal_length_mm`. Give this or `corners_px`.
    #[schema(value_type = Option<Vec<[f64; 2]>>)]
    pub corners_mm: Option<Vec<Vec<f64>>>,
    /// Order of the corners (default `qr`).
    #[serde(default)]
    pub corner_order: CornerOrderDto,
    /// Camera intrinsics.
    pub camera: CameraDto,
    /// The printed code.
    pub marker: MarkerDto,
    /// Solver and parameters (all optional).
    #[serde(default)]
    pub solver: SolverDto,
}

/// Which unit corners come in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CornersUnit {
    /// Pixels.
    Px,
    /// Image-plane millimetres.
    Mm,
}

/// Everything an estimate needs besides the corners, validated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSetup {
    /// The camera; for `corners_mm` with a pixel size, a pixel camera with its centre at 0.
    pub camera: Camera,
    /// The marker.
    pub marker: Marker,
    /// Solver parameters, range-checked.
    pub params: EstimatorParams,
    /// Image-plane mm per pixel when mm corners are converted to pixels.
    pub mm_per_px: Option<f64>,
}

/// The JSON pointer of a camera parameter below the camera object.
fn camera_param_name(param: CameraParam) -> String {
    if param.is_distortion() {
        format!("distortion/{param}")
    } else {
        param.name().to_owned()
    }
}

/// The problem for a refused camera parameter, under the JSON pointer `camera_pointer`.
pub fn problem_from_camera_error(err: CameraError, camera_pointer: &str) -> Problem {
    match err {
        CameraError::NonFinite { param } => {
            Problem::new(ErrorCode::NonFiniteNumber, err.to_string())
                .with_field(format!("{camera_pointer}/{}", camera_param_name(param)))
        }
        CameraError::NonPositive { param, value } => Problem::new(
            ErrorCode::InvalidCameraParameter,
            format!("{} must be positive, got {value}", camera_param_name(param)),
        )
        .with_field(format!("{camera_pointer}/{}", camera_param_name(param))),
        CameraError::UndistortionFailed { .. } => {
            Problem::new(ErrorCode::UndistortionFailed, err.to_string())
        }
    }
}

fn incomplete(detail: impl Into<String>, field: impl Into<String>) -> Problem {
    Problem::new(ErrorCode::IncompleteCamera, detail).with_field(field)
}

fn require(value: Option<f64>, name: &str, form: &str) -> Result<f64, Problem> {
    value.ok_or_else(|| {
        incomplete(
            format!("the {form} form of the camera needs {name}"),
            format!("/camera/{name}"),
        )
    })
}

impl CameraDto {
    /// Builds the camera for corners in `unit`, and for mm corners with a pixel size the
    /// mm-per-pixel scale that turns them into pixels.
    ///
    /// # Errors
    /// `incomplete_camera` for a missing or conflicting form, `invalid_camera_parameter` or
    /// `non_finite_number` for a bad value.
    pub fn to_camera(&self, unit: CornersUnit) -> Result<(Camera, Option<f64>), Problem> {
        let has_px = self.fx_px.is_some() || self.fy_px.is_some();
        let has_sensor = self.focal_length_mm.is_some() || self.pixel_size_um.is_some();
        let err = |e| problem_from_camera_error(e, "/camera");
        let (camera, mm_per_px) = match unit {
            CornersUnit::Px if has_px && has_sensor => {
                return Err(incomplete(
                    "give fx_px/fy_px or focal_length_mm/pixel_size_um, not both",
                    "/camera",
                ));
            }
            CornersUnit::Px if has_px => {
                let fx = require(self.fx_px, "fx_px", "pixel")?;
                let fy = require(self.fy_px, "fy_px", "pixel")?;
                let cx = require(self.cx_px, "cx_px", "pixel")?;
                let cy = require(self.cy_px, "cy_px", "pixel")?;
                (Camera::from_pixels(fx, fy, cx, cy).map_err(err)?, None)
            }
            CornersUnit::Px if has_sensor => {
                let f = require(self.focal_length_mm, "focal_length_mm", "sensor")?;
                let pitch = require(self.pixel_size_um, "pixel_size_um", "sensor")?;
                let cx = require(self.cx_px, "cx_px", "sensor")?;
                let cy = require(self.cy_px, "cy_px", "sensor")?;
                (
                    Camera::from_focal_length(f, pitch, cx, cy).map_err(err)?,
                    None,
                )
            }
            CornersUnit::Px => {
                return Err(incomplete(
                    "the camera needs fx_px, fy_px, cx_px, cy_px or focal_length_mm, pixel_size_um, cx_px, cy_px",
                    "/camera",
                ));
            }
            CornersUnit::Mm => {
                for (value, name) in [
                    (self.fx_px, "fx_px"),
                    (self.fy_px, "fy_px"),
                    (self.cx_px, "cx_px"),
                    (self.cy_px, "cy_px"),
                ] {
                    if value.is_some() {
                        return Err(incomplete(
                            format!(
                                "corners_mm are relative to the principal point and take focal_length_mm, not {name}"
                            ),
                            format!("/camera/{name}"),
                        ));
                    }
                }
                let f = require(self.focal_length_mm, "focal_length_mm", "image-plane")?;
                match self.pixel_size_um {
                    Some(pitch) => {
                        let camera = Camera::from_focal_length(f, pitch, 0.0, 0.0).map_err(err)?;
                        (camera, Some(pitch * 1e-3))
                    }
                    None => (Camera::image_plane_mm(f).map_err(err)?, None),
                }
            }
        };
        let d = self.distortion.unwrap_or_default();
        let distortion = Distortion::try_new(d.k1, d.k2, d.p1, d.p2, d.k3).map_err(err)?;
        Ok((camera.with_distortion(distortion), mm_per_px))
    }
}

impl SolverDto {
    /// The validated solver parameters.
    ///
    /// # Errors
    /// `solver_parameter_out_of_range` naming the parameter.
    pub fn to_params(&self) -> Result<EstimatorParams, Problem> {
        let max_iterations = u32::try_from(self.max_iterations)
            .ok()
            .filter(|n| (1..=MAX_ITERATIONS_LIMIT).contains(n))
            .ok_or_else(|| {
                Problem::new(
                    ErrorCode::SolverParameterOutOfRange,
                    format!(
                        "max_iterations must be between 1 and {MAX_ITERATIONS_LIMIT}, got {}",
                        self.max_iterations
                    ),
                )
                .with_field("/solver/max_iterations")
            })?;
        let params = EstimatorParams {
            method: self.method.into(),
            initial_z_mm: self.initial_z_mm,
            gain: self.gain,
            tolerance_mm: self.tolerance_mm,
            max_iterations,
            trace: self.trace,
            corner_sigma_px: self.corner_sigma_px,
        };
        params
            .validate()
            .map_err(|e| problem_from_estimate_error(e, "/corners_px"))?;
        Ok(params)
    }
}

/// The problem for an estimator refusal; `corners_pointer` names the corner list.
pub fn problem_from_estimate_error(err: EstimateError, corners_pointer: &str) -> Problem {
    match err {
        EstimateError::ParamOutOfRange {
            param,
            value,
            min_exclusive,
            max,
        } => {
            let name = param.name();
            Problem::new(
                ErrorCode::SolverParameterOutOfRange,
                format!(
                    "{name} must be greater than {min_exclusive} and at most {max}, got {value}"
                ),
            )
            .with_field(format!("/solver/{name}"))
        }
        EstimateError::Undistortion { index, source } => {
            Problem::new(ErrorCode::UndistortionFailed, source.to_string())
                .with_field(format!("{corners_pointer}/{index}"))
        }
        EstimateError::PointCount { .. } => {
            Problem::new(ErrorCode::CornerCount, err.to_string()).with_field(corners_pointer)
        }
        EstimateError::NoSolution { .. } => {
            Problem::new(ErrorCode::NoSolution, err.to_string()).with_field(corners_pointer)
        }
    }
}

/// The problem for a refused quadrilateral; `corners_pointer` names the corner list.
pub fn problem_from_quad_error(err: QuadError, corners_pointer: &str) -> Problem {
    let (code, index) = match err {
        QuadError::NonFinite { index } => (ErrorCode::NonFiniteNumber, Some(index)),
        QuadError::Duplicate { second, .. } => (ErrorCode::DuplicateCorners, Some(second)),
        QuadError::Collinear { indices } => (ErrorCode::CollinearCorners, Some(indices[2])),
        QuadError::SelfIntersecting => (ErrorCode::SelfIntersectingCorners, None),
        QuadError::NonConvex { index } => (ErrorCode::NonConvexCorners, Some(index)),
        QuadError::Mirrored => (ErrorCode::MirroredCorners, None),
    };
    let field = match index {
        Some(i) => format!("{corners_pointer}/{i}"),
        None => corners_pointer.to_owned(),
    };
    Problem::new(code, err.to_string()).with_field(field)
}

impl MarkerDto {
    /// The validated marker.
    ///
    /// # Errors
    /// `invalid_marker_size` unless the size is positive and finite.
    pub fn to_marker(&self) -> Result<Marker, Problem> {
        Marker::try_new(self.size_mm).map_err(|e: MarkerError| {
            Problem::new(ErrorCode::InvalidMarkerSize, e.to_string()).with_field("/marker/size_mm")
        })
    }
}

/// Validates camera, marker and solver for corners in `unit`.
///
/// # Errors
/// The first problem found, camera first.
pub fn pose_setup(
    camera: &CameraDto,
    marker: &MarkerDto,
    solver: &SolverDto,
    unit: CornersUnit,
) -> Result<PoseSetup, Problem> {
    let (camera, mm_per_px) = camera.to_camera(unit)?;
    Ok(PoseSetup {
        camera,
        marker: marker.to_marker()?,
        params: solver.to_params()?,
        mm_per_px,
    })
}

/// Exactly four `[u, v]` pairs, or the problem naming the list or the bad pair.
///
/// # Errors
/// `corner_count` for other than four corners, `invalid_type` for a corner that is not a
/// pair of numbers.
pub fn four_corners(corners: &[Vec<f64>], pointer: &str) -> Result<[[f64; 2]; 4], Problem> {
    if corners.len() != 4 {
        return Err(Problem::new(
            ErrorCode::CornerCount,
            format!("exactly 4 corners are needed, got {}", corners.len()),
        )
        .with_field(pointer));
    }
    let mut four = [[0.0; 2]; 4];
    for (i, corner) in corners.iter().enumerate() {
        four[i] = corner.as_slice().try_into().map_err(|_| {
            Problem::new(
                ErrorCode::InvalidType,
                format!("a corner is [u, v], 2 numbers; got {}", corner.len()),
            )
            .with_field(format!("{pointer}/{i}"))
        })?;
    }
    Ok(four)
}

/// A validated corners request: the quadrilateral and everything else.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValidCornersRequest {
    /// The four corners in the camera's image units.
    pub quad: ImageQuad,
    /// Camera, marker, parameters.
    pub setup: PoseSetup,
    /// `/corners_px` or `/corners_mm`, to name corners in later errors.
    pub corners_pointer: &'static str,
}

impl CornersRequest {
    /// Validates the whole request.
    ///
    /// # Errors
    /// A [`Problem`] naming the first field at fault.
    pub fn validate(&self) -> Result<ValidCornersRequest, Problem> {
        let (corners, unit, pointer) = match (&self.corners_px, &self.corners_mm) {
            (Some(px), None) => (px, CornersUnit::Px, "/corners_px"),
            (None, Some(mm)) => (mm, CornersUnit::Mm, "/corners_mm"),
            (None, None) => {
                return Err(Problem::new(
                    ErrorCode::CornersMissingOrConflicting,
                    "give corners_px or corners_mm",
                )
                .with_field("/corners_px"));
            }
            (Some(_), Some(_)) => {
                return Err(Problem::new(
                    ErrorCode::CornersMissingOrConflicting,
                    "give corners_px or corners_mm, not both",
                )
                .with_field("/corners_mm"));
            }
        };
        let setup = pose_setup(&self.camera, &self.marker, &self.solver, unit)?;
        let four = four_corners(corners, pointer)?;
        let scale = setup.mm_per_px.map_or(1.0, |mm_per_px| 1.0 / mm_per_px);
        let points = four.map(|[u, v]| PixelPoint::new(u * scale, v * scale));
        let quad = ImageQuad::try_new(points, self.corner_order.into())
            .map_err(|e| problem_from_quad_error(e, pointer))?;
        Ok(ValidCornersRequest {
            quad,
            setup,
            corners_pointer: pointer,
        })
    }
}
