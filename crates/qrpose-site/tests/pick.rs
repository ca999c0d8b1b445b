//! Picking against Monte Carlo: the covariance carried from the code through the box to a
//! grasp 150 mm away and into the robot frame (through an uncertain flange mount), the
//! probability of being within tolerance, its limits and analytic cases, and every reason.

use nalgebra::{Matrix6, Rotation3, Vector3, Vector6};
use qrpose_site::Site;
use qrpose_site::objects::Tolerance;
use qrpose_site::pick::{
    PickError, PickOptions, PickReason, camera_in_robot, plan_pick, within_tolerance_probability,
};
use qrpose_site::transform::{PoseWithCovariance, Rigid, perturbation_between};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use std::path::Path;

/// A box whose code is on its +x face and whose grasp is on its top, 150 mm from the code's
/// centre (lever arm (−100, 0, 112) mm in object axes: √(100² + 112²) = 150.1 mm).
const SITE: &str = "\
cameras:
  wrist:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 640, cy_px: 360}
    mount:
      parent: flange
      translation_mm: [0, 60, 40]
      quaternion_wxyz: [0.9961947, 0, 0, 0.0871557]
      std: {rotation_deg: [0.05, 0.04, 0.08], translation_mm: [0.3, 0.2, 0.5]}
  fixed:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 640, cy_px: 360}
    mount: {translation_mm: [500, 0, 900], quaternion_wxyz: [0, 1, 0, 0]}
  loose:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 640, cy_px: 360}
objects:
  - prefix: \"SKU-\"
    box_mm: [200, 150, 224]
    code: {translation_mm: [100, 0, 0], quaternion_wxyz: [0.5, 0.5, -0.5, 0.5]}
    grasps:
      - name: top
        kind: suction
        translation_mm: [0, 0, 112]
        quaternion_wxyz: [0, 1, 0, 0]
        tolerance: {position_mm: 5, rotation_deg: 3}
        approach_mm: 80
      - name: pinch
        kind: parallel
        translation_mm: [0, 0, 0]
        quaternion_wxyz: [0, 1, 0, 0]
        width_mm: 150
        tolerance: {position_mm: 6, rotation_deg: 4}
";

fn site() -> Site {
    Site::parse(SITE, Path::new("/sites/pick.yaml")).expect("a valid site")
}

/// The code 600 mm in front of the camera, turned a little, with a correlated covariance
/// of the size a 40 mm code at that distance gets (0.2-0.5°, 0.5-3 mm).
/// The pose of the site's camera `fixed` (mounted on the robot) in the robot frame.
fn fixed_camera_in_robot(site: &Site) -> Option<PoseWithCovariance> {
    let fixed = site
        .camera("fixed")
        .and_then(|c| c.camera_mount)
        .expect("mount");
    camera_in_robot(Some(&fixed), None)
}

fn marker_in_camera(scale: f64) -> PoseWithCovariance {
    let l = Matrix6::from_fn(|i, k| {
        let sd = [0.004, 0.006, 0.002, 0.6, 0.5, 2.5][i];
        if i == k {
            sd
        } else if i > k {
            0.3 * sd * (((i + 2 * k) % 3) as f64 - 1.0)
        } else {
            0.0
        }
    });
    PoseWithCovariance {
        pose: Rigid {
            rotation: Rotation3::from_euler_angles(0.2, -0.3, 0.1),
            translation_mm: Vector3::new(30.0, -20.0, 600.0),
        },
        covariance: Some(l * l.transpose() * scale * scale),
    }
}

fn flange_pose() -> Rigid {
    Rigid {
        rotation: Rotation3::from_euler_angles(3.0, 0.2, -0.7),
        translation_mm: Vector3::new(400.0, -150.0, 700.0),
    }
}

fn cholesky(c: &Matrix6<f64>) -> Matrix6<f64> {
    c.cholesky().expect("positive definite").l()
}

fn normal6(rng: &mut StdRng) -> Vector6<f64> {
    Vector6::from_fn(|_, _| StandardNormal.sample(rng))
}

/// `p` moved by the perturbation `d` in the convention of qrpose_site::transform.
fn perturbed(p: &Rigid, d: &Vector6<f64>) -> Rigid {
    Rigid {
        rotation: Rotation3::new(Vector3::new(d[0], d[1], d[2])) * p.rotation,
        translation_mm: p.translation_mm + Vector3::new(d[3], d[4], d[5]),
    }
}

fn sample_covariance(samples: &[Vector6<f64>]) -> Matrix6<f64> {
    let n = samples.len() as f64;
    let mean = samples.iter().sum::<Vector6<f64>>() / n;
    samples
        .iter()
        .map(|s| (s - mean) * (s - mean).transpose())
        .sum::<Matrix6<f64>>()
        / (n - 1.0)
}

/// Largest relative difference of the standard deviations, and largest difference of the
/// correlation coefficients.
fn compare(propagated: &Matrix6<f64>, sampled: &Matrix6<f64>) -> (f64, f64) {
    let sd_p = propagated.diagonal().map(f64::sqrt);
    let sd_s = sampled.diagonal().map(f64::sqrt);
    let sd_rel = (0..6)
        .map(|i| (sd_p[i] - sd_s[i]).abs() / sd_s[i])
        .fold(0.0, f64::max);
    let mut corr = 0.0f64;
    for i in 0..6 {
        for k in 0..6 {
            let rp = propagated[(i, k)] / (sd_p[i] * sd_p[k]);
            let rs = sampled[(i, k)] / (sd_s[i] * sd_s[k]);
            corr = corr.max((rp - rs).abs());
        }
    }
    (sd_rel, corr)
}

#[test]
fn the_grasp_covariance_in_the_robot_frame_matches_monte_carlo() {
    let site = site();
    let (_, rule) = site.object_for("SKU-42").expect("a rule");
    let mount = site
        .camera("wrist")
        .and_then(|c| c.camera_mount)
        .expect("mount");
    let std = mount.std.expect("std");
    let flange = flange_pose();
    let marker = marker_in_camera(1.0);
    let in_robot = camera_in_robot(Some(&mount), Some(&flange)).expect("robot frame");
    let plan = plan_pick(&marker, rule, Some(&in_robot), &PickOptions::default()).expect("plan");
    let grasp = &rule.grasps[0];
    let marker_to_grasp = rule.marker_in_object.inverse().then(&grasp.grasp_in_object);
    assert!(
        (marker_to_grasp.translation_mm.norm() - 150.0).abs() < 0.5,
        "the grasp is {} mm from the code",
        marker_to_grasp.translation_mm.norm()
    );

    let mut rng = StdRng::seed_from_u64(7);
    let l = cholesky(&marker.covariance.expect("covariance"));
    let nominal_robot = plan.grasps[0].pose_in_robot.expect("in robot").pose;
    let nominal_camera = plan.grasps[0].pose.pose;
    let nominal_object = plan.pose.pose;
    let (mut robot, mut camera, mut object) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..40_000 {
        let m = perturbed(&marker.pose, &(l * normal6(&mut rng)));
        // The mount's error about and along the camera's own axes, as the site file means.
        let z = normal6(&mut rng);
        let phi = std
            .rotation_rad
            .component_mul(&Vector3::new(z[0], z[1], z[2]));
        let rho = std
            .translation_mm
            .component_mul(&Vector3::new(z[3], z[4], z[5]));
        let mount_sample = Rigid {
            rotation: mount.pose.rotation * Rotation3::new(phi),
            translation_mm: mount.pose.translation_mm + mount.pose.rotation * rho,
        };
        let grasp_in_camera = m.then(&marker_to_grasp);
        let grasp_in_robot = flange.then(&mount_sample).then(&grasp_in_camera);
        robot.push(perturbation_between(&nominal_robot, &grasp_in_robot));
        camera.push(perturbation_between(&nominal_camera, &grasp_in_camera));
        let object_in_camera = m.then(&rule.marker_in_object.inverse());
        object.push(perturbation_between(&nominal_object, &object_in_camera));
    }
    let cases = [
        (
            "grasp in robot",
            plan.grasps[0].pose_in_robot.and_then(|p| p.covariance),
            robot,
        ),
        ("grasp in camera", plan.grasps[0].pose.covariance, camera),
        ("object in camera", plan.pose.covariance, object),
    ];
    for (name, propagated, samples) in cases {
        let propagated = propagated.expect("a covariance");
        let (sd_rel, corr) = compare(&propagated, &sample_covariance(&samples));
        // 40 000 draws: a standard deviation is known to ±0.35 % (1σ), a correlation to ±0.005.
        assert!(
            sd_rel < 0.03,
            "{name}: standard deviations differ by {sd_rel}"
        );
        assert!(corr < 0.03, "{name}: correlations differ by {corr}");
    }
    // The lever arm: the code's rotation error moves the grasp 150 mm away, so the grasp's
    // position error is larger than the code's.
    let grasp_cov = plan.grasps[0].pose.covariance.expect("covariance");
    let marker_cov = marker.covariance.expect("covariance");
    let ratio =
        grasp_cov.fixed_view::<3, 3>(3, 3).trace() / marker_cov.fixed_view::<3, 3>(3, 3).trace();
    assert!(ratio > 1.05, "position variance ratio {ratio}");
}

#[test]
fn the_probability_matches_monte_carlo() {
    let site = site();
    let (_, rule) = site.object_for("SKU-1").expect("a rule");
    let mount = site
        .camera("wrist")
        .and_then(|c| c.camera_mount)
        .expect("mount");
    let in_robot = camera_in_robot(Some(&mount), Some(&flange_pose())).expect("robot frame");
    let mut rng = StdRng::seed_from_u64(11);
    let mut checked = 0;
    for scale in [0.5, 0.8, 1.0, 1.3] {
        let plan = plan_pick(
            &marker_in_camera(scale),
            rule,
            Some(&in_robot),
            &PickOptions::default(),
        )
        .expect("plan");
        for (grasp, planned) in rule.grasps.iter().zip(&plan.grasps) {
            let cov = planned
                .pose_in_robot
                .and_then(|p| p.covariance)
                .expect("cov");
            let p = planned.within_tolerance_probability.expect("a probability");
            assert_eq!(
                within_tolerance_probability(&cov, &grasp.tolerance),
                Some(p)
            );
            let l = cholesky(&cov);
            let n = 200_000;
            let inside = (0..n)
                .filter(|_| {
                    let d = l * normal6(&mut rng);
                    let rotation = Vector3::new(d[0], d[1], d[2]).norm();
                    let position = Vector3::new(d[3], d[4], d[5]).norm();
                    rotation <= grasp.tolerance.rotation_rad
                        && position <= grasp.tolerance.position_mm
                })
                .count();
            let monte_carlo = inside as f64 / n as f64;
            // Monte Carlo's own standard error is at most 0.0011.
            assert!(
                (p - monte_carlo).abs() < 0.01,
                "scale {scale}, grasp {}: {p} vs Monte Carlo {monte_carlo}",
                grasp.name
            );
            if (0.05..0.95).contains(&monte_carlo) {
                checked += 1;
            }
        }
    }
    assert!(checked >= 3, "only {checked} cases away from 0 and 1");
}

/// erf(x), Abramowitz and Stegun 7.1.26 (|error| < 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.3275911 * x.abs());
    let poly = t
        * (0.254829592
            + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))));
    (1.0 - poly * (-x * x).exp()).copysign(x)
}

#[test]
fn the_probability_matches_analytic_cases() {
    let sigma_mm = 2.0;
    let sigma_rad = 0.01;
    let loose = |position_mm, rotation_rad| Tolerance {
        position_mm,
        rotation_rad,
    };
    for k in [0.5, 1.0, 2.0, 3.0] {
        // One axis of position: P(|x| ≤ kσ) = erf(k/√2).
        let mut c = Matrix6::zeros();
        c[(4, 4)] = sigma_mm * sigma_mm;
        let p = within_tolerance_probability(&c, &loose(k * sigma_mm, 1.0)).expect("p");
        let exact = erf(k / 2f64.sqrt());
        assert!(
            (p - exact).abs() < 0.005,
            "1-D position, k {k}: {p} vs {exact}"
        );
        // One axis of rotation.
        let mut c = Matrix6::zeros();
        c[(2, 2)] = sigma_rad * sigma_rad;
        let p = within_tolerance_probability(&c, &loose(1.0, k * sigma_rad)).expect("p");
        assert!(
            (p - exact).abs() < 0.005,
            "1-D rotation, k {k}: {p} vs {exact}"
        );
        // Isotropic 3-D position: the chi distribution with 3 degrees of freedom.
        let c = Matrix6::from_diagonal(&Vector6::new(0.0, 0.0, 0.0, 4.0, 4.0, 4.0));
        let p = within_tolerance_probability(&c, &loose(k * sigma_mm, 1.0)).expect("p");
        let exact3 =
            erf(k / 2f64.sqrt()) - (2.0 / std::f64::consts::PI).sqrt() * k * (-k * k / 2.0).exp();
        assert!(
            (p - exact3).abs() < 0.005,
            "3-D position, k {k}: {p} vs {exact3}"
        );
        // Independent rotation and position: the product.
        let c = Matrix6::from_diagonal(&Vector6::new(0.0, 0.0, 1e-4, 0.0, 0.0, 4.0));
        let p = within_tolerance_probability(&c, &loose(k * sigma_mm, k * sigma_rad)).expect("p");
        assert!(
            (p - exact * exact).abs() < 0.01,
            "product, k {k}: {p} vs {}",
            exact * exact
        );
    }
}

#[test]
fn tiny_and_huge_covariances_give_one_and_zero() {
    let site = site();
    let (_, rule) = site.object_for("SKU-1").expect("a rule");
    let in_robot = fixed_camera_in_robot(&site).expect("a robot mount");
    let tiny = plan_pick(
        &marker_in_camera(1e-3),
        rule,
        Some(&in_robot),
        &PickOptions::default(),
    )
    .expect("plan");
    let huge = plan_pick(
        &marker_in_camera(100.0),
        rule,
        Some(&in_robot),
        &PickOptions::default(),
    )
    .expect("plan");
    for g in &tiny.grasps {
        assert_eq!(g.within_tolerance_probability, Some(1.0), "{}", g.name);
        assert!(
            g.graspable && g.reasons.is_empty(),
            "{}: {:?}",
            g.name,
            g.reasons
        );
    }
    for g in &huge.grasps {
        let p = g.within_tolerance_probability.expect("p");
        assert!(p < 0.01, "{}: {p}", g.name);
        assert_eq!(g.reasons, [PickReason::BelowProbability], "{}", g.name);
        assert!(!g.graspable);
    }
}

#[test]
fn every_reason_is_given_when_it_applies() {
    let site = site();
    let (label, rule) = site.object_for("SKU-7").expect("a rule");
    assert_eq!(label, "prefix:SKU-");
    let wrist = site.camera("wrist").and_then(|c| c.camera_mount);
    let fixed = site.camera("fixed").and_then(|c| c.camera_mount);
    let loose = site.camera("loose").and_then(|c| c.camera_mount);
    assert!(loose.is_none());
    let flange = flange_pose();
    let good = marker_in_camera(0.01);
    let no_covariance = PoseWithCovariance {
        covariance: None,
        ..good
    };
    let options = |pose_ambiguous, not_converged| PickOptions {
        pose_ambiguous,
        not_converged,
        ..PickOptions::default()
    };
    use PickReason::*;
    type Case = (
        &'static str,
        PoseWithCovariance,
        Option<PoseWithCovariance>,
        PickOptions,
        Vec<PickReason>,
    );
    let cases: Vec<Case> = vec![
        (
            "all well",
            good,
            camera_in_robot(wrist.as_ref(), Some(&flange)),
            options(false, false),
            vec![],
        ),
        (
            "flange mount without a flange pose",
            good,
            camera_in_robot(wrist.as_ref(), None),
            options(false, false),
            vec![NoRobotPose],
        ),
        (
            "no mount",
            good,
            camera_in_robot(loose.as_ref(), Some(&flange)),
            options(false, false),
            vec![NoRobotPose],
        ),
        (
            "ambiguous",
            good,
            camera_in_robot(fixed.as_ref(), None),
            options(true, false),
            vec![PoseAmbiguous],
        ),
        (
            "not converged",
            good,
            camera_in_robot(fixed.as_ref(), None),
            options(false, true),
            vec![NotConverged],
        ),
        (
            "a fit worse than the corners' noise",
            good,
            camera_in_robot(fixed.as_ref(), None),
            PickOptions {
                high_reprojection_error: true,
                ..PickOptions::default()
            },
            vec![HighReprojectionError],
        ),
        (
            "no covariance",
            no_covariance,
            camera_in_robot(fixed.as_ref(), None),
            options(false, false),
            vec![BelowProbability],
        ),
        (
            "everything",
            marker_in_camera(50.0),
            None,
            options(true, true),
            vec![NoRobotPose, PoseAmbiguous, BelowProbability, NotConverged],
        ),
    ];
    for (name, marker, in_robot, opts, reasons) in cases {
        let plan = plan_pick(&marker, rule, in_robot.as_ref(), &opts).expect(name);
        assert_eq!(plan.rule, "prefix:SKU-");
        assert_eq!(plan.pose_in_robot.is_some(), in_robot.is_some(), "{name}");
        for g in &plan.grasps {
            assert_eq!(g.reasons, reasons, "{name}: {}", g.name);
            assert_eq!(g.graspable, reasons.is_empty(), "{name}: {}", g.name);
            assert_eq!(g.pose_in_robot.is_some(), in_robot.is_some(), "{name}");
            if in_robot.is_none() {
                assert!(g.pre_grasp_in_robot.is_none(), "{name}");
            }
            assert_eq!(
                g.within_tolerance_probability.is_some(),
                marker.covariance.is_some(),
                "{name}"
            );
        }
    }
    let codes: Vec<&str> = [
        NoRobotPose,
        PoseAmbiguous,
        BelowProbability,
        NotConverged,
        HighReprojectionError,
    ]
    .iter()
    .map(|r| r.as_str())
    .collect();
    assert_eq!(
        codes,
        [
            "no_robot_pose",
            "pose_ambiguous",
            "below_probability",
            "not_converged",
            "high_reprojection_error"
        ]
    );
}

#[test]
fn the_minimum_probability_is_the_bar_and_is_checked() {
    let site = site();
    let (_, rule) = site.object_for("SKU-1").expect("a rule");
    let in_robot = fixed_camera_in_robot(&site);
    let marker = marker_in_camera(1.3);
    let plan = plan_pick(&marker, rule, in_robot.as_ref(), &PickOptions::default()).expect("plan");
    let p = plan.grasps[0].within_tolerance_probability.expect("p");
    assert!(
        (0.05..0.95).contains(&p),
        "{p}: pick a scale that gives a middling probability"
    );
    for (min, graspable) in [(p, true), (p + 1e-6, false), (0.0, true), (1.0, false)] {
        let opts = PickOptions {
            min_grasp_probability: min,
            ..PickOptions::default()
        };
        let plan = plan_pick(&marker, rule, in_robot.as_ref(), &opts).expect("plan");
        assert_eq!(plan.grasps[0].graspable, graspable, "min {min}, p {p}");
    }
    for bad in [-0.1, 1.01, f64::NAN] {
        let opts = PickOptions {
            min_grasp_probability: bad,
            ..PickOptions::default()
        };
        let err = plan_pick(&marker, rule, in_robot.as_ref(), &opts)
            .map(|_| ())
            .expect_err("refused");
        assert!(
            matches!(err, PickError::MinGraspProbability { .. }),
            "{bad}"
        );
    }
}

#[test]
fn a_pose_that_may_be_the_mirror_has_its_probability_discounted_and_is_not_graspable() {
    let site = site();
    let (_, rule) = site.object_for("SKU-1").expect("a rule");
    let in_robot = fixed_camera_in_robot(&site);
    // A tight estimate: graspable on its own.
    let marker = marker_in_camera(0.05);
    let sure = plan_pick(&marker, rule, in_robot.as_ref(), &PickOptions::default()).expect("plan");
    let p = sure.grasps[0].within_tolerance_probability.expect("p");
    assert!(p > 0.99 && sure.grasps[0].graspable, "{p}");
    for mirror in [0.04, 0.3] {
        let opts = PickOptions {
            alternative_probability: mirror,
            ..PickOptions::default()
        };
        let plan = plan_pick(&marker, rule, in_robot.as_ref(), &opts).expect("plan");
        let q = plan.grasps[0].within_tolerance_probability.expect("p");
        assert!((q - p * (1.0 - mirror)).abs() < 1e-12, "{q} against {p}");
        assert_eq!(plan.grasps[0].graspable, q >= 0.95, "mirror {mirror}");
    }
    let opts = PickOptions {
        alternative_probability: 1.5,
        ..PickOptions::default()
    };
    assert!(matches!(
        plan_pick(&marker, rule, in_robot.as_ref(), &opts),
        Err(PickError::AlternativeProbability { .. })
    ));
}

#[test]
fn the_pre_grasp_lies_back_along_the_approach_axis() {
    let site = site();
    let (_, rule) = site.object_for("SKU-1").expect("a rule");
    let wrist = site
        .camera("wrist")
        .and_then(|c| c.camera_mount)
        .expect("mount");
    let in_robot = camera_in_robot(Some(&wrist), Some(&flange_pose()));
    let plan = plan_pick(
        &marker_in_camera(1.0),
        rule,
        in_robot.as_ref(),
        &PickOptions::default(),
    )
    .expect("plan");
    let top = &plan.grasps[0];
    let grasp = top.pose_in_robot.expect("in robot").pose;
    let pre = top.pre_grasp_in_robot.expect("approach_mm is given").pose;
    let approach = grasp.rotation * Vector3::z();
    let back = grasp.translation_mm - pre.translation_mm;
    assert!((back.norm() - 80.0).abs() < 1e-9, "{}", back.norm());
    assert!(
        (back - 80.0 * approach).norm() < 1e-9,
        "{back} vs {approach}"
    );
    assert!((pre.rotation.matrix() - grasp.rotation.matrix()).amax() < 1e-12);
    // The tool moves along +z into the grasp: here the grasp's z points into the box, whose
    // centre lies ahead of the grasp along z.
    let object = plan.pose_in_robot.expect("in robot").pose;
    assert!((object.translation_mm - grasp.translation_mm).dot(&approach) > 0.0);
    // Its covariance grows at the lever arm of the approach.
    let c_grasp = top.pose_in_robot.and_then(|p| p.covariance).expect("cov");
    let c_pre = top
        .pre_grasp_in_robot
        .and_then(|p| p.covariance)
        .expect("cov");
    assert!(c_pre.fixed_view::<3, 3>(3, 3).trace() > c_grasp.fixed_view::<3, 3>(3, 3).trace());
    // The parallel grasp has no approach_mm: no pre-grasp; it carries its width.
    assert!(plan.grasps[1].pre_grasp_in_robot.is_none());
    assert_eq!(plan.grasps[1].width_mm, Some(150.0));
    assert_eq!(plan.grasps[0].width_mm, None);
}
