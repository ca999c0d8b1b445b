//! What a hand-eye calibration answers: [`HandEyeCalibration`], its per-view reports, its
//! [`HandEyeWarning`]s, its [`HandEyeError`]s (each with a stable snake_case code), and the
//! `site_mount` YAML ([`site_mount_yaml`]) for the site file (`docs/hand-eye.md`).

use super::input::HandEyeSetup;
use crate::error::SolveFailure;
use nalgebra::{Isometry3, Matrix6, UnitQuaternion};
use thiserror::Error;

/// Why no hand-eye calibration was returned.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum HandEyeError {
    /// The camera is in image-plane millimetres (no pixels): the points are measured in px.
    #[error("the camera must be given in pixels")]
    InvalidCamera,
    /// An option is not finite or not positive.
    #[error("option {name} = {value} must be finite and positive")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// A flange pose or a point coordinate is NaN or infinite.
    #[error("view {view}: a flange pose or point coordinate is not a finite number")]
    NonFinite {
        /// The view, 0-based, in the order given.
        view: usize,
    },
    /// Fewer than [`super::MIN_HAND_EYE_VIEWS`] views have the code read (at least
    /// [`super::MIN_HAND_EYE_POINTS`] points whose pose could be found).
    #[error("{read} views with the code read; at least {required} are needed")]
    TooFewViews {
        /// Views with the code read.
        read: usize,
        /// Views needed.
        required: usize,
    },
    /// The flange's motions between the views turn about fewer than two distinct axes
    /// (every rotation larger than [`super::MIN_AXIS_ROTATION_RAD`] is about axes within
    /// [`super::MIN_AXIS_SPREAD_RAD`] of one line, or there is none): the mount's
    /// translation along that axis, and part of its rotation, cannot be told.
    #[error(
        "the flange turns about one axis only (spread {axis_spread_rad} rad): turn it about at least two different axes"
    )]
    DegenerateMotion {
        /// Largest angle between a motion's axis and the motions' main axis, rad (0 when
        /// no motion turns far enough to have an axis).
        axis_spread_rad: f64,
    },
    /// The joint fit could not be solved.
    #[error("the joint fit failed: {0}")]
    SolveFailed(SolveFailure),
}

impl HandEyeError {
    /// The stable snake_case code.
    #[must_use]
    pub const fn code(&self) -> &'static str {
        match self {
            Self::InvalidCamera => "invalid_camera",
            Self::InvalidOption { .. } => "invalid_option",
            Self::NonFinite { .. } => "non_finite",
            Self::TooFewViews { .. } => "too_few_views",
            Self::DegenerateMotion { .. } => "degenerate_motion",
            Self::SolveFailed(_) => "solve_failed",
        }
    }
}

/// A calibration that was computed but that the views constrain poorly, or a view left
/// out. Thresholds are named constants in [`super`].
#[derive(Debug, Clone, PartialEq)]
pub enum HandEyeWarning {
    /// Fewer than [`super::RECOMMENDED_HAND_EYE_VIEWS`] views were used.
    FewViews {
        /// Views used.
        used: usize,
        /// Views recommended.
        recommended: usize,
    },
    /// The largest rotation between two used views is below
    /// [`super::MIN_ROTATION_SPREAD_RAD`]: the mount's rotation rests on small angles and
    /// its translation is poorly constrained.
    SmallRotations {
        /// Largest rotation between two used views, rad.
        largest_rotation_rad: f64,
        /// The views concerned (every used view).
        views: Vec<usize>,
    },
    /// A view's flange pose or points disagree with the others (its flange residual above
    /// [`super::OUTLIER_FLANGE_SIGMAS`] standard deviations of the flange noise, or its
    /// reprojection RMS above [`super::OUTLIER_RMS_RATIO`] times the median view's and
    /// above [`super::OUTLIER_RMS_FLOOR_PX`]); it was left out and the fit redone.
    OutlierView {
        /// The view, 0-based.
        view: usize,
        /// Its flange residual in units of the flange noise (√ of the sum of the six
        /// squared normalised components).
        flange_residual_sigmas: f64,
        /// Its reprojection RMS when it was dropped, px.
        rms_px: f64,
    },
    /// Views whose code covers less than [`super::MIN_CODE_AREA_FRACTION`] of the image:
    /// the code is far or small, and its pose (above all its distance) is imprecise.
    LittleImageCoverage {
        /// The views, 0-based.
        views: Vec<usize>,
    },
    /// The final Levenberg-Marquardt run stopped on its iteration budget.
    NotConverged {
        /// Iterations of the final fit.
        iterations: usize,
    },
}

impl HandEyeWarning {
    /// The stable snake_case code.
    #[must_use]
    pub const fn code(&self) -> &'static str {
        match self {
            Self::FewViews { .. } => "few_views",
            Self::SmallRotations { .. } => "small_rotations",
            Self::OutlierView { .. } => "outlier_view",
            Self::LittleImageCoverage { .. } => "little_image_coverage",
            Self::NotConverged { .. } => "not_converged",
        }
    }

    /// The views the warning is about (empty when it is about the whole set).
    #[must_use]
    pub fn views(&self) -> Vec<usize> {
        match self {
            Self::SmallRotations { views, .. } | Self::LittleImageCoverage { views } => {
                views.clone()
            }
            Self::OutlierView { view, .. } => vec![*view],
            Self::FewViews { .. } | Self::NotConverged { .. } => Vec::new(),
        }
    }
}

impl std::fmt::Display for HandEyeWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::FewViews { used, recommended } => write!(
                f,
                "{used} views used; take at least {recommended}, turning about several axes"
            ),
            Self::SmallRotations {
                largest_rotation_rad,
                ..
            } => write!(
                f,
                "the views differ by at most {:.1}°: turn the flange further between photos",
                largest_rotation_rad.to_degrees()
            ),
            Self::OutlierView {
                view,
                flange_residual_sigmas,
                rms_px,
            } => write!(
                f,
                "view {view} disagrees with the others (flange residual {flange_residual_sigmas:.1} σ, {rms_px:.2} px RMS) and was left out"
            ),
            Self::LittleImageCoverage { views } => write!(
                f,
                "the code is small in views {views:?}: bring the camera closer"
            ),
            Self::NotConverged { iterations } => {
                write!(f, "the fit stopped after {iterations} iterations")
            }
        }
    }
}

/// One view's outcome.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandEyeViewReport {
    /// The view, 0-based, in the order given.
    pub index: usize,
    /// Whether it took part in the final fit (false: code not read, or left out as an
    /// outlier).
    pub used: bool,
    /// Its reprojection RMS, px (per point, the length of the residual), through the
    /// solution's mount and target and its own corrected flange pose (used views) or its
    /// reported one (views left out); `None` when the code was not read.
    pub rms_px: Option<f64>,
    /// The angle between the flange orientation the solution implies for this photo and
    /// the reported one, rad; `None` when the code was not read.
    pub rotation_residual_rad: Option<f64>,
    /// The distance between the flange position the solution implies and the reported one,
    /// mm; `None` when the code was not read.
    pub translation_residual_mm: Option<f64>,
}

impl HandEyeViewReport {
    /// `rotation_residual_rad` in degrees.
    #[must_use]
    pub fn rotation_residual_deg(&self) -> Option<f64> {
        self.rotation_residual_rad.map(f64::to_degrees)
    }
}

/// A hand-eye calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct HandEyeCalibration {
    /// The setup solved.
    pub setup: HandEyeSetup,
    /// T_flange←camera (eye-in-hand) or T_robot←camera (eye-to-hand), mm; the camera frame
    /// x right, y down, z forward.
    pub camera_pose: Isometry3<f64>,
    /// T_robot←marker (eye-in-hand) or T_flange←marker (eye-to-hand), mm, the marker frame
    /// of `docs/conventions.md` with its origin at the symbol's centre (as the site map's).
    pub target_pose: Isometry3<f64>,
    /// Covariance of `camera_pose`, 6 × 6 over (δθx, δθy, δθz, δtx, δty, δtz), rad², rad·mm,
    /// mm², for the perturbation R → exp(\[δθ\]×)·R, t → t + δt with δθ and δt along the
    /// *parent* frame's axes (flange or robot): qrpose-site's `transform` convention, so it
    /// propagates with its functions as it is. Marginal over the target and the flange
    /// corrections, scaled by the estimated pixel noise.
    pub covariance: Matrix6<f64>,
    /// One standard deviation of the camera's rotation about its *own* axes (camera x, y,
    /// z: the covariance turned into the camera frame, R → R·exp(\[δθ_c\]×)), rad.
    pub std_rotation_rad: [f64; 3],
    /// One standard deviation of the camera's position along its own axes, mm.
    pub std_translation_mm: [f64; 3],
    /// RMS of the residual lengths over every point of the used views, px.
    pub reprojection_rms_px: f64,
    /// The pixel noise estimate the covariance is scaled by, px per axis.
    pub pixel_noise_px: f64,
    /// Every view, in the order given.
    pub views: Vec<HandEyeViewReport>,
    /// What the views constrain poorly, and views left out.
    pub warnings: Vec<HandEyeWarning>,
    /// Levenberg-Marquardt iterations of the final fit.
    pub iterations: usize,
}

impl HandEyeCalibration {
    /// The covariance of `camera_pose` about the camera's own axes: diag(Rᵀ, Rᵀ)·Σ·diag(R, R),
    /// for R → R·exp(\[δθ_c\]×), t → t + R·δt_c.
    #[must_use]
    pub fn covariance_camera_axes(&self) -> Matrix6<f64> {
        covariance_in_own_axes(&self.covariance, &self.camera_pose.rotation)
    }

    /// `std_rotation_rad` in degrees.
    #[must_use]
    pub fn std_rotation_deg(&self) -> [f64; 3] {
        self.std_rotation_rad.map(f64::to_degrees)
    }

    /// The camera's `mount` for the site file ([`site_mount_yaml`]).
    #[must_use]
    pub fn site_mount(&self) -> String {
        site_mount_yaml(
            self.setup,
            &self.camera_pose,
            self.std_rotation_deg(),
            self.std_translation_mm,
        )
    }
}

/// `covariance` (parent axes) turned into the axes of the pose's own frame.
pub(crate) fn covariance_in_own_axes(
    covariance: &Matrix6<f64>,
    rotation: &UnitQuaternion<f64>,
) -> Matrix6<f64> {
    let r = *rotation.to_rotation_matrix().matrix();
    let rot = super::rigid::blocks(
        r.transpose(),
        nalgebra::Matrix3::zeros(),
        nalgebra::Matrix3::zeros(),
        r.transpose(),
    );
    let c = rot * covariance * rot.transpose();
    (c + c.transpose()) * 0.5
}

/// Decimal places of the YAML's millimetres (1 µm).
const YAML_MM_DECIMALS: usize = 3;
/// Decimal places of the YAML's quaternion components (about 0.00001° each).
const YAML_QUATERNION_DECIMALS: usize = 9;
/// Decimal places of the YAML's standard deviations in degrees.
const YAML_DEG_DECIMALS: usize = 5;

fn list(values: &[f64], decimals: usize) -> String {
    let items: Vec<String> = values
        .iter()
        .map(|v| {
            // No "-0.000".
            let text = format!("{v:.decimals$}");
            if text
                .trim_start_matches('-')
                .chars()
                .all(|c| c == '0' || c == '.')
            {
                format!("{:.decimals$}", 0.0)
            } else {
                text
            }
        })
        .collect();
    format!("[{}]", items.join(", "))
}

/// The camera's `mount` block for the site file (`docs/hand-eye.md`, `docs/site.md`):
///
/// ```text
/// mount:
///   parent: flange                  # robot for eye-to-hand
///   translation_mm: [x, y, z]
///   quaternion_wxyz: [w, x, y, z]   # w ≥ 0
///   std: {rotation_deg: [a, b, c], translation_mm: [x, y, z]}
/// ```
///
/// `pose` is T_parent←camera, mm; `std_*` one standard deviation about and along the
/// camera's own axes. The quaternion is written with w ≥ 0.
#[must_use]
pub fn site_mount_yaml(
    setup: HandEyeSetup,
    pose: &Isometry3<f64>,
    std_rotation_deg: [f64; 3],
    std_translation_mm: [f64; 3],
) -> String {
    let q = pose.rotation.into_inner();
    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
    let t = pose.translation.vector;
    format!(
        "mount:\n  parent: {}\n  translation_mm: {}\n  quaternion_wxyz: {}\n  std: {{rotation_deg: {}, translation_mm: {}}}\n",
        setup.camera_parent(),
        list(&[t.x, t.y, t.z], YAML_MM_DECIMALS),
        list(
            &[sign * q.w, sign * q.i, sign * q.j, sign * q.k],
            YAML_QUATERNION_DECIMALS
        ),
        list(&std_rotation_deg, YAML_DEG_DECIMALS),
        list(&std_translation_mm, YAML_MM_DECIMALS),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, Vector3};

    #[test]
    fn the_site_mount_names_the_parent_and_writes_w_first_with_w_positive() {
        // A quarter turn about z, given with w < 0.
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            -0.5_f64.sqrt(),
            0.0,
            0.0,
            -0.5_f64.sqrt(),
        ));
        let pose = Isometry3::from_parts(Translation3::new(1.5, -2.0, 30.25), q);
        let yaml = site_mount_yaml(
            HandEyeSetup::EyeInHand,
            &pose,
            [0.01, 0.02, 0.03],
            [0.1, 0.2, 0.3],
        );
        assert_eq!(
            yaml,
            "mount:\n  parent: flange\n  translation_mm: [1.500, -2.000, 30.250]\n  \
             quaternion_wxyz: [0.707106781, 0.000000000, 0.000000000, 0.707106781]\n  \
             std: {rotation_deg: [0.01000, 0.02000, 0.03000], translation_mm: [0.100, 0.200, 0.300]}\n"
        );
        let robot = site_mount_yaml(HandEyeSetup::EyeToHand, &pose, [0.0; 3], [0.0; 3]);
        assert!(robot.contains("parent: robot\n"), "{robot}");
    }

    #[test]
    fn the_own_axes_covariance_turns_the_parent_axes_into_the_cameras() {
        // The camera turned a quarter about z: its x is the parent's y.
        let rotation =
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
        let mut c = Matrix6::zeros();
        c[(1, 1)] = 4.0; // rotation about the parent's y
        c[(3, 3)] = 9.0; // translation along the parent's x
        let own = covariance_in_own_axes(&c, &rotation);
        assert!((own[(0, 0)] - 4.0).abs() < 1e-12, "{own}");
        assert!((own[(4, 4)] - 9.0).abs() < 1e-12, "{own}");
    }
}
