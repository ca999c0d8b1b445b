//! What a site adds to a pose (`docs/site.md`), on the wire: the marker size and its
//! source, the code's pose in the robot frame, the robot's pose in the warehouse from a
//! mapped code, the fused `localization` of a photo, and the `prior` that resolves the
//! planar ambiguity (validated into [`crate::app::Prior`]). The math is the application
//! layer's and the qrpose-site crate's.

use super::alternatives::{Form, Narrowed, Rule};
use super::problem::{ErrorCode, Problem};
use super::response::{COVARIANCE_ORDER, CovarianceDto, RotationDto, Vec3Mm};
use crate::app::{Localization, Prior};
use nalgebra::{Quaternion, Rotation3, UnitQuaternion};
use qrpose_site::SizeSource;
use qrpose_site::localize::{CHI2_GATE_6DOF, residual_rotation_deg};
use qrpose_site::prior::RotationPrior;
use qrpose_site::transform::PoseWithCovariance;
use serde::{Deserialize, Serialize};
use serde_json::json;
use utoipa::ToSchema;

/// Where `marker_size_mm` came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub enum MarkerSizeSourceDto {
    /// The request's `marker.size_mm` (`marker_size_mm`).
    #[serde(rename = "request")]
    Request,
    /// The site's rule for this exact payload.
    #[serde(rename = "site:exact")]
    SiteExact,
    /// The site's rule for a prefix of this payload.
    #[serde(rename = "site:prefix")]
    SitePrefix,
    /// The site's rule whose pattern matches this payload.
    #[serde(rename = "site:pattern")]
    SitePattern,
    /// The site's `default_size_mm`.
    #[serde(rename = "site:default")]
    SiteDefault,
}

impl From<SizeSource> for MarkerSizeSourceDto {
    fn from(s: SizeSource) -> Self {
        match s {
            SizeSource::Request => Self::Request,
            SizeSource::SiteExact => Self::SiteExact,
            SizeSource::SitePrefix => Self::SitePrefix,
            SizeSource::SitePattern => Self::SitePattern,
            SizeSource::SiteDefault => Self::SiteDefault,
        }
    }
}

/// A pose in a named frame, with its covariance carried through the transform: the
/// parameters are a small rotation about the *frame's* axes applied on the left (rad) and
/// the position (mm), in `covariance.order` (`docs/site.md`, Frames).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct FramePoseDto {
    /// The origin of the posed thing (the code's centre, or the robot) in the frame, mm.
    pub position_mm: Vec3Mm,
    /// Its orientation: p_frame = R·p_local + position.
    pub rotation: RotationDto,
    /// 6×6 covariance; null when the estimate has none (methods other than
    /// `reprojection`).
    pub covariance: Option<CovarianceDto>,
}

impl From<&PoseWithCovariance> for FramePoseDto {
    fn from(p: &PoseWithCovariance) -> Self {
        Self {
            position_mm: p.pose.translation_mm.into(),
            rotation: RotationDto::from_rotation(&p.pose.rotation),
            covariance: p.covariance.map(|c| CovarianceDto {
                order: COVARIANCE_ORDER.map(str::to_owned),
                matrix: std::array::from_fn(|i| std::array::from_fn(|j| c[(i, j)])),
            }),
        }
    }
}

/// One mapped code's part in the `localization`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LocalizationCodeDto {
    /// Index into `markers`.
    pub marker_index: usize,
    /// The code's payload.
    pub payload: String,
    /// This code's robot position minus the fused one, warehouse frame, mm.
    pub residual_position_mm: Vec3Mm,
    /// Angle between this code's robot rotation and the fused one, degrees.
    pub residual_rotation_deg: f64,
    /// Squared Mahalanobis distance of the residual (6 degrees of freedom).
    pub chi2: f64,
    /// `chi2` > `chi2_gate`: left out of the fused pose (with two codes that disagree, both
    /// are flagged and both kept).
    pub outlier: bool,
}

/// The robot's pose in the warehouse frame, fused over every mapped code of the photo,
/// weighted by their covariances.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LocalizationDto {
    /// T_world←robot: the robot's origin (`position_mm`) and axes in the warehouse frame.
    pub robot_pose_in_world: FramePoseDto,
    /// Every mapped code that took part.
    pub codes: Vec<LocalizationCodeDto>,
    /// The outlier gate: the 99.9 % quantile of χ² with 6 degrees of freedom.
    pub chi2_gate: f64,
}

/// An expected orientation that picks between the two poses of the planar ambiguity: give
/// `marker_quaternion_wxyz` or `robot_quaternion_wxyz`, and `sigma_deg`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PriorDto {
    /// The expected rotation of the code in the camera frame (R of p_cam = R·p_marker + t),
    /// as a quaternion (w, x, y, z); normalised.
    #[schema(min_items = 4, max_items = 4)]
    pub marker_quaternion_wxyz: Option<[f64; 4]>,
    /// The robot's expected rotation in the warehouse frame (from odometry), (w, x, y, z):
    /// with the camera's mount and the map it gives each mapped code's expected rotation
    /// (needs a site, `camera.id` with a mount; unmapped codes are left alone).
    #[schema(min_items = 4, max_items = 4)]
    pub robot_quaternion_wxyz: Option<[f64; 4]>,
    /// Standard deviation of the angle to the expected rotation, degrees, in (0, 180].
    #[schema(example = 15.0, exclusive_minimum = 0, maximum = 180)]
    pub sigma_deg: f64,
}

/// The prior's forms in the document ([`crate::api::alternatives`]): the code's rotation or
/// the robot's, neither all zero (a quaternion without a rotation).
#[must_use]
pub fn prior_forms() -> Rule {
    let form = |name, summary, fields: &'static [&'static str; 2]| Form {
        name,
        summary,
        fields: fields.to_vec(),
        required: fields,
        narrowed: vec![(
            fields[0],
            Narrowed::With(json!({"not": {"items": {"const": 0}}})),
        )],
    };
    Rule::Split {
        component: "PriorDto",
        forms: vec![
            form(
                "MarkerPrior",
                "the code's rotation",
                &["marker_quaternion_wxyz", "sigma_deg"],
            ),
            form(
                "RobotPrior",
                "the robot's rotation",
                &["robot_quaternion_wxyz", "sigma_deg"],
            ),
        ],
        only_within: &[],
    }
}

/// Largest `sigma_deg` of a prior: beyond half a turn a prior says nothing.
pub const MAX_PRIOR_SIGMA_DEG: f64 = 180.0;

fn prior_problem(detail: impl Into<String>, field: &str) -> Problem {
    Problem::new(ErrorCode::InvalidPrior, detail).with_field(format!("/prior/{field}"))
}

fn rotation_of(q: [f64; 4], field: &str) -> Result<Rotation3<f64>, Problem> {
    let [w, x, y, z] = q;
    let q = Quaternion::new(w, x, y, z);
    let norm = q.norm();
    if !norm.is_finite() || norm < qrpose_site::file::MIN_QUATERNION_NORM {
        return Err(prior_problem(
            format!("{field} must be a non-zero, finite quaternion, got norm {norm}"),
            field,
        ));
    }
    Ok(UnitQuaternion::from_quaternion(q).to_rotation_matrix())
}

impl PriorDto {
    /// The validated prior.
    ///
    /// # Errors
    /// 422 `invalid_prior` for neither or both rotations, a zero or non-finite quaternion
    /// or `sigma_deg` outside (0, 180].
    pub fn validate(&self) -> Result<Prior, Problem> {
        if !(self.sigma_deg.is_finite()
            && self.sigma_deg > 0.0
            && self.sigma_deg <= MAX_PRIOR_SIGMA_DEG)
        {
            return Err(prior_problem(
                format!(
                    "sigma_deg must be in (0, {MAX_PRIOR_SIGMA_DEG}], got {}",
                    self.sigma_deg
                ),
                "sigma_deg",
            ));
        }
        let sigma_rad = self.sigma_deg.to_radians();
        match (self.marker_quaternion_wxyz, self.robot_quaternion_wxyz) {
            (Some(q), None) => Ok(Prior::Marker(RotationPrior {
                expected: rotation_of(q, "marker_quaternion_wxyz")?,
                sigma_rad,
            })),
            (None, Some(q)) => Ok(Prior::Robot {
                rotation: rotation_of(q, "robot_quaternion_wxyz")?,
                sigma_rad,
            }),
            (Some(_), Some(_)) => Err(prior_problem(
                "give marker_quaternion_wxyz or robot_quaternion_wxyz, not both",
                "robot_quaternion_wxyz",
            )),
            (None, None) => Err(prior_problem(
                "give marker_quaternion_wxyz or robot_quaternion_wxyz",
                "marker_quaternion_wxyz",
            )),
        }
    }
}

impl From<&Localization> for LocalizationDto {
    fn from(l: &Localization) -> Self {
        Self {
            robot_pose_in_world: FramePoseDto::from(&l.fusion.pose),
            codes: l
                .codes
                .iter()
                .zip(&l.fusion.codes)
                .map(|((index, payload), c)| LocalizationCodeDto {
                    marker_index: *index,
                    payload: payload.clone(),
                    residual_position_mm: Vec3Mm {
                        x: c.residual[3],
                        y: c.residual[4],
                        z: c.residual[5],
                    },
                    residual_rotation_deg: residual_rotation_deg(&c.residual),
                    chi2: c.chi2,
                    outlier: c.outlier,
                })
                .collect(),
            chi2_gate: CHI2_GATE_6DOF,
        }
    }
}
