//! The solver of a pose request (`solver`): the method and its parameters, every field
//! optional, validated into the core's [`ValidSolver`].

use super::problem::{ErrorCode, Problem};
use super::refusal::problem_from_estimate_error;
use super::request::MethodDto;
use crate::estimate::{
    DEFAULT_CORNER_SIGMA_PX, DEFAULT_GAIN, DEFAULT_INITIAL_Z_MM, DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOLERANCE_MM, DepthNewtonParams, MAX_ITERATIONS_LIMIT, Method, PaperParams,
    ReprojectionParams, Solver, ValidSolver,
};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

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
    #[schema(default = MethodDto::default)]
    pub method: MethodDto,
    /// Starting depth of every corner, mm, in (0, 1e7]. `paper`: z0 (default 450, as in the
    /// paper). `depth-newton`: replaces its closed-form start. Unused by `reprojection`.
    #[schema(example = 450.0, exclusive_minimum = 0, maximum = 1e7)]
    pub initial_z_mm: Option<f64>,
    /// `paper` only: updating coefficient k of Eq. 12, in (0, 10]. Default 1.
    #[serde(default = "default_gain")]
    #[schema(example = 1.0, default = default_gain, exclusive_minimum = 0, maximum = 10)]
    pub gain: f64,
    /// `paper` only: convergence threshold e_d on Σ|Δz| (Eq. 13), mm, in (0, 1e6]. Default 1.
    #[serde(default = "default_tolerance_mm")]
    #[schema(example = 1.0, default = default_tolerance_mm, exclusive_minimum = 0, maximum = 1e6)]
    pub tolerance_mm: f64,
    /// Iteration limit of every method, 1 to 10000. Default 30.
    #[serde(
        default = "default_max_iterations",
        deserialize_with = "super::integral::deserialize"
    )]
    #[schema(example = 30, default = default_max_iterations, minimum = 1, maximum = 10000)]
    pub max_iterations: u64,
    /// Return the per-iteration trace (corner depths and Σ|Δz|). Default false.
    #[serde(default)]
    #[schema(default = false)]
    pub trace: bool,
    /// `reprojection` only: corner noise σ per coordinate, px, in (0, 100], for the pose
    /// covariance. Default 0.5.
    #[serde(default = "default_corner_sigma_px")]
    #[schema(example = 0.5, default = default_corner_sigma_px, exclusive_minimum = 0, maximum = 100)]
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

impl SolverDto {
    /// The method's [`Solver`], validated. Parameters the chosen method does not read
    /// (`gain` with `reprojection`, say) are range-checked and then ignored, as documented
    /// per field.
    ///
    /// # Errors
    /// `solver_parameter_out_of_range` naming the parameter.
    pub fn to_solver(&self) -> Result<ValidSolver, Problem> {
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
        // Every parameter given is range-checked, also those the chosen method ignores
        // (`gain` with `reprojection`): an out-of-range value is a client's mistake either way.
        let paper = PaperParams {
            initial_z_mm: self.initial_z_mm.unwrap_or(DEFAULT_INITIAL_Z_MM),
            gain: self.gain,
            tolerance_mm: self.tolerance_mm,
            max_iterations,
            trace: self.trace,
            corner_sigma_px: self.corner_sigma_px,
        };
        let solver = match Method::from(self.method) {
            Method::Paper => Solver::Paper(paper),
            Method::DepthNewton => {
                paper
                    .validate()
                    .map_err(|e| problem_from_estimate_error(e, "/corners_px"))?;
                Solver::DepthNewton(DepthNewtonParams {
                    initial_z_mm: self.initial_z_mm,
                    max_iterations,
                    trace: self.trace,
                    corner_sigma_px: self.corner_sigma_px,
                })
            }
            Method::Reprojection => {
                paper
                    .validate()
                    .map_err(|e| problem_from_estimate_error(e, "/corners_px"))?;
                Solver::Reprojection(ReprojectionParams {
                    max_iterations,
                    trace: self.trace,
                    corner_sigma_px: self.corner_sigma_px,
                })
            }
        };
        solver
            .validate()
            .map_err(|e| problem_from_estimate_error(e, "/corners_px"))
    }
}
