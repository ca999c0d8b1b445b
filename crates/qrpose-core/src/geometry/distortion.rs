//! Brown-Conrady lens distortion with OpenCV's coefficients and meaning (k1, k2, p1, p2, k3),
//! applied to normalised coordinates (`docs/conventions.md`, Normalised coordinates and
//! distortion). Its inverse has no closed form: [`Distortion::undistort`] solves it by
//! Newton's method to [`UNDISTORT_TOL`] in normalised units, which is far below 1e-6 px for
//! any real focal length.

use super::camera::{CameraError, CameraParam};
use super::frames::NormalizedPoint;

/// Convergence tolerance of the undistortion, normalised units (1e-12 · fx px; 1e-9 px at
/// fx = 1000 px).
pub const UNDISTORT_TOL: f64 = 1e-12;

/// Newton iterations allowed for one undistortion; it converges in 3-6 on real lenses.
pub const UNDISTORT_MAX_ITERATIONS: usize = 50;

/// Brown-Conrady lens distortion, OpenCV's coefficients and meaning.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distortion {
    /// Radial, r² term.
    pub k1: f64,
    /// Radial, r⁴ term.
    pub k2: f64,
    /// Tangential.
    pub p1: f64,
    /// Tangential.
    pub p2: f64,
    /// Radial, r⁶ term.
    pub k3: f64,
}

/// A distorted normalised point and the Jacobian of the distortion there.
struct DistortedWithJacobian {
    xd: f64,
    yd: f64,
    /// ∂(xd, yd)/∂(x, y), row-major.
    j: [[f64; 2]; 2],
}

impl Distortion {
    /// No distortion.
    pub const NONE: Self = Self {
        k1: 0.0,
        k2: 0.0,
        p1: 0.0,
        p2: 0.0,
        k3: 0.0,
    };

    /// Checks that every coefficient is finite.
    ///
    /// # Errors
    /// [`CameraError::NonFinite`] naming the first bad coefficient.
    pub fn try_new(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Result<Self, CameraError> {
        let named = [
            (k1, CameraParam::K1),
            (k2, CameraParam::K2),
            (p1, CameraParam::P1),
            (p2, CameraParam::P2),
            (k3, CameraParam::K3),
        ];
        for (value, param) in named {
            if !value.is_finite() {
                return Err(CameraError::NonFinite { param });
            }
        }
        Ok(Self { k1, k2, p1, p2, k3 })
    }

    /// True when every coefficient is zero.
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// The forward model: an ideal normalised point to its distorted position.
    pub fn distort(&self, p: &NormalizedPoint) -> NormalizedPoint {
        let d = self.distort_with_jacobian(p.x(), p.y());
        NormalizedPoint::new(d.xd, d.yd)
    }

    fn distort_with_jacobian(&self, x: f64, y: f64) -> DistortedWithJacobian {
        let Self { k1, k2, p1, p2, k3 } = *self;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        // ∂radial/∂(r²)
        let dradial = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        let j = [
            [
                radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
                2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
            ],
            [
                2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
                radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ];
        DistortedWithJacobian { xd, yd, j }
    }

    /// The inverse model: the ideal normalised point whose distorted image is `p`.
    ///
    /// Returns `None` when Newton's method does not converge to [`UNDISTORT_TOL`] or the
    /// model folds over at the solution.
    pub fn undistort(&self, p: &NormalizedPoint) -> Option<NormalizedPoint> {
        if self.is_none() {
            return Some(*p);
        }
        let (mut x, mut y) = (p.x(), p.y());
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let d = self.distort_with_jacobian(x, y);
            let (ex, ey) = (d.xd - p.x(), d.yd - p.y());
            let det = d.j[0][0] * d.j[1][1] - d.j[0][1] * d.j[1][0];
            if !det.is_finite() || det <= 0.0 {
                return None;
            }
            if ex.abs().max(ey.abs()) <= UNDISTORT_TOL {
                return Some(NormalizedPoint::new(x, y));
            }
            x -= (d.j[1][1] * ex - d.j[0][1] * ey) / det;
            y -= (-d.j[1][0] * ex + d.j[0][0] * ey) / det;
        }
        None
    }
}
