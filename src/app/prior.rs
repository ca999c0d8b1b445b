//! The prior: an expected orientation that decides between the two poses of the planar
//! ambiguity (`docs/site.md`, Priors). The decision is the site crate's
//! ([`qrpose_site::prior::apply_prior`]); this module turns a request's prior into the
//! rotation expected of one code and applies it.

use super::frames::SiteFrames;
use nalgebra::Rotation3;
use qrpose_core::estimate::PoseEstimate;
use qrpose_core::geometry::{
    camera::Camera,
    frames::{MarkerPoint, PixelPoint},
    marker::Marker,
};
use qrpose_site::prior::{Observation, RotationPrior, apply_prior, expected_marker_rotation};

/// A validated prior.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Prior {
    /// The code's rotation in the camera frame.
    Marker(RotationPrior),
    /// The robot's rotation in the world (odometry), with σ: each mapped code's expected
    /// rotation follows from the camera's mount and the map.
    Robot {
        /// R_world←robot.
        rotation: Rotation3<f64>,
        /// σ of the angle, rad.
        sigma_rad: f64,
    },
}

impl Prior {
    /// The rotation expected of the code with `payload`, if this prior says anything about
    /// it: a robot prior needs a site camera with a mount and a mapped payload.
    #[must_use]
    pub fn for_code(
        &self,
        frames: &SiteFrames<'_>,
        payload: Option<&str>,
    ) -> Option<RotationPrior> {
        match *self {
            Self::Marker(p) => Some(p),
            Self::Robot {
                rotation,
                sigma_rad,
            } => {
                let mount = frames.camera?.mount?;
                let mapped = frames.site?.mapped(payload?)?;
                Some(RotationPrior {
                    expected: expected_marker_rotation(
                        &rotation,
                        &mount.rotation,
                        &mapped.rotation,
                    ),
                    sigma_rad,
                })
            }
        }
    }
}

/// What a pose was solved from, for re-weighing its two candidates.
#[derive(Debug, Clone, Copy)]
pub(super) struct Observed<'a> {
    /// The model points, marker frame, mm.
    pub model: &'a [MarkerPoint],
    /// The measured points, px.
    pub image: &'a [PixelPoint],
    /// The camera.
    pub camera: &'a Camera,
    /// The code's size.
    pub marker: &'a Marker,
    /// Corner noise σ of the covariance, px.
    pub corner_sigma_px: f64,
}

/// `estimate` after `prior`, and whether the prior decided (took the alternative or
/// confirmed the best fit against a close call). Unchanged without a prior for this code
/// or without an ambiguity block (methods other than `reprojection`).
pub(super) fn with_prior(
    estimate: PoseEstimate,
    prior: Option<RotationPrior>,
    observed: &Observed<'_>,
) -> (PoseEstimate, bool) {
    let Some(prior) = prior else {
        return (estimate, false);
    };
    let obs = Observation {
        model: observed.model,
        image: observed.image,
        camera: observed.camera,
        marker: observed.marker,
        corner_sigma_px: observed.corner_sigma_px,
    };
    match apply_prior(&estimate, &obs, &prior) {
        Some((with_prior, _)) => (with_prior, true),
        None => (estimate, false),
    }
}
