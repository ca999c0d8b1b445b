//! The error-state Kalman filter of one motion model of one hypothesis: state,
//! constant-velocity prediction, the iterated update with a frame's four corners.
//!
//! **Nominal state** x = (R, c, v, ω): R the marker-to-camera rotation, c the marker centre
//! in the camera frame (mm), v its velocity (mm/s), ω the angular velocity (rad/s, camera
//! axes, so Ṙ = [ω]×·R). **Error state** δx = (δθ, δc, δv, δω) ∈ ℝ¹², with
//! R_true = Exp(δθ)·R (a left, "global" rotation error: Solà 2017 §7) and the others
//! additive; P is its 12×12 covariance. The first six components are exactly the per-frame
//! covariance's (rx, ry, rz, x, y, z): P's pose block is reported in that convention.
//!
//! **Prediction** over dt seconds (constant velocity, white accelerations):
//!
//! ```text
//! R⁺ = Exp(ω·dt)·R      c⁺ = c + v·dt      v⁺ = v      ω⁺ = ω
//! P⁺ = F·P·Fᵀ + Q
//!      ⎡Exp(ω dt)  0   0     J_l(ω dt)·dt⎤
//! F =  ⎢0          I   I·dt  0           ⎥   (δθ⁺ = Exp(ω dt)·δθ + J_l(ω dt)·dt·δω, from
//!      ⎢0          0   I     0           ⎥    Exp((ω+δω)dt) ≈ Exp(J_l δω dt)·Exp(ω dt) and
//!      ⎣0          0   0     I           ⎦    Exp(a)·Exp(δ)·Exp(−a) = Exp(Exp(a)·δ))
//! Q: per axis, for (c, v) with q = q_a and for (δθ, ω) with q = q_α,
//!      q·⎡dt³/3  dt²/2⎤   (the continuous white-noise acceleration model, Bar-Shalom, Li
//!        ⎣dt²/2  dt   ⎦    and Kirubarajan, "Estimation with Applications to Tracking and
//!                          Navigation", Wiley 2001, §6.2.2; for δθ the rotation of the
//!                          noise by Exp(ω dt) within one step is neglected)
//! ```
//!
//! **Update** with the four corners z (8 ideal pixel coordinates, noise R = σ²·I, the
//! per-frame pose covariance's own noise model) by the iterated EKF, Gauss-Newton on
//! J(δ) = δᵀP⁻¹δ + |z − π(x̂ ⊞ δ)|²/σ² (Bell and Cathey, "The iterated Kalman filter update
//! as a Gauss-Newton method", IEEE TAC 38(2), 1993; Solà 2017 §6.1-6.3 for the error
//! state):
//!
//! ```text
//! x_i = x̂ ⊞ δ_i: R_i = Exp(δθ_i)·R̂, c_i = ĉ + δc_i, …       (δ_0 = 0, or a start pose)
//! r_i = z − π(x_i)   π: corner m_j ↦ (fx·X/Z, fy·Y/Z), p = R_i·(m_j − m_c) + c_i
//! H_i = [∂π/∂ε·J_l(δθ_i), ∂π/∂c, 0, 0]  (∂p/∂ε = −[R_i(m_j − m_c)]× for a left rotation ε
//!                                         at x_i; Exp(δθ_i + η) ≈ Exp(J_l η)·Exp(δθ_i))
//! S_i = H_i P H_iᵀ + R,  K_i = P H_iᵀ S_i⁻¹,  δ_{i+1} = K_i·(r_i + H_i·δ_i)
//! (the step is halved while J does not decrease; at most 10 iterations)
//! P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ   (Joseph form, at the last linearisation)
//! x⁺ = x̂ ⊞ δ;  P⁺ ← G P⁺ Gᵀ, G = diag(J_l(δθ), I, I, I)   (reset: the error about x⁺,
//!                                       ε = J_l(δθ)·(δθ_true − δθ); Solà §7 to first order)
//! ```
//!
//! J at the optimum is the squared Mahalanobis distance of the measurement (χ² with 8
//! degrees of freedom for a consistent filter) and −½(J + ln det S) the log of the
//! measurement's predictive likelihood (Laplace approximation), which weighs hypotheses.

use crate::measurement::{Corners, PoseCandidate};
use crate::so3::{left_jacobian, log};
use nalgebra::{Matrix3, Matrix6, Rotation3, SMatrix, Vector3, Vector6};
use qrpose_core::geometry::marker::Marker;

/// The 12×12 covariance of the error state (δθ, δc, δv, δω).
pub(crate) type Cov12 = SMatrix<f64, 12, 12>;

/// Spectral densities of the white accelerations driving the constant-velocity model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ProcessNoise {
    /// q_a, mm²/s³.
    pub accel_psd: f64,
    /// q_α, rad²/s³.
    pub angular_accel_psd: f64,
}

/// The result of an iterated update.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Posterior {
    /// The updated filter.
    pub filter: Eskf,
    /// J at the optimum: χ²(8) for a consistent filter.
    pub cost: f64,
    /// ln det S at the last linearisation.
    pub ln_det_s: f64,
}

/// Gauss-Newton iterations of the update at most.
const MAX_ITERATIONS: usize = 10;
/// Iteration ends when the rotation step is below this (rad) and the centre step below
/// this × 1000 mm.
const STEP_TOL_RAD: f64 = 1e-9;

type Obs = SMatrix<f64, 8, 1>;
type Jac = SMatrix<f64, 8, 12>;

/// One filter: the nominal state and the error covariance.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Eskf {
    /// R, marker to camera.
    pub rotation: Rotation3<f64>,
    /// Marker centre, camera frame, mm.
    pub centre_mm: Vector3<f64>,
    /// Velocity of the centre, mm/s.
    pub velocity_mm_s: Vector3<f64>,
    /// Angular velocity, rad/s, camera axes.
    pub angular_velocity_rad_s: Vector3<f64>,
    /// Covariance of (δθ, δc, δv, δω).
    pub covariance: Cov12,
}

impl Eskf {
    /// A filter at a measured pose with the given velocity and velocity uncertainty.
    pub fn from_pose(
        pose: &PoseCandidate,
        inflation: f64,
        velocity_mm_s: Vector3<f64>,
        velocity_sigma_mm_s: f64,
        angular_sigma_rad_s: f64,
    ) -> Self {
        let mut covariance = Cov12::zeros();
        covariance
            .fixed_view_mut::<6, 6>(0, 0)
            .copy_from(&(pose.covariance * inflation));
        for i in 0..3 {
            covariance[(6 + i, 6 + i)] = velocity_sigma_mm_s * velocity_sigma_mm_s;
            covariance[(9 + i, 9 + i)] = angular_sigma_rad_s * angular_sigma_rad_s;
        }
        Self {
            rotation: pose.rotation,
            centre_mm: pose.centre_mm,
            velocity_mm_s,
            angular_velocity_rad_s: Vector3::zeros(),
            covariance,
        }
    }

    /// The pose block of P: (δθ, δc), 6×6.
    pub fn pose_covariance(&self) -> Matrix6<f64> {
        self.covariance.fixed_view::<6, 6>(0, 0).into_owned()
    }

    /// The state predicted `dt_s` seconds ahead (dt ≤ 0 or not finite: unchanged).
    pub fn predicted(&self, dt_s: f64, noise: &ProcessNoise) -> Self {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return self.clone();
        }
        let phi = self.angular_velocity_rad_s * dt_s;
        let turn = Rotation3::new(phi);
        let mut rotation = turn * self.rotation;
        rotation.renormalize();
        let mut f = Cov12::identity();
        f.fixed_view_mut::<3, 3>(0, 0).copy_from(turn.matrix());
        f.fixed_view_mut::<3, 3>(0, 9)
            .copy_from(&(left_jacobian(&phi) * dt_s));
        f.fixed_view_mut::<3, 3>(3, 6)
            .copy_from(&(Matrix3::identity() * dt_s));
        let mut covariance = f * self.covariance * f.transpose() + process_noise(dt_s, noise);
        symmetrise(&mut covariance);
        Self {
            rotation,
            centre_mm: self.centre_mm + self.velocity_mm_s * dt_s,
            velocity_mm_s: self.velocity_mm_s,
            angular_velocity_rad_s: self.angular_velocity_rad_s,
            covariance,
        }
    }

    /// Holds the code still: velocity and angular velocity set to zero, with no variance and
    /// no correlation with the pose (the at-rest model of crate::imm; its prediction adds
    /// the velocities' process noise back, so the covariance stays positive definite).
    pub fn hold_still(&mut self) {
        self.velocity_mm_s = Vector3::zeros();
        self.angular_velocity_rad_s = Vector3::zeros();
        for i in 6..12 {
            for j in 0..12 {
                self.covariance[(i, j)] = 0.0;
                self.covariance[(j, i)] = 0.0;
            }
        }
    }

    /// The state at error δ from this one: R = Exp(δθ)·R̂, c = ĉ + δc, v = v̂ + δv,
    /// ω = ω̂ + δω (covariance unchanged).
    pub fn plus(&self, d: &SMatrix<f64, 12, 1>) -> Self {
        let mut rotation = Rotation3::new(Vector3::new(d[0], d[1], d[2])) * self.rotation;
        rotation.renormalize();
        Self {
            rotation,
            centre_mm: self.centre_mm + Vector3::new(d[3], d[4], d[5]),
            velocity_mm_s: self.velocity_mm_s + Vector3::new(d[6], d[7], d[8]),
            angular_velocity_rad_s: self.angular_velocity_rad_s + Vector3::new(d[9], d[10], d[11]),
            covariance: self.covariance,
        }
    }

    /// Residuals z − π(x) and the Jacobian of π with respect to (left ε at x, δc), 8×6;
    /// `None` when a corner is at or behind the camera.
    fn residuals(&self, corners: &Corners, marker: &Marker) -> Option<(Obs, SMatrix<f64, 8, 6>)> {
        let mut r = Obs::zeros();
        let mut h = SMatrix::<f64, 8, 6>::zeros();
        let centre = marker.centre().0.coords;
        for (j, m) in marker.object_points().iter().enumerate() {
            let q = self.rotation * (m.0.coords - centre);
            let p = q + self.centre_mm;
            if !(p.z > 0.0 && p.z.is_finite()) {
                return None;
            }
            let inv_z = 1.0 / p.z;
            r[2 * j] = corners.ideal_px[j].x - corners.fx * p.x * inv_z;
            r[2 * j + 1] = corners.ideal_px[j].y - corners.fy * p.y * inv_z;
            let dproj = SMatrix::<f64, 2, 3>::new(
                corners.fx * inv_z,
                0.0,
                -corners.fx * p.x * inv_z * inv_z,
                0.0,
                corners.fy * inv_z,
                -corners.fy * p.y * inv_z * inv_z,
            );
            h.fixed_view_mut::<2, 3>(2 * j, 0)
                .copy_from(&(dproj * -q.cross_matrix()));
            h.fixed_view_mut::<2, 3>(2 * j, 3).copy_from(&dproj);
        }
        Some((r, h))
    }

    /// J(δ) = δᵀP⁻¹δ + |r|²/σ² for the error δ whose state has residuals `r`.
    fn cost(
        p_chol: &nalgebra::Cholesky<f64, nalgebra::Const<12>>,
        d: &SMatrix<f64, 12, 1>,
        r: &Obs,
        variance: f64,
    ) -> f64 {
        d.dot(&p_chol.solve(d)) + r.norm_squared() / variance
    }

    /// The iterated update with the four corners (module docs), started at this state or,
    /// with `start`, at that pose (rotation, centre); `inflation` multiplies σ². `None` when
    /// a corner falls behind the camera or a matrix is singular.
    pub fn iterated_update(
        &self,
        corners: &Corners,
        marker: &Marker,
        inflation: f64,
        start: Option<(&Rotation3<f64>, &Vector3<f64>)>,
    ) -> Option<Posterior> {
        let variance = corners.variance_px2 * inflation;
        let p_chol = self.covariance.cholesky()?;
        let mut d = SMatrix::<f64, 12, 1>::zeros();
        if let Some((r, c)) = start {
            d.fixed_rows_mut::<3>(0)
                .copy_from(&log(&(r * self.rotation.inverse())));
            d.fixed_rows_mut::<3>(3).copy_from(&(c - self.centre_mm));
        }
        let (mut r, mut h6) = self.plus(&d).residuals(corners, marker)?;
        let mut cost = Self::cost(&p_chol, &d, &r, variance);
        let mut gain = SMatrix::<f64, 12, 8>::zeros();
        let mut h = Jac::zeros();
        let mut ln_det_s = 0.0;
        for _ in 0..MAX_ITERATIONS {
            h = Jac::zeros();
            let jl = left_jacobian(&Vector3::new(d[0], d[1], d[2]));
            h.fixed_view_mut::<8, 3>(0, 0)
                .copy_from(&(h6.fixed_view::<8, 3>(0, 0) * jl));
            h.fixed_view_mut::<8, 3>(0, 3)
                .copy_from(&h6.fixed_view::<8, 3>(0, 3));
            let s =
                h * self.covariance * h.transpose() + SMatrix::<f64, 8, 8>::identity() * variance;
            let s_chol = s.cholesky()?;
            ln_det_s = 2.0 * s_chol.l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
            gain = self.covariance * h.transpose() * s_chol.inverse();
            let target = gain * (r + h * d);
            let mut step = target - d;
            let mut accepted = false;
            for _ in 0..6 {
                let trial = d + step;
                if let Some((r_t, h_t)) = self.plus(&trial).residuals(corners, marker) {
                    let c_t = Self::cost(&p_chol, &trial, &r_t, variance);
                    if c_t <= cost {
                        (d, r, h6, cost, accepted) = (trial, r_t, h_t, c_t, true);
                        break;
                    }
                }
                step *= 0.5;
            }
            let small = step.fixed_rows::<3>(0).amax() < STEP_TOL_RAD
                && step.fixed_rows::<3>(3).amax() < STEP_TOL_RAD * 1000.0;
            if !accepted || small {
                break;
            }
        }
        let mut i_kh = SMatrix::<f64, 12, 12>::identity();
        i_kh -= gain * h;
        let r_cov = SMatrix::<f64, 8, 8>::identity() * variance;
        let mut p = i_kh * self.covariance * i_kh.transpose() + gain * r_cov * gain.transpose();
        let mut g = Cov12::identity();
        g.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&left_jacobian(&Vector3::new(d[0], d[1], d[2])));
        p = g * p * g.transpose();
        symmetrise(&mut p);
        let mut filter = self.plus(&d);
        filter.covariance = p;
        (cost.is_finite() && ln_det_s.is_finite() && filter.is_finite()).then_some(Posterior {
            filter,
            cost,
            ln_det_s,
        })
    }

    /// ln det S, S = H P Hᵀ + σ²·inflation·I, of the corners at this state (0 when a corner
    /// is behind the camera).
    pub fn predicted_ln_det_s(&self, corners: &Corners, marker: &Marker, inflation: f64) -> f64 {
        let Some((_, h6)) = self.residuals(corners, marker) else {
            return 0.0;
        };
        let p6 = self.pose_covariance();
        let s = h6 * p6 * h6.transpose()
            + SMatrix::<f64, 8, 8>::identity() * (corners.variance_px2 * inflation);
        s.cholesky().map_or(0.0, |c| {
            2.0 * c.l().diagonal().iter().map(|x| x.ln()).sum::<f64>()
        })
    }

    /// The error-state difference self ⊟ other: (Log(R_self·R_otherᵀ), c, v, ω differences).
    pub fn minus(&self, other: &Eskf) -> SMatrix<f64, 12, 1> {
        let mut d = SMatrix::<f64, 12, 1>::zeros();
        d.fixed_rows_mut::<6>(0)
            .copy_from(&self.pose_difference(other));
        d.fixed_rows_mut::<3>(6)
            .copy_from(&(self.velocity_mm_s - other.velocity_mm_s));
        d.fixed_rows_mut::<3>(9)
            .copy_from(&(self.angular_velocity_rad_s - other.angular_velocity_rad_s));
        d
    }

    /// The pose difference (Log(R_self·R_otherᵀ), c_self − c_other).
    pub fn pose_difference(&self, other: &Eskf) -> Vector6<f64> {
        let mut d = Vector6::zeros();
        d.fixed_rows_mut::<3>(0)
            .copy_from(&log(&(self.rotation * other.rotation.inverse())));
        d.fixed_rows_mut::<3>(3)
            .copy_from(&(self.centre_mm - other.centre_mm));
        d
    }

    /// Whether every number of the state is finite.
    pub fn is_finite(&self) -> bool {
        self.rotation.matrix().iter().all(|x| x.is_finite())
            && self.centre_mm.iter().all(|x| x.is_finite())
            && self.velocity_mm_s.iter().all(|x| x.is_finite())
            && self.angular_velocity_rad_s.iter().all(|x| x.is_finite())
            && self.covariance.iter().all(|x| x.is_finite())
    }
}

/// Q of the constant-velocity model over dt (module docs).
fn process_noise(dt: f64, noise: &ProcessNoise) -> Cov12 {
    let mut q = Cov12::zeros();
    let (d3, d2) = (dt * dt * dt / 3.0, dt * dt / 2.0);
    for axis in 0..3 {
        for (pos, vel, psd) in [
            (3 + axis, 6 + axis, noise.accel_psd),
            (axis, 9 + axis, noise.angular_accel_psd),
        ] {
            q[(pos, pos)] = psd * d3;
            q[(pos, vel)] = psd * d2;
            q[(vel, pos)] = psd * d2;
            q[(vel, vel)] = psd * dt;
        }
    }
    q
}

fn symmetrise(p: &mut Cov12) {
    *p = (*p + p.transpose()) * 0.5;
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn candidate(rotation: Rotation3<f64>, centre: Vector3<f64>, sigma: f64) -> PoseCandidate {
        let mut covariance = Matrix6::identity() * (sigma * sigma);
        for i in 0..3 {
            covariance[(i, i)] = 1e-4;
        }
        PoseCandidate {
            rotation,
            centre_mm: centre,
            covariance,
        }
    }

    const NOISE: ProcessNoise = ProcessNoise {
        accel_psd: 1e4,
        angular_accel_psd: 1.0,
    };

    #[test]
    fn prediction_moves_the_pose_at_constant_velocity() {
        let z = candidate(Rotation3::identity(), Vector3::new(0.0, 0.0, 500.0), 1.0);
        let mut f = Eskf::from_pose(&z, 1.0, Vector3::new(100.0, 0.0, -50.0), 10.0, 0.1);
        f.angular_velocity_rad_s = Vector3::new(0.0, 0.5, 0.0);
        let p = f.predicted(0.2, &NOISE);
        assert_relative_eq!(p.centre_mm, Vector3::new(20.0, 0.0, 490.0), epsilon = 1e-12);
        assert_relative_eq!(
            log(&p.rotation),
            Vector3::new(0.0, 0.1, 0.0),
            epsilon = 1e-12
        );
        assert!(p.covariance[(3, 3)] > f.covariance[(3, 3)]);
        assert_eq!(f.predicted(-1.0, &NOISE), f, "dt ≤ 0 leaves the state");
    }

    fn corners_of(rotation: &Rotation3<f64>, centre: &Vector3<f64>, marker: &Marker) -> Corners {
        let c = marker.centre().0.coords;
        let ideal_px = marker.object_points().map(|m| {
            let p = rotation * (m.0.coords - c) + centre;
            nalgebra::Vector2::new(1000.0 * p.x / p.z, 1000.0 * p.y / p.z)
        });
        Corners {
            ideal_px,
            fx: 1000.0,
            fy: 1000.0,
            variance_px2: 0.25,
        }
    }

    #[test]
    fn the_iterated_update_converges_to_the_corners_from_a_distant_start() {
        let marker = Marker::try_new(50.0).expect("marker");
        let truth_r = Rotation3::new(Vector3::new(0.4, -0.2, 0.1));
        let truth_c = Vector3::new(20.0, -10.0, 600.0);
        // A weak prior 4° and 8 mm off: the update must land on the corners' own pose.
        let prior = candidate(
            Rotation3::new(Vector3::new(0.45, -0.25, 0.1)),
            truth_c + Vector3::new(2.0, 0.0, 8.0),
            200.0,
        );
        let mut f = Eskf::from_pose(&prior, 1.0, Vector3::zeros(), 10.0, 0.1);
        for i in 0..3 {
            f.covariance[(i, i)] = 1.0;
        }
        let z = corners_of(&truth_r, &truth_c, &marker);
        let post = f
            .iterated_update(&z, &marker, 1.0, None)
            .expect("converges");
        let angle = crate::so3::angle_between(&post.filter.rotation, &truth_r);
        assert!(
            angle < 2e-3,
            "{angle} rad, {} mm",
            (post.filter.centre_mm - truth_c).norm()
        );
        assert!((post.filter.centre_mm - truth_c).norm() < 0.5);
        assert!(post.filter.covariance[(5, 5)] < f.covariance[(5, 5)]);
    }
}
