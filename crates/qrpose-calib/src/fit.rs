//! One fit of a set of views, from nothing to the robust optimum:
//!
//! 1. Zhang's closed form for the intrinsics and each view's pose ([`crate::zhang`]); for
//!    the fisheye model, iterated on pinhole-equivalent pixels ([`crate::fisheye_init`]);
//! 2. the linear radial estimate (Eq. 13, [`crate::distortion_init`]), kept when it lowers
//!    the sum of squared residuals;
//! 3. robust rounds: σ̂ from the residuals, one Levenberg-Marquardt on Huber's loss at
//!    c = 2.5·σ̂ ([`crate::lm`], [`crate::robust`]), until σ̂ moves by less than
//!    [`SCALE_SETTLED`] or after [`MAX_ROBUST_ROUNDS`]. The first round starts from the
//!    closed form's large residuals, so it is nearly plain least squares and converges
//!    from afar; later rounds tighten the threshold to the noise. The rational model is
//!    fitted in two stages: `plumb_bob` first, then `rational_polynomial` from there. Its
//!    numerator and denominator nearly cancel over the few tenths of r² an image spans,
//!    and started from the closed form its eight coefficients can run into a valley far
//!    from the lens (k1 = −11, k2 = 45 on the wide-angle test camera, with one view left
//!    badly fitted and then dropped); the plumb_bob optimum is already in the right one.

use crate::error::SolveFailure;
use crate::input::{ImageSize, Options};
use crate::lm::{self, State, ViewData};
use crate::model::{Intrinsics, Pose};
use crate::robust::{Huber, robust_sigma_px};
use crate::zhang::{self, ClosedFormAssumption};
use crate::{distortion_init, fisheye_init};
use nalgebra::Matrix3;
use qrpose_core::geometry::camera::DistortionModel;

/// Most robust rounds (each a full Levenberg-Marquardt run); σ̂ settles in 2-4.
pub const MAX_ROBUST_ROUNDS: usize = 8;

/// σ̂ has settled when a round moves it by less than this fraction.
pub const SCALE_SETTLED: f64 = 0.01;

/// A fitted set of views.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Fit {
    pub state: State,
    /// The loss of the last round.
    pub loss: Huber,
    /// σ̂ at the solution, px.
    pub sigma_px: f64,
    /// Iterations over every round.
    pub iterations: usize,
    /// Whether the last round converged.
    pub converged: bool,
    /// What the closed form assumed.
    pub assumption: Option<ClosedFormAssumption>,
}

/// Residual lengths, px, of every point; `None` as [`lm::residuals`].
pub(crate) fn residual_lengths(state: &State, views: &[ViewData]) -> Option<Vec<f64>> {
    Some(
        lm::residuals(state, views)?
            .iter()
            .flatten()
            .map(|e| e.norm())
            .collect(),
    )
}

fn sum_of_squares(state: &State, views: &[ViewData]) -> Option<f64> {
    let s: f64 = residual_lengths(state, views)?.iter().map(|e| e * e).sum();
    s.is_finite().then_some(s)
}

/// The result of robust rounds.
struct Rounds {
    state: State,
    loss: Huber,
    sigma_px: f64,
    iterations: usize,
    converged: bool,
}

/// Robust rounds from `state` (module doc, step 3).
fn robust_rounds(
    views: &[ViewData],
    mut state: State,
    options: &Options,
) -> Result<Rounds, SolveFailure> {
    let lengths = residual_lengths(&state, views).ok_or(SolveFailure::NonFiniteStart)?;
    let mut sigma = robust_sigma_px(&lengths);
    let mut loss = Huber::for_scale(sigma);
    let (mut iterations, mut converged) = (0, false);
    for _ in 0..MAX_ROBUST_ROUNDS {
        loss = Huber::for_scale(sigma);
        let outcome = lm::minimise(views, state, loss, options.max_iterations)?;
        state = outcome.state;
        iterations += outcome.iterations;
        converged = outcome.converged;
        let lengths = residual_lengths(&state, views).ok_or(SolveFailure::InvalidCamera)?;
        let next = robust_sigma_px(&lengths);
        let settled = (next - sigma).abs() <= SCALE_SETTLED * sigma;
        sigma = next;
        if settled {
            break;
        }
    }
    Ok(Rounds {
        state,
        loss,
        sigma_px: sigma,
        iterations,
        converged,
    })
}

/// The model fitted first: `plumb_bob` before `rational_polynomial` (module doc, step 3),
/// the model itself otherwise.
fn first_model(model: DistortionModel) -> DistortionModel {
    match model {
        DistortionModel::RationalPolynomial => DistortionModel::PlumbBob,
        other => other,
    }
}

/// Fits `views` with their `homographies` (same order).
///
/// # Errors
/// A [`SolveFailure`] from the closed form or the Levenberg-Marquardt.
pub(crate) fn fit(
    views: &[ViewData],
    homographies: &[Matrix3<f64>],
    image: ImageSize,
    options: &Options,
) -> Result<Fit, SolveFailure> {
    let (init, homographies) = if options.model == DistortionModel::Equidistant {
        fisheye_init::equidistant_start(views, homographies, image)?
    } else {
        (
            zhang::intrinsics_from_homographies(homographies, image)?,
            homographies.to_vec(),
        )
    };
    #[rustfmt::skip]
    let a = Matrix3::new(
        init.fx, 0.0, init.cx,
        0.0, init.fy, init.cy,
        0.0, 0.0, 1.0,
    );
    let poses = homographies
        .iter()
        .map(|h| zhang::pose_from_homography(h, &a))
        .map(|pose| pose.map(|(r, t_mm)| Pose { r, t_mm }))
        .collect::<Option<Vec<_>>>()
        .ok_or(SolveFailure::NonFiniteStart)?;
    let model = first_model(options.model);
    let mut state = State {
        intrinsics: Intrinsics::pinhole(init.fx, init.fy, init.cx, init.cy, model),
        poses,
    };
    let start_cost = sum_of_squares(&state, views).ok_or(SolveFailure::NonFiniteStart)?;
    if let Some(radial) = distortion_init::with_radial_estimate(&state, views)
        && sum_of_squares(&radial, views).is_some_and(|c| c < start_cost)
    {
        state = radial;
    }
    let mut rounds = robust_rounds(views, state, options)?;
    if model != options.model {
        // plumb_bob's coefficients are the rational model's first five, in order; k4..k6
        // start at 0, so the rational fit starts where the plumb_bob fit ended.
        let mut state = rounds.state;
        state.intrinsics.model = options.model;
        let iterations = rounds.iterations;
        rounds = robust_rounds(views, state, options)?;
        rounds.iterations += iterations;
    }
    Ok(Fit {
        state: rounds.state,
        loss: rounds.loss,
        sigma_px: rounds.sigma_px,
        iterations: rounds.iterations,
        converged: rounds.converged,
        assumption: init.assumption,
    })
}
