//! Response bodies: the pose of one marker, with rotation and diagnostics.

use super::finite::first_non_finite;
use super::frames::{FramePoseDto, MarkerSizeSourceDto};
use super::pick::ObjectDto;
use super::problem::{ErrorCode, Problem};
use super::request::MethodDto;
use crate::app::InFrames;
use crate::estimate::{Ambiguity, Diagnostics, Method, PoseEstimate, TraceStep, Warning};
use crate::geometry::{
    camera::{Camera, ImageUnit},
    euler::{EulerXyz, quaternion_wxyz},
    frames::MarkerPoint,
    marker::{Corner, Marker},
};
use nalgebra::{Rotation3, Vector3};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A point or vector, mm: in the camera frame (x right, y down, z forward) unless the field
/// names another frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Vec3Mm {
    /// Right, mm.
    pub x: f64,
    /// Down, mm.
    pub y: f64,
    /// Forward (depth), mm.
    pub z: f64,
}

impl From<Vector3<f64>> for Vec3Mm {
    fn from(v: Vector3<f64>) -> Self {
        Self {
            x: v.x,
            y: v.y,
            z: v.z,
        }
    }
}

/// One corner of the marker in the camera frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CornerMm {
    /// The paper's label: P1, P2, P3 or P4.
    #[schema(example = "P1")]
    pub label: String,
    /// Which corner of the symbol: bottom_right (P1), top_right (P2), top_left (P3),
    /// bottom_left (P4).
    #[schema(example = "bottom_right")]
    pub qr_corner: String,
    /// Right, mm.
    pub x: f64,
    /// Down, mm.
    pub y: f64,
    /// Forward (depth), mm.
    pub z: f64,
}

/// Euler angles of R = Rx(alpha)·Ry(beta)·Rz(gamma), counter-clockwise about the camera
/// axes (paper Eq. 17), degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct EulerXyzDeg {
    /// About the camera x axis, degrees, in (−180, 180].
    pub alpha: f64,
    /// About the camera y axis, degrees, in [−90, 90].
    pub beta: f64,
    /// About the camera z axis, degrees, in (−180, 180]; 0 at gimbal lock (|beta| = 90).
    pub gamma: f64,
}

/// The marker's orientation: p_cam = R·p_marker + t.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RotationDto {
    /// Euler angles, degrees.
    pub euler_xyz_deg: EulerXyzDeg,
    /// R, row-major (`matrix[row][column]`).
    pub matrix: [[f64; 3]; 3],
    /// R as a unit quaternion (w, x, y, z) with w ≥ 0.
    pub quaternion_wxyz: [f64; 4],
}

/// The other pose of the planar ambiguity (`reprojection` only): the same four corners seen
/// as a square tilted the other way. Near-frontal and small or distant markers can make the
/// two fit about equally well.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct AmbiguityDto {
    /// The alternative pose's marker centre, camera frame, mm.
    pub alternative_position_mm: Vec3Mm,
    /// The alternative pose's orientation.
    pub alternative_rotation: RotationDto,
    /// Reprojection RMS of the alternative pose after its own refinement, px; null for an
    /// image-plane-mm camera without a pixel size.
    pub alternative_rms_px: Option<f64>,
    /// Best RMS / alternative RMS, in [0, 1]; near 1 when the two cannot be told apart.
    pub ratio: f64,
    /// Angle between the two poses' rotations, degrees.
    pub rotation_difference_deg: f64,
    /// Probability that the alternative, not the reported pose, is the true one, given
    /// Gaussian corner noise of `solver.corner_sigma_px` (calibrated: see docs/accuracy.md);
    /// 0 when both candidates are one pose; null for an image-plane-mm camera without a
    /// pixel size.
    pub alternative_probability: Option<f64>,
    /// True when the poses differ by more than 0.1° and `alternative_probability` ≥ 0.01,
    /// i.e. `ratio` ≥ RMS_best / √(RMS_best² + ½·σ²·ln 99) (without pixel units: `ratio` ≥
    /// 0.3). The reported pose may then be the mirror image of the true one: use it only with
    /// other evidence, e.g. a `prior`.
    pub ambiguous: bool,
    /// What chose the reported pose: `fit` (the better reprojection fit) or `prior` (the
    /// request's `prior` weighed with the fit; `alternative_probability` then includes the
    /// prior, and the reported pose may be the one that fits slightly worse).
    pub resolved_by: ResolvedByDto,
}

/// What chose between the two poses of the planar ambiguity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ResolvedByDto {
    /// The better reprojection fit.
    Fit,
    /// The request's `prior`, weighed with the fit.
    Prior,
}

/// The pose covariance for the stated corner noise (`reprojection` only).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CovarianceDto {
    /// Parameter order: a small rotation about the camera x, y, z axes applied on the left
    /// of R (rad), then the marker centre's position (mm).
    pub order: [String; 6],
    /// 6×6 symmetric covariance, rad² / rad·mm / mm².
    pub matrix: [[f64; 6]; 6],
}

/// One iteration: the four corner depths and their total change.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TraceStepDto {
    /// 1-based iteration number.
    pub iteration: u32,
    /// z1..z4 (P1..P4) after the iteration, mm.
    pub z_mm: [f64; 4],
    /// Σ|z_i(n) − z_i(n−1)|, mm (paper Eq. 13).
    pub convergence_error_mm: f64,
}

/// Something the caller should know before trusting the pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum WarningDto {
    /// The method hit `max_iterations` before converging.
    NotConverged,
    /// The two poses of the planar ambiguity fit about equally well.
    PoseAmbiguous,
    /// A corner of the solved pose is at or behind the camera.
    BehindCamera,
    /// The reprojection RMS exceeds 4× `corner_sigma_px`: the corners do not look like a
    /// square under this camera (wrong intrinsics, marker size or corners?).
    HighReprojectionError,
}

impl From<Warning> for WarningDto {
    fn from(w: Warning) -> Self {
        match w {
            Warning::NotConverged => WarningDto::NotConverged,
            Warning::PoseAmbiguous => WarningDto::PoseAmbiguous,
            Warning::BehindCamera => WarningDto::BehindCamera,
            Warning::HighReprojectionError => WarningDto::HighReprojectionError,
        }
    }
}

/// How the pose was found and how far to trust it. Fields a method does not produce are null.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct DiagnosticsDto {
    /// The method used: `paper`, `depth-newton` or `reprojection`.
    #[schema(value_type = String, example = "reprojection")]
    pub method: MethodDto,
    /// Whether the method met its convergence criterion. A `false` still carries the last
    /// estimate.
    pub converged: bool,
    /// Iterations run.
    pub iterations: u32,
    /// `paper`, `depth-newton`: Σ|Δz| of the last iteration (e_c, Eq. 13), mm.
    pub convergence_error_mm: Option<f64>,
    /// `paper`, `depth-newton`: e1..e6 = known − computed length of l1..l6 (P1P2, P2P3,
    /// P3P4, P1P4, P1P3, P2P4) at the final depths, mm.
    pub side_residuals_mm: Option<[f64; 6]>,
    /// RMS distance between the measured corners and the model corners projected under the
    /// reported pose, px (in the undistorted image); null for an image-plane-mm camera
    /// without a pixel size, or when a corner is behind the camera.
    pub reprojection_rms_px: Option<f64>,
    /// `reprojection`: the other candidate of the planar ambiguity.
    pub ambiguity: Option<AmbiguityDto>,
    /// `reprojection` with a pixel camera: pose covariance for `solver.corner_sigma_px`.
    pub covariance: Option<CovarianceDto>,
    /// The per-iteration trace when `solver.trace` is true.
    pub trace: Option<Vec<TraceStepDto>>,
    /// Conditions to check before trusting the pose; empty when there are none.
    pub warnings: Vec<WarningDto>,
    /// Time spent validating and estimating, µs.
    pub elapsed_us: f64,
}

/// The pose of one marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "position_mm": {"x": 25.0, "y": 10.0, "z": 500.0},
    "reference_point_mm": {"x": 50.0, "y": -15.0, "z": 500.0},
    "distance_mm": 500.72,
    "marker_size_mm": 50.0,
    "marker_size_source": "request",
    "corners_mm": [{"label": "P1", "qr_corner": "bottom_right", "x": 50.0, "y": 35.0, "z": 500.0}],
    "rotation": {"euler_xyz_deg": {"alpha": 0.0, "beta": 0.0, "gamma": 0.0},
                 "matrix": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                 "quaternion_wxyz": [1.0, 0.0, 0.0, 0.0]},
    "pose_in_robot": null,
    "robot_pose_in_world": null,
    "diagnostics": {"method": "reprojection", "converged": true, "iterations": 2,
                    "convergence_error_mm": null, "side_residuals_mm": null,
                    "reprojection_rms_px": 0.0,
                    "ambiguity": {"alternative_position_mm": {"x": 24.1, "y": 10.3, "z": 502.2},
                                  "alternative_rotation": {"euler_xyz_deg": {"alpha": 2.9, "beta": -1.2, "gamma": 0.1},
                                      "matrix": [[0.9998, -0.0017, -0.0209], [0.0028, 0.9987, 0.0506], [0.0208, -0.0506, 0.9985]],
                                      "quaternion_wxyz": [0.9996, -0.0253, -0.0104, 0.0011]},
                                  "alternative_rms_px": 0.84, "ratio": 0.0,
                                  "rotation_difference_deg": 3.1,
                                  "alternative_probability": 0.0, "ambiguous": false,
                                  "resolved_by": "fit"},
                    "covariance": null, "trace": null, "warnings": [], "elapsed_us": 4.2}
}))]
pub struct PoseResponse {
    /// The marker centre in the camera frame, mm.
    pub position_mm: Vec3Mm,
    /// Corner P2 (the symbol's top-right corner, the marker-frame origin) in the camera
    /// frame, mm: the translation t of p_cam = R·p_marker + t.
    pub reference_point_mm: Vec3Mm,
    /// Distance from the camera's optical centre to the marker centre, mm.
    pub distance_mm: f64,
    /// The side of the QR symbol this pose was computed with, mm.
    pub marker_size_mm: f64,
    /// Where `marker_size_mm` came from: `request`, or the site's rule for the payload
    /// (`site:exact`, `site:prefix`, `site:pattern`) or its default (`site:default`).
    pub marker_size_source: MarkerSizeSourceDto,
    /// The four corners P1..P4 in the camera frame, mm.
    pub corners_mm: Vec<CornerMm>,
    /// The marker's orientation.
    pub rotation: RotationDto,
    /// The code in the robot frame (T_robot←marker, origin at the code's centre), when the
    /// request names a site camera with a `mount`; else null.
    pub pose_in_robot: Option<FramePoseDto>,
    /// The robot's pose in the warehouse frame from this code alone (T_world←robot), when
    /// the code's payload is in the site's `map` and the camera has a `mount`; else null.
    pub robot_pose_in_world: Option<FramePoseDto>,
    /// The product the payload names in the site's `objects`, with its grasps; else null
    /// (`docs/pick.md`).
    pub object: Option<ObjectDto>,
    /// How the pose was found and how far to trust it.
    pub diagnostics: DiagnosticsDto,
}

/// The refusal of a pose whose number at `pointer` (within the pose) is not finite.
pub fn numerically_degenerate(pointer: &str, corners_pointer: &str) -> Problem {
    Problem::new(
        ErrorCode::NumericallyDegenerate,
        format!(
            "the pose cannot be computed in double precision: {pointer} came out NaN or infinite; \
             the magnitudes of the corners, intrinsics or marker size are out of reach"
        ),
    )
    .with_field(corners_pointer)
}

/// Covariance parameter names, in order.
pub const COVARIANCE_ORDER: [&str; 6] = ["rx_rad", "ry_rad", "rz_rad", "x_mm", "y_mm", "z_mm"];

fn px_value(value: f64, camera: &Camera) -> Option<f64> {
    (camera.unit() == ImageUnit::Pixel).then_some(value)
}

impl RotationDto {
    /// Euler angles, matrix and quaternion of a rotation.
    pub fn from_rotation(r: &Rotation3<f64>) -> Self {
        let [alpha, beta, gamma] = EulerXyz::from_rotation(r).to_degrees();
        let m = r.matrix();
        Self {
            euler_xyz_deg: EulerXyzDeg { alpha, beta, gamma },
            matrix: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
            quaternion_wxyz: quaternion_wxyz(r),
        }
    }
}

impl DiagnosticsDto {
    fn new(d: &Diagnostics, camera: &Camera, marker_centre: &MarkerPoint, elapsed_us: f64) -> Self {
        Self {
            method: d.method.into(),
            converged: d.converged,
            iterations: d.iterations,
            convergence_error_mm: d.convergence_error_mm,
            side_residuals_mm: d.side_residuals_mm,
            reprojection_rms_px: d.reprojection_rms.and_then(|rms| px_value(rms, camera)),
            ambiguity: d.ambiguity.map(|a: Ambiguity| AmbiguityDto {
                alternative_position_mm: a.alternative.transform(marker_centre).0.coords.into(),
                alternative_rotation: RotationDto::from_rotation(&a.alternative.rotation()),
                alternative_rms_px: px_value(a.alternative_rms, camera).filter(|v| v.is_finite()),
                ratio: a.ratio,
                rotation_difference_deg: a.rotation_difference_rad.to_degrees(),
                alternative_probability: a.alternative_probability,
                ambiguous: a.ambiguous,
                resolved_by: ResolvedByDto::Fit,
            }),
            covariance: d.covariance.map(|c| CovarianceDto {
                order: COVARIANCE_ORDER.map(str::to_owned),
                matrix: std::array::from_fn(|i| std::array::from_fn(|j| c[(i, j)])),
            }),
            trace: d.trace.as_ref().map(|steps| {
                steps
                    .iter()
                    .map(|s: &TraceStep| TraceStepDto {
                        iteration: s.iteration,
                        z_mm: s.z_mm,
                        convergence_error_mm: s.convergence_error_mm,
                    })
                    .collect()
            }),
            warnings: d.warnings.iter().map(|w| (*w).into()).collect(),
            elapsed_us,
        }
    }
}

impl PoseResponse {
    /// The wire form of an estimate.
    pub fn new(estimate: &PoseEstimate, camera: &Camera, marker: &Marker, elapsed_us: f64) -> Self {
        let corners_mm = Corner::ALL
            .iter()
            .zip(&estimate.corners_cam)
            .map(|(c, p)| CornerMm {
                label: c.label().to_owned(),
                qr_corner: c.qr_corner().to_owned(),
                x: p.0.x,
                y: p.0.y,
                z: p.0.z,
            })
            .collect();
        Self {
            position_mm: estimate.centre_mm.into(),
            reference_point_mm: estimate.pose.translation_mm().into(),
            distance_mm: estimate.centre_mm.norm(),
            marker_size_mm: marker.size_mm(),
            marker_size_source: MarkerSizeSourceDto::Request,
            corners_mm,
            rotation: RotationDto::from_rotation(&estimate.pose.rotation()),
            pose_in_robot: None,
            robot_pose_in_world: None,
            object: None,
            diagnostics: DiagnosticsDto::new(
                &estimate.diagnostics,
                camera,
                &marker.centre(),
                elapsed_us,
            ),
        }
    }

    /// [`PoseResponse::new`], checked: every number must be finite (serde_json would write
    /// NaN or ±∞ as `null` where the schema promises a number). The image path calls this
    /// for each marker and answers a refusal as the marker's `problem`, with `pose: null`.
    ///
    /// # Errors
    /// 422 `numerically_degenerate` naming the first non-finite number; `field` is
    /// `corners_pointer` (the corner list whose scale broke the arithmetic).
    pub fn try_new(
        estimate: &PoseEstimate,
        camera: &Camera,
        marker: &Marker,
        elapsed_us: f64,
        corners_pointer: &str,
    ) -> Result<Self, Problem> {
        let response = Self::new(estimate, camera, marker, elapsed_us);
        match first_non_finite(&response) {
            None => Ok(response),
            Some(pointer) => Err(numerically_degenerate(&pointer, corners_pointer)),
        }
    }

    /// This pose with what a site adds: the size's source, the code in the robot frame and
    /// the robot in the world (each null when the site does not allow it), and the prior's
    /// mark on the ambiguity.
    ///
    /// # Errors
    /// 422 `numerically_degenerate` (field `corners_pointer`) when a number of the added
    /// poses is not finite.
    pub fn with_site(
        mut self,
        source: MarkerSizeSourceDto,
        frames: &InFrames,
        resolved_by_prior: bool,
        corners_pointer: &str,
    ) -> Result<Self, Problem> {
        self.marker_size_source = source;
        self.pose_in_robot = frames.in_robot.as_ref().map(FramePoseDto::from);
        self.robot_pose_in_world = frames.in_world.as_ref().map(FramePoseDto::from);
        self.object = frames.object.as_ref().map(ObjectDto::from);
        if resolved_by_prior && let Some(a) = self.diagnostics.ambiguity.as_mut() {
            a.resolved_by = ResolvedByDto::Prior;
        }
        let added = (&self.pose_in_robot, &self.robot_pose_in_world, &self.object);
        match first_non_finite(&added) {
            None => Ok(self),
            Some(pointer) => Err(numerically_degenerate(&pointer, corners_pointer)),
        }
    }

    /// The method that produced this pose.
    pub fn method(&self) -> Method {
        self.diagnostics.method.into()
    }
}
