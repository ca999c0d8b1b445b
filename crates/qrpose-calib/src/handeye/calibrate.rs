//! [`calibrate_hand_eye`]: input checks, each view's pose, the motion check, the closed
//! form, robust rounds of the joint fit, outlier views left out, the covariance and the
//! warnings.

use super::closed_form::{mount_from_motions, target_from_mount, view_pose};
use super::input::{
    HandEyeOptions, HandEyeSetup, HandEyeView, MIN_HAND_EYE_POINTS, MIN_HAND_EYE_VIEWS,
    check_finite, check_options,
};
use super::joint::{self, Problem, State, camera_pose_of};
use super::motion::{MIN_AXIS_SPREAD_RAD, axis_spread_rad, largest_rotation_rad};
use super::outliers::{
    MAX_OUTLIER_FRACTION, MIN_CODE_AREA_FRACTION, UsedFit, code_area_fraction, rms, view_residuals,
    worst_outlier,
};
use super::report::{
    HandEyeCalibration, HandEyeError, HandEyeViewReport, HandEyeWarning, covariance_in_own_axes,
};
use super::rigid::{compose, difference, inverse, isometry_from_pose, pose_from_isometry};
use crate::error::SolveFailure;
use crate::fit::{MAX_ROBUST_ROUNDS, SCALE_SETTLED};
use crate::input::ImageSize;
use crate::lm::ViewData;
use crate::model::{Intrinsics, Pose};
use crate::robust::{Huber, robust_sigma_px};
use nalgebra::{Matrix6, Vector2, Vector3, Vector6};
use qrpose_core::geometry::camera::{Camera, Distortion, ImageUnit};
use qrpose_core::geometry::marker::Marker;

/// Views used below which `few_views` is raised: each view adds six constraints but the
/// mount's translation needs rotations about several axes, and with fewer views one poor
/// flange pose moves the answer.
pub const RECOMMENDED_HAND_EYE_VIEWS: usize = 8;

/// Largest rotation between two views below which `small_rotations` is raised (20°): the
/// mount's translation error grows as the flange noise over the rotation angle.
pub const MIN_ROTATION_SPREAD_RAD: f64 = 20.0 * std::f64::consts::PI / 180.0;

/// A view that could be used: its index, points, own pose of the code and reported G_i.
struct ReadView {
    index: usize,
    data: ViewData,
    own_pose: Pose,
    reported: Pose,
}

/// The intrinsics of `camera` in the fitted model's form.
fn intrinsics_of(camera: &Camera) -> Intrinsics {
    let d = camera.distortion();
    let mut k = Intrinsics::pinhole(
        camera.fx(),
        camera.fy(),
        camera.cx(),
        camera.cy(),
        d.model(),
    );
    for (c, v) in k.coefficients.iter_mut().zip(d.coefficients()) {
        *c = v;
    }
    k
}

/// G_i of the reported flange pose (closed_form module doc).
fn g_of(setup: HandEyeSetup, flange: &Pose) -> Pose {
    match setup {
        HandEyeSetup::EyeInHand => *flange,
        HandEyeSetup::EyeToHand => inverse(flange),
    }
}

/// The flange pose F for G.
fn flange_of(setup: HandEyeSetup, g: &Pose) -> Pose {
    g_of(setup, g)
}

/// The views whose code was read and whose own pose was found.
fn read_views(k: &Intrinsics, lens: &Distortion, views: &[HandEyeView]) -> Vec<ReadView> {
    views
        .iter()
        .enumerate()
        .filter(|(_, v)| v.correspondences.len() >= MIN_HAND_EYE_POINTS)
        .filter_map(|(index, v)| {
            let data = ViewData {
                target_mm: v.correspondences.iter().map(|c| c.target_mm).collect(),
                pixel_px: v
                    .correspondences
                    .iter()
                    .map(|c| Vector2::new(c.pixel_px.u(), c.pixel_px.v()))
                    .collect(),
            };
            let own_pose = view_pose(k, lens, &data)?;
            Some(ReadView {
                index,
                data,
                own_pose,
                reported: pose_from_isometry(&v.flange_pose),
            })
        })
        .collect()
}

/// A fitted subset of the read views.
struct Fitted {
    used: Vec<usize>,
    state: State,
    loss: Huber,
    iterations: usize,
    converged: bool,
}

/// Closed form, then robust rounds of the joint fit, on the read views `used`.
fn fit(
    setup: HandEyeSetup,
    k: &Intrinsics,
    lens: &Distortion,
    read: &[ReadView],
    used: &[usize],
    options: &HandEyeOptions,
) -> Result<Fitted, HandEyeError> {
    let g: Vec<Pose> = used
        .iter()
        .map(|&i| g_of(setup, &read[i].reported))
        .collect();
    let c: Vec<Pose> = used.iter().map(|&i| read[i].own_pose).collect();
    let singular = HandEyeError::SolveFailed(SolveFailure::SingularSystem);
    let x = mount_from_motions(&g, &c).ok_or(singular)?;
    let y = target_from_mount(&g, &x, &c).ok_or(singular)?;
    let views: Vec<ViewData> = used.iter().map(|&i| read[i].data.clone()).collect();
    let reported: Vec<Pose> = used.iter().map(|&i| read[i].reported).collect();
    let problem = Problem::new(setup, (k, lens), &views, &reported, options.flange_noise);
    let mut state = State {
        x,
        y,
        flanges: reported.clone(),
    };
    let lengths = |s: &State| -> Result<Vec<f64>, HandEyeError> {
        joint::residuals(&problem, s)
            .map(|r| r.iter().flatten().map(Vector2::norm).collect())
            .ok_or(HandEyeError::SolveFailed(SolveFailure::NonFiniteStart))
    };
    let mut sigma = options
        .loss_scale_px
        .map_or_else(|| lengths(&state).map(|l| robust_sigma_px(&l)), Ok)?;
    let mut iterations = 0;
    let mut converged = false;
    for _ in 0..MAX_ROBUST_ROUNDS {
        let loss = Huber::for_scale(sigma);
        let outcome = joint::minimise(&problem, state, loss, options.max_iterations)
            .map_err(HandEyeError::SolveFailed)?;
        state = outcome.state;
        iterations += outcome.iterations;
        converged = outcome.converged;
        if options.loss_scale_px.is_some() {
            break;
        }
        let next = robust_sigma_px(&lengths(&state)?);
        let settled = (next - sigma).abs() <= SCALE_SETTLED * sigma;
        sigma = next;
        if settled {
            break;
        }
    }
    Ok(Fitted {
        used: used.to_vec(),
        state,
        loss: Huber::for_scale(sigma),
        iterations,
        converged,
    })
}

fn used_fits(
    setup: HandEyeSetup,
    k: &Intrinsics,
    lens: &Distortion,
    read: &[ReadView],
    fitted: &Fitted,
    options: &HandEyeOptions,
) -> Vec<UsedFit> {
    let noise = options.flange_noise;
    let (sr, st) = (noise.rotation_std_rad, noise.translation_std_mm);
    let std = Vector6::new(sr, sr, sr, st, st, st);
    fitted
        .used
        .iter()
        .zip(&fitted.state.flanges)
        .map(|(&i, f)| {
            let c = camera_pose_of(setup, &fitted.state.x, &fitted.state.y, f);
            let residuals = view_residuals(k, lens, &c, &read[i].data);
            let correction = difference(f, &read[i].reported);
            UsedFit {
                rms_px: rms(&residuals),
                flange_sigmas: correction.component_div(&std).norm(),
                correction,
            }
        })
        .collect()
}

/// Calibrates a camera's mount on a robot from photos of one printed code (module doc of
/// [`crate::handeye`]): `camera` in pixels (intrinsics and lens, as calibrated), `image`
/// the photos' size (for the coverage warning), `marker` the printed code (its side sets
/// where the symbol's centre is in the views' target points), `views` in the order taken.
///
/// Views with fewer than [`MIN_HAND_EYE_POINTS`] points, or whose own pose cannot be
/// found, are reported unused; a view that disagrees with the others is left out with an
/// `outlier_view` warning (up to [`MAX_OUTLIER_FRACTION`] of the views read).
///
/// # Errors
/// [`HandEyeError::InvalidCamera`] for an image-plane camera,
/// [`HandEyeError::InvalidOption`] for a non-positive or non-finite option,
/// [`HandEyeError::NonFinite`] for a NaN or infinite coordinate,
/// [`HandEyeError::TooFewViews`] with fewer than [`MIN_HAND_EYE_VIEWS`] views read,
/// [`HandEyeError::DegenerateMotion`] when the flange turns about fewer than two axes,
/// [`HandEyeError::SolveFailed`] when the fit cannot be solved.
///
/// # Example
/// ```
/// use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
/// use qrpose_calib::handeye::{calibrate_hand_eye, HandEyeOptions, HandEyeSetup, HandEyeView};
/// use qrpose_calib::{Correspondence, ImageSize};
/// use qrpose_core::geometry::camera::Camera;
/// use qrpose_core::geometry::marker::Marker;
///
/// let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).unwrap();
/// let marker = Marker::try_new(120.0).unwrap();
/// // The truth: the camera 80 mm along the flange's z, looking along it; the code's
/// // corner P2 in the robot frame, facing up.
/// let mount = Isometry3::from_parts(Translation3::new(5.0, -3.0, 80.0), UnitQuaternion::identity());
/// let code = Isometry3::from_parts(
///     Translation3::new(600.0, 0.0, 0.0),
///     UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
/// );
/// let views: Vec<HandEyeView> = [(0.2, 0.0, 0.0), (0.0, 0.25, 0.3), (-0.2, 0.1, -0.4), (0.1, -0.25, 0.6), (0.0, 0.0, -0.2)]
///     .iter()
///     .map(|&(rx, ry, rz)| {
///         // The camera 500 mm above the code's centre, tilted.
///         let turn = UnitQuaternion::from_euler_angles(rx, ry, rz);
///         let centre = Vector3::new(540.0, 60.0, 0.0);
///         let cam_in_code = Isometry3::from_parts(
///             Translation3::from(turn * Vector3::new(0.0, 0.0, -500.0)),
///             turn,
///         );
///         let cam_in_robot = Isometry3::from_parts(Translation3::from(centre), code.rotation) * cam_in_code;
///         let flange_pose = cam_in_robot * mount.inverse();
///         let code_in_cam = cam_in_robot.inverse() * code;
///         let correspondences = (0..=6)
///             .flat_map(|i| (0..=6).map(move |j| (f64::from(i) * -20.0, f64::from(j) * 20.0)))
///             .map(|(x, y)| {
///                 let p = code_in_cam * Point3::new(x, y, 0.0);
///                 Correspondence::new(x, y, 1000.0 * p.x / p.z + 639.5, 1000.0 * p.y / p.z + 359.5)
///             })
///             .collect();
///         HandEyeView { correspondences, flange_pose }
///     })
///     .collect();
/// let found = calibrate_hand_eye(
///     &camera, ImageSize::new(1280, 720), &marker, &views, HandEyeSetup::EyeInHand,
///     &HandEyeOptions::default(),
/// ).unwrap();
/// assert!((found.camera_pose.translation.vector - mount.translation.vector).norm() < 1e-3);
/// ```
pub fn calibrate_hand_eye(
    camera: &Camera,
    image: ImageSize,
    marker: &Marker,
    views: &[HandEyeView],
    setup: HandEyeSetup,
    options: &HandEyeOptions,
) -> Result<HandEyeCalibration, HandEyeError> {
    if camera.unit() != ImageUnit::Pixel {
        return Err(HandEyeError::InvalidCamera);
    }
    check_options(options)?;
    check_finite(views)?;
    let k = intrinsics_of(camera);
    let lens = *camera.distortion();
    let read = read_views(&k, &lens, views);
    if read.len() < MIN_HAND_EYE_VIEWS {
        return Err(HandEyeError::TooFewViews {
            read: read.len(),
            required: MIN_HAND_EYE_VIEWS,
        });
    }
    let g_read: Vec<Pose> = read.iter().map(|v| g_of(setup, &v.reported)).collect();
    let spread_rad = axis_spread_rad(&g_read);
    if spread_rad < MIN_AXIS_SPREAD_RAD {
        return Err(HandEyeError::DegenerateMotion {
            axis_spread_rad: spread_rad,
        });
    }
    #[allow(
        clippy::cast_precision_loss,
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss
    )]
    let max_dropped = (MAX_OUTLIER_FRACTION * read.len() as f64).floor() as usize;
    let mut used: Vec<usize> = (0..read.len()).collect();
    let mut warnings = Vec::new();
    let mut fitted = fit(setup, &k, &lens, &read, &used, options)?;
    let mut dropped = 0;
    loop {
        let fits = used_fits(setup, &k, &lens, &read, &fitted, options);
        let can_drop = dropped < max_dropped && used.len() > MIN_HAND_EYE_VIEWS;
        let worst = worst_outlier(&fits).filter(|_| can_drop);
        let Some(position) = worst else { break };
        let f = &fits[position];
        warnings.push(HandEyeWarning::OutlierView {
            view: read[used[position]].index,
            flange_residual_sigmas: f.flange_sigmas,
            rms_px: f.rms_px,
        });
        used.remove(position);
        dropped += 1;
        // The closed form is redone too: the outlier pulled it.
        let g_used: Vec<Pose> = used.iter().map(|&i| g_read[i]).collect();
        let spread_rad = axis_spread_rad(&g_used);
        if spread_rad < MIN_AXIS_SPREAD_RAD {
            return Err(HandEyeError::DegenerateMotion {
                axis_spread_rad: spread_rad,
            });
        }
        fitted = fit(setup, &k, &lens, &read, &used, options)?;
    }
    assemble(
        setup,
        image,
        marker,
        views.len(),
        &k,
        &lens,
        &read,
        &fitted,
        options,
        warnings,
        &g_read,
    )
}

/// The answer from the final fit.
#[allow(clippy::too_many_arguments)]
fn assemble(
    setup: HandEyeSetup,
    image: ImageSize,
    marker: &Marker,
    view_count: usize,
    k: &Intrinsics,
    lens: &Distortion,
    read: &[ReadView],
    fitted: &Fitted,
    options: &HandEyeOptions,
    mut warnings: Vec<HandEyeWarning>,
    g_read: &[Pose],
) -> Result<HandEyeCalibration, HandEyeError> {
    let views: Vec<ViewData> = fitted.used.iter().map(|&i| read[i].data.clone()).collect();
    let reported: Vec<Pose> = fitted.used.iter().map(|&i| read[i].reported).collect();
    let problem = Problem::new(setup, (k, lens), &views, &reported, options.flange_noise);
    let covariance: Matrix6<f64> = joint::mount_covariance(&problem, &fitted.state, fitted.loss)
        .ok_or(HandEyeError::SolveFailed(SolveFailure::SingularSystem))?;
    let (x, y) = (fitted.state.x, fitted.state.y);
    let camera_pose = isometry_from_pose(&x);
    // The symbol's centre in the paper's marker frame: (−l/2, l/2, 0).
    let half = 0.5 * marker.size_mm();
    let centre = Pose {
        r: nalgebra::Rotation3::identity(),
        t_mm: Vector3::new(-half, half, 0.0),
    };
    let target_pose = isometry_from_pose(&compose(&y, &centre));
    let own = covariance_in_own_axes(&covariance, &camera_pose.rotation);
    let std = |i: usize| own[(i, i)].max(0.0).sqrt();

    let fits = used_fits(setup, k, lens, read, fitted, options);
    let mut reports: Vec<HandEyeViewReport> = (0..view_count)
        .map(|index| HandEyeViewReport {
            index,
            used: false,
            rms_px: None,
            rotation_residual_rad: None,
            translation_residual_mm: None,
        })
        .collect();
    let mut all_residuals = Vec::new();
    for (position, &i) in fitted.used.iter().enumerate() {
        let f = &fits[position];
        let c = camera_pose_of(setup, &x, &y, &fitted.state.flanges[position]);
        all_residuals.extend(view_residuals(k, lens, &c, &read[i].data));
        reports[read[i].index] = HandEyeViewReport {
            index: read[i].index,
            used: true,
            rms_px: Some(f.rms_px),
            rotation_residual_rad: Some(f.correction.fixed_rows::<3>(0).norm()),
            translation_residual_mm: Some(f.correction.fixed_rows::<3>(3).norm()),
        };
    }
    for (i, v) in read.iter().enumerate() {
        if fitted.used.contains(&i) {
            continue;
        }
        // Left out: the flange pose its own view implies, G = Y·C⁻¹·X⁻¹.
        let g = compose(&compose(&y, &inverse(&v.own_pose)), &inverse(&x));
        let implied = flange_of(setup, &g);
        let d = difference(&implied, &v.reported);
        let c = camera_pose_of(setup, &x, &y, &v.reported);
        reports[v.index] = HandEyeViewReport {
            index: v.index,
            used: false,
            rms_px: Some(rms(&view_residuals(k, lens, &c, &v.data))),
            rotation_residual_rad: Some(d.fixed_rows::<3>(0).norm()),
            translation_residual_mm: Some(d.fixed_rows::<3>(3).norm()),
        };
    }

    let used_indices: Vec<usize> = fitted.used.iter().map(|&i| read[i].index).collect();
    if fitted.used.len() < RECOMMENDED_HAND_EYE_VIEWS {
        warnings.push(HandEyeWarning::FewViews {
            used: fitted.used.len(),
            recommended: RECOMMENDED_HAND_EYE_VIEWS,
        });
    }
    let g_used: Vec<Pose> = fitted.used.iter().map(|&i| g_read[i]).collect();
    let largest = largest_rotation_rad(&g_used);
    if largest < MIN_ROTATION_SPREAD_RAD {
        warnings.push(HandEyeWarning::SmallRotations {
            largest_rotation_rad: largest,
            views: used_indices.clone(),
        });
    }
    let small: Vec<usize> = fitted
        .used
        .iter()
        .zip(&fitted.state.flanges)
        .filter(|&(&i, f)| {
            let c = camera_pose_of(setup, &x, &y, f);
            code_area_fraction(k, lens, &c, &read[i].data, image) < MIN_CODE_AREA_FRACTION
        })
        .map(|(&i, _)| read[i].index)
        .collect();
    if !small.is_empty() {
        warnings.push(HandEyeWarning::LittleImageCoverage { views: small });
    }
    if !fitted.converged {
        warnings.push(HandEyeWarning::NotConverged {
            iterations: fitted.iterations,
        });
    }
    Ok(HandEyeCalibration {
        setup,
        camera_pose,
        target_pose,
        covariance,
        std_rotation_rad: [std(0), std(1), std(2)],
        std_translation_mm: [std(3), std(4), std(5)],
        reprojection_rms_px: rms(&all_residuals),
        pixel_noise_px: fitted.loss.sigma_px,
        views: reports,
        warnings,
        iterations: fitted.iterations,
    })
}
