//! Which solver runs, with its parameters: one [`Solver`] variant per method, each method's
//! parameters, defaults and ranges in the method's own file ([`PaperParams`] in `iterative`,
//! [`DepthNewtonParams`] in `depth_newton`, [`ReprojectionParams`] in `reprojection`).
//!
//! A solver is checked once, by [`Solver::validate`], into a [`ValidSolver`]; the estimators
//! take only a [`ValidSolver`], so no request is validated twice and none is run unchecked.
//! The ranges shared by every method (iteration limit, corner noise, starting depth) live
//! here.

use super::depth_newton::DepthNewtonParams;
use super::iterative::PaperParams;
use super::reprojection::ReprojectionParams;
use super::result::EstimateError;

/// Default iteration limit of every method (the paper's n_max).
pub const DEFAULT_MAX_ITERATIONS: u32 = 30;
/// Upper bound on `max_iterations`, so that no request can keep a worker busy for long
/// (10 000 paper iterations take about 0.3 ms).
pub const MAX_ITERATIONS_LIMIT: u32 = 10_000;
/// Default corner noise, px per coordinate: the covariance's σ and the scale of
/// [`Warning::HighReprojectionError`](super::Warning::HighReprojectionError).
pub const DEFAULT_CORNER_SIGMA_PX: f64 = 0.5;
/// Largest accepted corner noise, px.
pub const MAX_CORNER_SIGMA_PX: f64 = 100.0;
/// Largest accepted starting depth, mm (10 km).
pub const MAX_INITIAL_Z_MM: f64 = 1e7;

/// How the pose is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Method {
    /// The paper's iteration (`docs/paper-method.md`).
    Paper,
    /// The paper's equations solved by Levenberg-Marquardt.
    DepthNewton,
    /// IPPE plus Levenberg-Marquardt on pixel error (the default).
    #[default]
    Reprojection,
}

impl Method {
    /// Every method, in the order of the documentation.
    pub const ALL: [Method; 3] = [Method::Paper, Method::DepthNewton, Method::Reprojection];

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

/// A method and its parameters. [`Solver::default`] is `reprojection` with its defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Solver {
    /// The paper's iteration.
    Paper(PaperParams),
    /// The paper's unknowns and residuals by Levenberg-Marquardt.
    DepthNewton(DepthNewtonParams),
    /// IPPE's two candidates refined on pixel error.
    Reprojection(ReprojectionParams),
}

impl Default for Solver {
    fn default() -> Self {
        Self::default_for(Method::default())
    }
}

impl Solver {
    /// `method` with its default parameters.
    #[must_use]
    pub fn default_for(method: Method) -> Self {
        match method {
            Method::Paper => Self::Paper(PaperParams::default()),
            Method::DepthNewton => Self::DepthNewton(DepthNewtonParams::default()),
            Method::Reprojection => Self::Reprojection(ReprojectionParams::default()),
        }
    }

    /// The method.
    #[must_use]
    pub fn method(&self) -> Method {
        match self {
            Self::Paper(_) => Method::Paper,
            Self::DepthNewton(_) => Method::DepthNewton,
            Self::Reprojection(_) => Method::Reprojection,
        }
    }

    /// The corner noise σ, px per coordinate, that scales the reprojection warning (and,
    /// for `reprojection`, the covariance and the ambiguity test).
    #[must_use]
    pub fn corner_sigma_px(&self) -> f64 {
        match self {
            Self::Paper(p) => p.corner_sigma_px,
            Self::DepthNewton(p) => p.corner_sigma_px,
            Self::Reprojection(p) => p.corner_sigma_px,
        }
    }

    /// Checks every parameter of the method against its range.
    ///
    /// # Errors
    /// [`EstimateError::ParamOutOfRange`] for the first parameter outside its range.
    pub fn validate(self) -> Result<ValidSolver, EstimateError> {
        match &self {
            Self::Paper(p) => p.validate()?,
            Self::DepthNewton(p) => p.validate()?,
            Self::Reprojection(p) => p.validate()?,
        }
        Ok(ValidSolver(self))
    }
}

/// A [`Solver`] whose parameters are in range: built only by [`Solver::validate`] (or as
/// the default, which is valid).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ValidSolver(Solver);

impl ValidSolver {
    /// The solver.
    #[must_use]
    pub fn solver(&self) -> &Solver {
        &self.0
    }

    /// The method.
    #[must_use]
    pub fn method(&self) -> Method {
        self.0.method()
    }

    /// `method` with its default parameters (always valid).
    #[must_use]
    pub fn default_for(method: Method) -> Self {
        Self(Solver::default_for(method))
    }

    /// The parameters every method shares (iteration limit, trace, corner noise), as the
    /// `reprojection` method's: what a solve from more than four plane points runs with.
    #[must_use]
    pub fn as_reprojection(&self) -> ReprojectionParams {
        match self.0 {
            Solver::Paper(p) => ReprojectionParams {
                max_iterations: p.max_iterations,
                trace: p.trace,
                corner_sigma_px: p.corner_sigma_px,
            },
            Solver::DepthNewton(p) => ReprojectionParams {
                max_iterations: p.max_iterations,
                trace: p.trace,
                corner_sigma_px: p.corner_sigma_px,
            },
            Solver::Reprojection(p) => p,
        }
    }
}

/// `Ok` when `value` is finite and in (`min_exclusive`, `max`].
///
/// # Errors
/// [`EstimateError::ParamOutOfRange`] naming `param`.
pub(super) fn check_range(
    value: f64,
    param: SolverParam,
    min_exclusive: f64,
    max: f64,
) -> Result<(), EstimateError> {
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
}

/// The checks every method shares: the iteration limit and the corner noise.
///
/// # Errors
/// [`EstimateError::ParamOutOfRange`] for the first one out of range.
pub(super) fn check_common(max_iterations: u32, corner_sigma_px: f64) -> Result<(), EstimateError> {
    check_range(
        f64::from(max_iterations),
        SolverParam::MaxIterations,
        0.0,
        f64::from(MAX_ITERATIONS_LIMIT),
    )?;
    check_range(
        corner_sigma_px,
        SolverParam::CornerSigmaPx,
        0.0,
        MAX_CORNER_SIGMA_PX,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_for_every_method() {
        for method in Method::ALL {
            let solver = Solver::default_for(method);
            assert_eq!(solver.method(), method);
            assert_eq!(
                solver.validate(),
                Ok(ValidSolver::default_for(method)),
                "{method:?}"
            );
        }
        assert_eq!(Solver::default().method(), Method::Reprojection);
    }

    #[test]
    fn refuses_each_parameter_out_of_range() {
        let paper = PaperParams::default();
        let cases = [
            (
                Solver::Paper(PaperParams { gain: 0.0, ..paper }),
                SolverParam::Gain,
            ),
            (
                Solver::Paper(PaperParams {
                    tolerance_mm: f64::NAN,
                    ..paper
                }),
                SolverParam::ToleranceMm,
            ),
            (
                Solver::Paper(PaperParams {
                    initial_z_mm: 2e7,
                    ..paper
                }),
                SolverParam::InitialZMm,
            ),
            (
                Solver::DepthNewton(DepthNewtonParams {
                    initial_z_mm: Some(-1.0),
                    ..DepthNewtonParams::default()
                }),
                SolverParam::InitialZMm,
            ),
            (
                Solver::DepthNewton(DepthNewtonParams {
                    max_iterations: 0,
                    ..DepthNewtonParams::default()
                }),
                SolverParam::MaxIterations,
            ),
            (
                Solver::Reprojection(ReprojectionParams {
                    max_iterations: MAX_ITERATIONS_LIMIT + 1,
                    ..ReprojectionParams::default()
                }),
                SolverParam::MaxIterations,
            ),
            (
                Solver::Reprojection(ReprojectionParams {
                    corner_sigma_px: 101.0,
                    ..ReprojectionParams::default()
                }),
                SolverParam::CornerSigmaPx,
            ),
        ];
        for (solver, param) in cases {
            match solver.validate() {
                Err(EstimateError::ParamOutOfRange { param: got, .. }) => {
                    assert_eq!(got, param, "{solver:?}");
                }
                other => panic!("{solver:?}: {other:?}"),
            }
        }
    }
}
