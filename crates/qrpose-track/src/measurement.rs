//! One code seen in one frame, as the tracker takes it ([`Measurement`]): its payload (or
//! none when the symbol was found but not decoded), the marker, its four corners (the
//! filter's measurement, with the solver's corner noise σ), and the two poses of the planar
//! ambiguity with their covariances and the image's odds between them (to start and
//! re-open hypotheses, and to associate).
//!
//! Pose conventions are qrpose-core's (`docs/conventions.md`): camera frame x right, y
//! down, z forward, mm; `p_cam = R·p_marker + t`; a covariance is 6×6 over (rx, ry, rz rad:
//! a small rotation about the camera axes applied on the left of R; x, y, z mm of the
//! marker centre). [`Measurement::from_estimate`] builds one from a `reprojection`
//! estimate; the alternative pose's covariance, which the estimate does not carry, is
//! σ²·(JᵀJ)⁻¹ at the alternative (the same formula qrpose-core applies to the best pose:
//! `crates/qrpose-core/src/estimate/refine.rs`).

use crate::params::TrackerParams;
use crate::so3::angle_between;
use nalgebra::{Matrix3, Matrix6, Rotation3, SMatrix, Vector2, Vector3};
use qrpose_core::estimate::PoseEstimate;
use qrpose_core::geometry::camera::{Camera, ImageUnit};
use qrpose_core::geometry::marker::Marker;
use qrpose_core::geometry::quad::ImageQuad;
use thiserror::Error;

/// Why a measurement was refused.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum MeasurementError {
    /// The estimate has no covariance: the method was not `reprojection`, or the camera
    /// is in image-plane millimetres (no pixel noise to scale it).
    #[error(
        "the pose estimate carries no covariance (needs the reprojection method and a pixel camera)"
    )]
    NoCovariance,
    /// A pose, covariance or probability is not finite.
    #[error("a pose, covariance or probability of the measurement is not finite")]
    NonFinite,
    /// A covariance is not symmetric positive definite.
    #[error("a pose covariance is not symmetric positive definite")]
    NotPositiveDefinite,
    /// The alternative's probability is outside [0, 1].
    #[error("the alternative's probability {0} is outside [0, 1]")]
    Probability(f64),
    /// The corner noise is not a positive finite number of pixels.
    #[error("corner noise {0} px is not positive and finite")]
    CornerSigma(f64),
    /// A corner could not be undistorted.
    #[error("corner {0} (paper order) cannot be undistorted")]
    Undistortion(usize),
}

/// The four corners as the filter observes them: ideal (undistorted) pixel coordinates
/// (fx·x_n, fy·y_n) in paper order P1..P4, with the pixel scale and the noise variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Corners {
    /// (fx·x_n, fy·y_n) of P1..P4, px (principal point at 0).
    pub ideal_px: [Vector2<f64>; 4],
    /// fx, fy, px per normalised unit.
    pub fx: f64,
    pub fy: f64,
    /// σ², px² per coordinate.
    pub variance_px2: f64,
}

/// One pose of the planar pair: rotation, marker centre, covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseCandidate {
    /// R, marker to camera.
    pub rotation: Rotation3<f64>,
    /// The marker centre in the camera frame, mm.
    pub centre_mm: Vector3<f64>,
    /// 6×6 covariance of (rx, ry, rz rad, left, camera axes; x, y, z mm of the centre).
    pub covariance: Matrix6<f64>,
}

/// The other pose of the planar ambiguity and the image's probability that it is the true
/// one (qrpose-core's calibrated `alternative_probability`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alternative {
    /// The alternative pose.
    pub pose: PoseCandidate,
    /// Probability, from this image alone, that the alternative is the true pose; in [0, 1].
    pub probability: f64,
}

/// One code in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    pub(crate) payload: Option<String>,
    pub(crate) marker: Marker,
    pub(crate) corners: Corners,
    pub(crate) best: PoseCandidate,
    pub(crate) alternative: Option<Alternative>,
    pub(crate) ambiguous: bool,
    /// The best pose's covariance at `corners`' noise (the estimate's own covariance is at
    /// the solver's `corner_sigma_px`, which may differ).
    pub(crate) best_at_corner_sigma: Matrix6<f64>,
}

fn check_candidate(c: &PoseCandidate) -> Result<(), MeasurementError> {
    let finite = c.rotation.matrix().iter().all(|x| x.is_finite())
        && c.centre_mm.iter().all(|x| x.is_finite())
        && c.covariance.iter().all(|x| x.is_finite());
    if !finite {
        return Err(MeasurementError::NonFinite);
    }
    let asymmetry = (c.covariance - c.covariance.transpose()).amax();
    if asymmetry > 1e-9 * c.covariance.amax() || c.covariance.cholesky().is_none() {
        return Err(MeasurementError::NotPositiveDefinite);
    }
    Ok(())
}

impl Measurement {
    /// The share of the frame's own pose covariance that frames share: its best pose's
    /// σ²·(JᵀJ)⁻¹ at the corner noise it is fused with, × `measurement_inflation` ×
    /// `frame_bias_share`.
    pub(crate) fn frame_covariance(&self, params: &TrackerParams) -> Matrix6<f64> {
        self.best_at_corner_sigma * (params.measurement_inflation * params.frame_bias_share)
    }

    /// A measurement of `marker` from its validated corners `quad` seen by `camera`, the
    /// `reprojection` estimate made from them, and the corner noise `corner_sigma_px` the
    /// estimate assumed (the solver's `corner_sigma_px`). The alternative pose is kept when
    /// its probability is above 0 (the two poses are distinct).
    ///
    /// # Errors
    /// [`MeasurementError::NoCovariance`] without a covariance (another method, or a camera
    /// in image-plane mm); [`MeasurementError::Undistortion`] for a corner with no ray;
    /// [`MeasurementError::CornerSigma`], [`MeasurementError::NonFinite`],
    /// [`MeasurementError::NotPositiveDefinite`], [`MeasurementError::Probability`] for
    /// values that cannot be used.
    pub fn from_estimate(
        payload: Option<String>,
        marker: &Marker,
        quad: &ImageQuad,
        estimate: &PoseEstimate,
        camera: &Camera,
        corner_sigma_px: f64,
    ) -> Result<Self, MeasurementError> {
        if !(corner_sigma_px.is_finite() && corner_sigma_px > 0.0) {
            return Err(MeasurementError::CornerSigma(corner_sigma_px));
        }
        let d = &estimate.diagnostics;
        let covariance = d.covariance.ok_or(MeasurementError::NoCovariance)?;
        if camera.unit() != ImageUnit::Pixel {
            return Err(MeasurementError::NoCovariance);
        }
        let mut ideal_px = [Vector2::zeros(); 4];
        for (i, p) in quad.paper_order().iter().enumerate() {
            let n = camera
                .normalize(p)
                .map_err(|_| MeasurementError::Undistortion(i))?;
            ideal_px[i] = Vector2::new(camera.fx() * n.x(), camera.fy() * n.y());
        }
        let corners = Corners {
            ideal_px,
            fx: camera.fx(),
            fy: camera.fy(),
            variance_px2: corner_sigma_px * corner_sigma_px,
        };
        let best = PoseCandidate {
            rotation: estimate.pose.rotation(),
            centre_mm: estimate.centre_mm,
            covariance,
        };
        let alternative = match d.ambiguity {
            Some(a) if a.alternative_probability.is_some_and(|p| p > 0.0) => {
                let rotation = a.alternative.rotation();
                let centre_mm = a.alternative.transform(&marker.centre()).0.coords;
                let covariance =
                    pose_covariance(marker, &rotation, &centre_mm, camera, corner_sigma_px)
                        .ok_or(MeasurementError::NotPositiveDefinite)?;
                Some(Alternative {
                    pose: PoseCandidate {
                        rotation,
                        centre_mm,
                        covariance,
                    },
                    probability: a.alternative_probability.unwrap_or(0.0),
                })
            }
            _ => None,
        };
        check_candidate(&best)?;
        let best_at_corner_sigma = pose_covariance(
            marker,
            &best.rotation,
            &best.centre_mm,
            camera,
            corner_sigma_px,
        )
        .ok_or(MeasurementError::NotPositiveDefinite)?;
        if let Some(a) = &alternative {
            check_candidate(&a.pose)?;
            if !a.probability.is_finite() {
                return Err(MeasurementError::NonFinite);
            }
            if !(0.0..=1.0).contains(&a.probability) {
                return Err(MeasurementError::Probability(a.probability));
            }
        }
        if !ideal_px.iter().all(|c| c.iter().all(|x| x.is_finite())) {
            return Err(MeasurementError::NonFinite);
        }
        Ok(Self {
            payload,
            marker: *marker,
            corners,
            best,
            alternative,
            ambiguous: d.ambiguity.is_some_and(|a| a.ambiguous),
            best_at_corner_sigma,
        })
    }

    /// The decoded payload, if any.
    pub fn payload(&self) -> Option<&str> {
        self.payload.as_deref()
    }

    /// The pose the frame alone reports (the better fit).
    pub fn best(&self) -> &PoseCandidate {
        &self.best
    }

    /// The other pose of the planar ambiguity, when the two are distinct.
    pub fn alternative(&self) -> Option<&Alternative> {
        self.alternative.as_ref()
    }

    /// The index in [`Self::candidates`] of the candidate nearer `rotation` (angle between
    /// rotations): 1 when the alternative is strictly nearer, else 0.
    pub(crate) fn nearer_candidate(&self, rotation: &Rotation3<f64>) -> usize {
        usize::from(self.alternative.is_some_and(|a| {
            angle_between(rotation, &a.pose.rotation) < angle_between(rotation, &self.best.rotation)
        }))
    }

    /// The candidates with their image evidence e_k = −2·ln P(k | image): index 0 the best,
    /// 1 the alternative. Probabilities are clamped to [10⁻³⁰⁰, 1] so e stays finite.
    pub(crate) fn candidates(&self) -> Vec<(PoseCandidate, f64)> {
        let p_alt = self.alternative.map_or(0.0, |a| a.probability);
        let evidence = |p: f64| -2.0 * p.clamp(1e-300, 1.0).ln();
        let mut out = vec![(self.best, evidence(1.0 - p_alt))];
        if let Some(a) = self.alternative {
            out.push((a.pose, evidence(p_alt)));
        }
        out
    }
}

/// The 2×3 Jacobian of the ideal pixel projection (fx·X/Z, fy·Y/Z) at camera point p.
pub(crate) fn projection_jacobian(camera: &Camera, p: &Vector3<f64>) -> SMatrix<f64, 2, 3> {
    let inv_z = 1.0 / p.z;
    SMatrix::<f64, 2, 3>::new(
        camera.fx() * inv_z,
        0.0,
        -camera.fx() * p.x * inv_z * inv_z,
        0.0,
        camera.fy() * inv_z,
        -camera.fy() * p.y * inv_z * inv_z,
    )
}

/// The 2×6 Jacobian of corner `m` (marker frame, mm) in the ideal image with respect to
/// (δθ left, δc): p = Exp(δθ)·R·(m − m_c) + c + δc, so ∂p/∂δθ = −[R(m − m_c)]×,
/// ∂p/∂δc = I (refine.rs's parametrisation). `None` at or behind the camera.
pub(crate) fn corner_jacobian(
    marker: &Marker,
    m: &Vector3<f64>,
    rotation: &Rotation3<f64>,
    centre_mm: &Vector3<f64>,
    camera: &Camera,
) -> Option<SMatrix<f64, 2, 6>> {
    let q = rotation * (m - marker.centre().0.coords);
    let p = q + centre_mm;
    if p.z <= 0.0 || !p.z.is_finite() {
        return None;
    }
    let mut dp = SMatrix::<f64, 3, 6>::zeros();
    dp.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-q.cross_matrix()));
    dp.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&Matrix3::identity());
    Some(projection_jacobian(camera, &p) * dp)
}

/// σ²·(JᵀJ)⁻¹ of the pose (rotation, centre) of `marker` from its four corners with
/// independent noise of `sigma_px` per coordinate; `None` when a corner is behind the
/// camera or JᵀJ is singular.
pub(crate) fn pose_covariance(
    marker: &Marker,
    rotation: &Rotation3<f64>,
    centre_mm: &Vector3<f64>,
    camera: &Camera,
    sigma_px: f64,
) -> Option<Matrix6<f64>> {
    let mut jtj = Matrix6::zeros();
    for m in marker.object_points() {
        let j = corner_jacobian(marker, &m.0.coords, rotation, centre_mm, camera)?;
        jtj += j.transpose() * j;
    }
    let inv = jtj.try_inverse()? * (sigma_px * sigma_px);
    Some((inv + inv.transpose()) * 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;
    use qrpose_core::estimate::{ReprojectionParams, Solver, estimate_pose};
    use qrpose_core::geometry::frames::PixelPoint;
    use qrpose_core::geometry::{euler::EulerXyz, marker::CornerOrder, quad::ImageQuad};

    #[test]
    fn the_covariance_formula_reproduces_the_one_qrpose_core_reports() {
        let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("camera");
        let marker = Marker::try_new(50.0).expect("marker");
        let truth = marker.pose_centred_at(
            EulerXyz::from_degrees(35.0, -10.0, 20.0).to_rotation(),
            Vector3::new(40.0, -30.0, 900.0),
        );
        let noise = [(0.3, -0.2), (-0.4, 0.1), (0.2, 0.5), (-0.1, -0.3)];
        let corners: [PixelPoint; 4] = std::array::from_fn(|i| {
            let p = camera
                .project(&truth.transform(&marker.object_points()[i]))
                .expect("in front");
            PixelPoint::new(p.u() + noise[i].0, p.v() + noise[i].1)
        });
        let quad = ImageQuad::try_new(corners, CornerOrder::Paper).expect("quad");
        let solver = Solver::Reprojection(ReprojectionParams {
            corner_sigma_px: 0.7,
            ..ReprojectionParams::default()
        })
        .validate()
        .expect("solver");
        let e = estimate_pose(&quad, &camera, &marker, &solver).expect("pose");
        let ours = pose_covariance(&marker, &e.pose.rotation(), &e.centre_mm, &camera, 0.7)
            .expect("covariance");
        let theirs = e.diagnostics.covariance.expect("covariance");
        assert!(
            (ours - theirs).norm() < 1e-6 * theirs.norm(),
            "{ours} vs {theirs}"
        );
        let m = Measurement::from_estimate(Some("A".into()), &marker, &quad, &e, &camera, 0.7)
            .expect("measurement");
        assert_eq!(m.payload(), Some("A"));
        assert!(
            m.alternative().is_some(),
            "900 mm, 35° tilt: two distinct poses"
        );
    }
}
