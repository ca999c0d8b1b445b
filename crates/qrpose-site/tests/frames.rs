//! Frames end to end: a robot with a known pose in the warehouse, a camera on a known mount,
//! three mapped codes. From the codes' projected corners, each code's `robot_pose_in_world`
//! and the fused localisation must recover the robot (exact corners: within 1 mm and 0.1°),
//! and with noisy corners the fused covariance must match the observed error (mean NEES
//! within 20 % of its 6 degrees of freedom over 500 trials).

use nalgebra::{Matrix3, Rotation3, Vector3, Vector6};
use qrpose_core::estimate::{ValidSolver, estimate_pose};
use qrpose_core::geometry::{
    camera::Camera,
    euler::EulerXyz,
    frames::PixelPoint,
    marker::{CornerOrder, Marker},
    quad::ImageQuad,
};
use qrpose_site::localize::fuse;
use qrpose_site::transform::{
    PoseWithCovariance, Rigid, marker_in_camera, perturbation_between, pose_in_robot,
    robot_pose_in_world,
};
use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::StandardNormal;

/// Largest position error on exact corners, mm.
const EXACT_POSITION_MM: f64 = 1.0;
/// Largest rotation error on exact corners, degrees.
const EXACT_ROTATION_DEG: f64 = 0.1;
/// Corner noise of the noisy trials, px per coordinate.
const SIGMA_PX: f64 = 0.5;
/// Noisy trials.
const TRIALS: u32 = 500;

struct World {
    camera: Camera,
    robot_in_world: Rigid,
    mount: Rigid,
    /// (marker, T_world←marker with the origin at the code's centre).
    codes: Vec<(Marker, Rigid)>,
}

/// A robot at (12 m, 4.5 m) turned 90°, a forward camera 300 mm ahead and 500 mm up, and
/// three codes of 80 and 100 mm on racks 0.8-1.0 m ahead, each turned differently.
fn world() -> World {
    let robot_in_world = Rigid {
        rotation: Rotation3::from_axis_angle(&Vector3::z_axis(), 90f64.to_radians()),
        translation_mm: Vector3::new(12000.0, 4500.0, 0.0),
    };
    #[rustfmt::skip]
    let forward = Rotation3::from_matrix_unchecked(Matrix3::new(
        0.0, 0.0, 1.0,
        -1.0, 0.0, 0.0,
        0.0, -1.0, 0.0,
    ));
    let mount = Rigid {
        rotation: forward,
        translation_mm: Vector3::new(300.0, 0.0, 500.0),
    };
    let in_camera = [
        (80.0, [-220.0, 40.0, 900.0], [10.0, 35.0, 0.0]),
        (80.0, [230.0, -30.0, 1000.0], [-10.0, -30.0, 0.0]),
        (100.0, [20.0, 90.0, 800.0], [40.0, 10.0, 20.0]),
    ];
    let camera_in_world = robot_in_world.then(&mount);
    let codes = in_camera
        .iter()
        .map(|&(size_mm, centre, euler)| {
            let marker_in_camera = Rigid {
                rotation: EulerXyz::from_degrees(euler[0], euler[1], euler[2]).to_rotation(),
                translation_mm: Vector3::from(centre),
            };
            (
                Marker::try_new(size_mm).expect("a size"),
                camera_in_world.then(&marker_in_camera),
            )
        })
        .collect();
    World {
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a camera"),
        robot_in_world,
        mount,
        codes,
    }
}

impl World {
    /// Code i's corners (paper order), with Gaussian noise of `sigma_px`.
    fn corners(&self, i: usize, sigma_px: f64, rng: &mut StdRng) -> [PixelPoint; 4] {
        let (marker, in_world) = &self.codes[i];
        let camera_in_world = self.robot_in_world.then(&self.mount);
        let in_camera = camera_in_world.inverse().then(in_world);
        let pose = marker.pose_centred_at(in_camera.rotation, in_camera.translation_mm);
        marker.object_points().map(|m| {
            let p = self.camera.project(&pose.transform(&m)).expect("in front");
            let mut noise = || sigma_px * rng.sample::<f64, _>(StandardNormal);
            PixelPoint::new(p.u() + noise(), p.v() + noise())
        })
    }

    /// Code i's estimate and the robot's pose in the world from it.
    fn robot_from_code(&self, i: usize, sigma_px: f64, rng: &mut StdRng) -> PoseWithCovariance {
        let (marker, in_world) = &self.codes[i];
        let quad =
            ImageQuad::try_new(self.corners(i, sigma_px, rng), CornerOrder::Paper).expect("a quad");
        let estimate =
            estimate_pose(&quad, &self.camera, marker, &ValidSolver::default()).expect("a pose");
        robot_pose_in_world(in_world, &marker_in_camera(&estimate), &self.mount)
    }
}

fn errors(truth: &Rigid, estimate: &Rigid) -> (f64, f64) {
    let e = perturbation_between(truth, estimate);
    let rotation_deg = Vector3::new(e[0], e[1], e[2]).norm().to_degrees();
    let position_mm = Vector3::new(e[3], e[4], e[5]).norm();
    (position_mm, rotation_deg)
}

fn nees(truth: &Rigid, estimate: &PoseWithCovariance) -> f64 {
    let e: Vector6<f64> = perturbation_between(truth, &estimate.pose);
    let c = estimate.covariance.expect("a covariance");
    e.dot(&c.cholesky().expect("positive definite").solve(&e))
}

#[test]
fn exact_corners_give_the_robot_within_a_millimetre_and_a_tenth_of_a_degree() {
    let w = world();
    let mut rng = StdRng::seed_from_u64(0);
    let per_code: Vec<PoseWithCovariance> = (0..w.codes.len())
        .map(|i| w.robot_from_code(i, 0.0, &mut rng))
        .collect();
    for (i, p) in per_code.iter().enumerate() {
        let (mm, deg) = errors(&w.robot_in_world, &p.pose);
        assert!(
            mm < EXACT_POSITION_MM && deg < EXACT_ROTATION_DEG,
            "code {i}: robot_pose_in_world off by {mm:.2e} mm, {deg:.2e}°"
        );
    }
    let fused = fuse(&per_code).expect("fused");
    let (mm, deg) = errors(&w.robot_in_world, &fused.pose.pose);
    assert!(
        mm < EXACT_POSITION_MM && deg < EXACT_ROTATION_DEG,
        "localisation off by {mm:.2e} mm, {deg:.2e}°"
    );
    assert!(fused.codes.iter().all(|c| !c.outlier), "{:?}", fused.codes);
    println!("exact corners: localisation off by {mm:.2e} mm, {deg:.2e}°");
}

#[test]
fn pose_in_robot_is_the_code_seen_through_the_mount() {
    let w = world();
    let mut rng = StdRng::seed_from_u64(0);
    let (marker, in_world) = &w.codes[0];
    let quad = ImageQuad::try_new(w.corners(0, 0.0, &mut rng), CornerOrder::Paper).expect("quad");
    let estimate =
        estimate_pose(&quad, &w.camera, marker, &ValidSolver::default()).expect("a pose");
    let in_robot = pose_in_robot(&w.mount, &marker_in_camera(&estimate));
    let truth = w.robot_in_world.inverse().then(in_world);
    let (mm, deg) = errors(&truth, &in_robot.pose);
    assert!(mm < 1e-6 && deg < 1e-6, "{mm} mm, {deg}°");
}

#[test]
fn the_fused_covariance_matches_the_observed_error_over_500_noisy_trials() {
    let w = world();
    let mut rng = StdRng::seed_from_u64(14);
    let mut fused_nees = 0.0;
    let mut per_code_nees = vec![0.0; w.codes.len()];
    let mut outliers = 0;
    for _ in 0..TRIALS {
        let per_code: Vec<PoseWithCovariance> = (0..w.codes.len())
            .map(|i| w.robot_from_code(i, SIGMA_PX, &mut rng))
            .collect();
        for (sum, p) in per_code_nees.iter_mut().zip(&per_code) {
            *sum += nees(&w.robot_in_world, p);
        }
        let fused = fuse(&per_code).expect("fused");
        outliers += fused.codes.iter().filter(|c| c.outlier).count();
        fused_nees += nees(&w.robot_in_world, &fused.pose);
    }
    let dof = 6.0;
    let mean = fused_nees / f64::from(TRIALS);
    let per_code: Vec<f64> = per_code_nees
        .iter()
        .map(|s| s / f64::from(TRIALS))
        .collect();
    println!(
        "mean NEES over {TRIALS} trials: fused {mean:.2}, per code {per_code:.2?} (dof 6); {outliers} outlier flags"
    );
    assert!(
        (mean - dof).abs() <= 0.2 * dof,
        "fused: mean NEES {mean:.2}, expected 6 ± 1.2"
    );
    for (i, m) in per_code.iter().enumerate() {
        assert!(
            (m - dof).abs() <= 0.2 * dof,
            "code {i}: mean NEES {m:.2}, expected 6 ± 1.2"
        );
    }
}
