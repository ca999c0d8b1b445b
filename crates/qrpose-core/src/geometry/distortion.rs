//! Lens distortion in OpenCV's three common models, with OpenCV's coefficients, order and
//! meaning, applied to normalised coordinates (`docs/conventions.md`, Normalised coordinates
//! and distortion; `docs/calibration.md`, Lens models):
//!
//! - `plumb_bob` ([`PlumbBob`]): Brown-Conrady, k1 k2 p1 p2 k3, as `cv::projectPoints`;
//! - `rational_polynomial` ([`RationalPolynomial`]): k1 k2 p1 p2 k3 k4 k5 k6, OpenCV's
//!   rational model (`CALIB_RATIONAL_MODEL`): the radial factor is a ratio of two
//!   polynomials in r²;
//! - `equidistant` ([`Equidistant`]): the fisheye model of `cv::fisheye::projectPoints`,
//!   k1 k2 k3 k4 on the angle θ from the optical axis.
//!
//! [`Distortion`] holds one of them. Its forward map [`Distortion::distort`] takes an ideal
//! normalised point (x, y) = (X/Z, Y/Z) to the distorted one; its inverse
//! [`Distortion::undistort`] has no closed form and is solved by Newton's method to
//! [`UNDISTORT_TOL`] in normalised units (far below 1e-6 px for any real focal length):
//! with the 2 × 2 Jacobian for the two radial-tangential models (module
//! `radial_tangential`), and on θ alone for the fisheye model (module `equidistant`).

mod equidistant;
mod radial_tangential;

pub use equidistant::Equidistant;
pub use radial_tangential::{PlumbBob, RationalPolynomial};

use super::camera::{CameraError, CameraParam};
use super::frames::NormalizedPoint;
use thiserror::Error;

/// Convergence tolerance of the undistortion, normalised units (1e-12 · fx px; 1e-9 px at
/// fx = 1000 px).
pub const UNDISTORT_TOL: f64 = 1e-12;

/// Newton iterations allowed for one undistortion; it converges in 3-6 on real lenses.
pub const UNDISTORT_MAX_ITERATIONS: usize = 50;

/// Which lens model, by the name ROS `camera_info` gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DistortionModel {
    /// Brown-Conrady: k1 k2 p1 p2 k3.
    PlumbBob,
    /// OpenCV's rational model: k1 k2 p1 p2 k3 k4 k5 k6.
    RationalPolynomial,
    /// OpenCV's fisheye model: k1 k2 k3 k4 on the angle from the axis.
    Equidistant,
}

/// The coefficients of each model, in OpenCV's order.
const PLUMB_BOB_PARAMS: [CameraParam; 5] = [
    CameraParam::K1,
    CameraParam::K2,
    CameraParam::P1,
    CameraParam::P2,
    CameraParam::K3,
];
const RATIONAL_PARAMS: [CameraParam; 8] = [
    CameraParam::K1,
    CameraParam::K2,
    CameraParam::P1,
    CameraParam::P2,
    CameraParam::K3,
    CameraParam::K4,
    CameraParam::K5,
    CameraParam::K6,
];
const EQUIDISTANT_PARAMS: [CameraParam; 4] = [
    CameraParam::K1,
    CameraParam::K2,
    CameraParam::K3,
    CameraParam::K4,
];

impl DistortionModel {
    /// Every model, in the order of the docs.
    pub const ALL: [Self; 3] = [Self::PlumbBob, Self::RationalPolynomial, Self::Equidistant];

    /// The model's name as ROS `camera_info` and the API spell it (`plumb_bob`, …).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::PlumbBob => "plumb_bob",
            Self::RationalPolynomial => "rational_polynomial",
            Self::Equidistant => "equidistant",
        }
    }

    /// The model's coefficients, in OpenCV's order.
    #[must_use]
    pub const fn params(self) -> &'static [CameraParam] {
        match self {
            Self::PlumbBob => &PLUMB_BOB_PARAMS,
            Self::RationalPolynomial => &RATIONAL_PARAMS,
            Self::Equidistant => &EQUIDISTANT_PARAMS,
        }
    }

    /// How many coefficients the model takes (5, 8 or 4).
    #[must_use]
    pub const fn coefficient_count(self) -> usize {
        self.params().len()
    }
}

impl std::fmt::Display for DistortionModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for DistortionModel {
    type Err = DistortionError;

    /// Parses a model name exactly as [`DistortionModel::name`] spells it.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| DistortionError::UnknownModel {
                name: name.to_owned(),
            })
    }
}

/// Why a set of distortion coefficients was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DistortionError {
    /// The model's name is none of `plumb_bob`, `rational_polynomial`, `equidistant`.
    #[error(
        "unknown distortion model {name:?}; the models are plumb_bob, rational_polynomial and equidistant"
    )]
    UnknownModel {
        /// The name given.
        name: String,
    },
    /// The number of coefficients is not the model's: they cannot be matched to its terms.
    #[error("the {model} model takes {expected} coefficients, got {got}")]
    CoefficientCount {
        /// The model.
        model: DistortionModel,
        /// How many it takes.
        expected: usize,
        /// How many were given.
        got: usize,
    },
    /// A coefficient is NaN or infinite: nothing can be computed from it.
    #[error("distortion coefficient {param} is not a finite number")]
    NonFinite {
        /// The coefficient at fault.
        param: CameraParam,
    },
}

/// Checks that every coefficient is finite, naming the first that is not.
fn check_finite(values: &[f64], params: &[CameraParam]) -> Result<(), CameraParam> {
    match values.iter().zip(params).find(|(v, _)| !v.is_finite()) {
        Some((_, &param)) => Err(param),
        None => Ok(()),
    }
}

/// Lens distortion: one of OpenCV's models with its coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distortion {
    /// Brown-Conrady (`plumb_bob`).
    PlumbBob(PlumbBob),
    /// OpenCV's rational model (`rational_polynomial`).
    RationalPolynomial(RationalPolynomial),
    /// OpenCV's fisheye model (`equidistant`).
    Equidistant(Equidistant),
}

impl Default for Distortion {
    fn default() -> Self {
        Self::NONE
    }
}

impl From<PlumbBob> for Distortion {
    fn from(d: PlumbBob) -> Self {
        Self::PlumbBob(d)
    }
}

impl From<RationalPolynomial> for Distortion {
    fn from(d: RationalPolynomial) -> Self {
        Self::RationalPolynomial(d)
    }
}

impl From<Equidistant> for Distortion {
    fn from(d: Equidistant) -> Self {
        Self::Equidistant(d)
    }
}

impl Distortion {
    /// No distortion (`plumb_bob` with every coefficient 0).
    pub const NONE: Self = Self::PlumbBob(PlumbBob::NONE);

    /// Brown-Conrady distortion, checking that every coefficient is finite.
    ///
    /// # Errors
    /// [`CameraError::NonFinite`] naming the first bad coefficient.
    pub fn try_new(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Result<Self, CameraError> {
        check_finite(&[k1, k2, p1, p2, k3], &PLUMB_BOB_PARAMS)
            .map_err(|param| CameraError::NonFinite { param })?;
        Ok(Self::PlumbBob(PlumbBob { k1, k2, p1, p2, k3 }))
    }

    /// The model `model` with `coefficients` in OpenCV's order (as
    /// [`DistortionModel::params`] lists them).
    ///
    /// # Errors
    /// [`DistortionError::CoefficientCount`] when there are not exactly
    /// [`DistortionModel::coefficient_count`] of them, [`DistortionError::NonFinite`] naming
    /// the first coefficient that is NaN or infinite.
    ///
    /// # Example
    /// A fisheye lens: distort an ideal point 60° off the axis, then undistort it back.
    /// ```
    /// use qrpose_core::geometry::camera::{Distortion, DistortionModel};
    /// use qrpose_core::geometry::frames::NormalizedPoint;
    ///
    /// let coefficients = [-0.00566, 0.04186, -0.03869, 0.00673];
    /// let lens = Distortion::from_coefficients(DistortionModel::Equidistant, &coefficients)?;
    /// let ideal = NormalizedPoint::new(60f64.to_radians().tan(), 0.0);
    /// let seen = lens.distort(&ideal);
    /// let back = lens.undistort(&seen).expect("within 90° of the axis");
    /// assert!((back.x() - ideal.x()).abs() < 1e-12 && back.y() == 0.0);
    /// # Ok::<(), qrpose_core::geometry::distortion::DistortionError>(())
    /// ```
    pub fn from_coefficients(
        model: DistortionModel,
        coefficients: &[f64],
    ) -> Result<Self, DistortionError> {
        let expected = model.coefficient_count();
        if coefficients.len() != expected {
            return Err(DistortionError::CoefficientCount {
                model,
                expected,
                got: coefficients.len(),
            });
        }
        check_finite(coefficients, model.params())
            .map_err(|param| DistortionError::NonFinite { param })?;
        let c = |i: usize| coefficients[i];
        Ok(match model {
            DistortionModel::PlumbBob => Self::PlumbBob(PlumbBob {
                k1: c(0),
                k2: c(1),
                p1: c(2),
                p2: c(3),
                k3: c(4),
            }),
            DistortionModel::RationalPolynomial => Self::RationalPolynomial(RationalPolynomial {
                k1: c(0),
                k2: c(1),
                p1: c(2),
                p2: c(3),
                k3: c(4),
                k4: c(5),
                k5: c(6),
                k6: c(7),
            }),
            DistortionModel::Equidistant => Self::Equidistant(Equidistant {
                k1: c(0),
                k2: c(1),
                k3: c(2),
                k4: c(3),
            }),
        })
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> DistortionModel {
        match self {
            Self::PlumbBob(_) => DistortionModel::PlumbBob,
            Self::RationalPolynomial(_) => DistortionModel::RationalPolynomial,
            Self::Equidistant(_) => DistortionModel::Equidistant,
        }
    }

    /// The coefficients in OpenCV's order, as [`Distortion::from_coefficients`] takes them.
    #[must_use]
    pub fn coefficients(&self) -> Vec<f64> {
        match *self {
            Self::PlumbBob(PlumbBob { k1, k2, p1, p2, k3 }) => vec![k1, k2, p1, p2, k3],
            Self::RationalPolynomial(RationalPolynomial {
                k1,
                k2,
                p1,
                p2,
                k3,
                k4,
                k5,
                k6,
            }) => vec![k1, k2, p1, p2, k3, k4, k5, k6],
            Self::Equidistant(Equidistant { k1, k2, k3, k4 }) => vec![k1, k2, k3, k4],
        }
    }

    /// True when the model maps every point to itself: `plumb_bob` or `rational_polynomial`
    /// with every coefficient zero. The fisheye model is never the identity (with zero
    /// coefficients it still maps tan θ to θ).
    #[must_use]
    pub fn is_none(&self) -> bool {
        match self {
            Self::PlumbBob(d) => *d == PlumbBob::NONE,
            Self::RationalPolynomial(d) => *d == RationalPolynomial::NONE,
            Self::Equidistant(_) => false,
        }
    }

    /// The forward model: an ideal normalised point (X/Z, Y/Z) to its distorted position.
    #[must_use]
    pub fn distort(&self, p: &NormalizedPoint) -> NormalizedPoint {
        let (xd, yd) = match self {
            Self::PlumbBob(d) => d.distort(p.x(), p.y()),
            Self::RationalPolynomial(d) => d.distort(p.x(), p.y()),
            Self::Equidistant(d) => d.distort(p.x(), p.y()),
        };
        NormalizedPoint::new(xd, yd)
    }

    /// The inverse model: the ideal normalised point whose distorted image is `p`.
    ///
    /// Returns `None` when Newton's method does not converge to [`UNDISTORT_TOL`], the
    /// model folds over at the solution (no unique ray), or (fisheye) the ray is 90° or
    /// more from the optical axis, so that it never meets the plane Z = 1.
    #[must_use]
    pub fn undistort(&self, p: &NormalizedPoint) -> Option<NormalizedPoint> {
        if self.is_none() {
            return Some(*p);
        }
        let (x, y) = match self {
            Self::PlumbBob(d) => d.undistort(p.x(), p.y())?,
            Self::RationalPolynomial(d) => d.undistort(p.x(), p.y())?,
            Self::Equidistant(d) => d.undistort(p.x(), p.y())?,
        };
        Some(NormalizedPoint::new(x, y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn models_round_trip_through_their_names_and_coefficients() {
        for model in DistortionModel::ALL {
            assert_eq!(model.name().parse::<DistortionModel>(), Ok(model));
            let coefficients: Vec<f64> = (1..=model.coefficient_count())
                .map(|i| 0.01 * i as f64)
                .collect();
            let d = Distortion::from_coefficients(model, &coefficients).expect("valid");
            assert_eq!(d.model(), model);
            assert_eq!(d.coefficients(), coefficients, "{model}");
        }
        assert!(matches!(
            "fisheye".parse::<DistortionModel>(),
            Err(DistortionError::UnknownModel { .. })
        ));
    }

    #[test]
    fn refuses_a_wrong_count_and_names_a_non_finite_coefficient() {
        let err = Distortion::from_coefficients(DistortionModel::Equidistant, &[0.1; 5])
            .expect_err("five for fisheye");
        assert_eq!(
            err,
            DistortionError::CoefficientCount {
                model: DistortionModel::Equidistant,
                expected: 4,
                got: 5
            }
        );
        let mut rational = [0.0; 8];
        rational[6] = f64::INFINITY;
        let err = Distortion::from_coefficients(DistortionModel::RationalPolynomial, &rational)
            .expect_err("infinite k5");
        assert_eq!(
            err,
            DistortionError::NonFinite {
                param: CameraParam::K5
            }
        );
    }

    #[test]
    fn only_zero_radial_tangential_coefficients_are_the_identity() {
        assert!(Distortion::NONE.is_none());
        assert!(Distortion::from(RationalPolynomial::NONE).is_none());
        let fisheye = Distortion::from(Equidistant {
            k1: 0.0,
            k2: 0.0,
            k3: 0.0,
            k4: 0.0,
        });
        assert!(!fisheye.is_none());
        // tan θ = 1 at θ = 45°: the fisheye puts the point at θ = π/4 along the same ray.
        let seen = fisheye.distort(&NormalizedPoint::new(1.0, 0.0));
        assert!((seen.x() - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
    }

    /// Undistortion is exact to rounding, not just to [`UNDISTORT_TOL`]: a small, distant
    /// marker's tilt amplifies a ray's error about (distance / size)² times, so a 1e-12 ray
    /// error cost a 36 mm code at 1.2 m 2e-6° of rotation (a property test's failure).
    #[test]
    fn every_model_inverts_to_rounding_precision() {
        let lenses = [
            Distortion::from(PlumbBob {
                k1: 0.09711547711121035,
                k2: 0.09228154596297444,
                p1: 0.0,
                p2: 0.0,
                k3: 0.0,
            }),
            Distortion::from(PlumbBob {
                k1: -0.28,
                k2: 0.07,
                p1: 4e-4,
                p2: -3e-4,
                k3: -0.01,
            }),
            Distortion::from(Equidistant {
                k1: -0.0139,
                k2: 0.0047,
                k3: -0.0051,
                k4: 0.0012,
            }),
        ];
        for lens in lenses {
            let mut worst: f64 = 0.0;
            for i in 0..400 {
                let t = f64::from(i) * 0.37;
                let r = 0.6 * (f64::from(i) / 400.0).sqrt();
                let truth = NormalizedPoint::new(r * t.cos(), 0.6 * r * t.sin());
                let back = lens.undistort(&lens.distort(&truth)).expect("invertible");
                worst = worst.max((back.0 - truth.0).norm());
            }
            assert!(worst < 1e-15, "{lens:?}: worst round-trip error {worst:e}");
        }
    }

    /// Up to the fold of a barrel lens (x_d = x·(1 − 0.3·x²) peaks at x = 1/√0.9), every
    /// ray that comes back reproduces its distorted point to the tolerance, however flat the
    /// model is there: the last Newton step, taken past the tolerance, never spoils it (at
    /// 1e-7 from the fold the slope is 2e-7).
    #[test]
    fn rays_near_the_fold_still_reproduce_their_point() {
        let lens = Distortion::from(PlumbBob {
            k1: -0.3,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        });
        let fold = 1.0 / 0.9f64.sqrt();
        let mut returned = 0;
        for gap in [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7] {
            let truth = NormalizedPoint::new(fold - gap, 0.0);
            let seen = lens.distort(&truth);
            if let Some(back) = lens.undistort(&seen) {
                returned += 1;
                let again = lens.distort(&back);
                let residual = (again.0 - seen.0).norm();
                assert!(
                    residual <= UNDISTORT_TOL,
                    "gap {gap}: residual {residual:e}"
                );
            }
        }
        assert!(returned >= 4, "only {returned} rays came back");
    }
}
