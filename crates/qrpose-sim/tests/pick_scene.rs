//! Picking scenes: the study generator's geometry, and the truth against the picture (each
//! code found by qrpose-detect where the truth puts its corners).

use nalgebra::{Isometry3, Vector3};
use qrpose_detect::decode::{DecodeLimits, decode_gray};
use qrpose_detect::{DetectorChoice, detect_codes};
use qrpose_sim::pick::study::{
    APPROACH_FRAMES, PICK_DISTANCE_MM, PRODUCT_TYPES, grasp_in_object, marker_in_object,
    study_scene, study_site_yaml,
};
use qrpose_sim::pick::{PickScene, PickSceneError, PoseSpec, camera_in_robot, render_pick_scene};
use qrpose_sim::render::{Effects, Encoding};

fn iso(p: &PoseSpec) -> Isometry3<f64> {
    p.to_isometry().expect("a rigid transform")
}

/// The code's centre in the robot frame for the product of a photo.
fn code_centre(scene: &PickScene, product: usize) -> Vector3<f64> {
    let p = &scene.products[product];
    (iso(&p.object_in_robot) * iso(&p.marker_in_object))
        .translation
        .vector
}

#[test]
fn the_study_places_cameras_where_it_says() {
    let scene = study_scene(3, 30).expect("a scene");
    assert_eq!(
        scene,
        study_scene(3, 30).expect("a scene"),
        "same seed, same scene"
    );
    assert_ne!(scene, study_scene(4, 30).expect("a scene"));
    assert_eq!(scene.photos.len(), 30 + APPROACH_FRAMES);
    assert_eq!(
        scene.products.len(),
        31,
        "one product per pick, one for the approach"
    );
    for (i, photo) in scene.photos.iter().take(30).enumerate() {
        let camera = camera_in_robot(&scene, i).expect("a camera");
        let d = (camera.translation.vector - code_centre(&scene, i)).norm();
        assert!(
            (PICK_DISTANCE_MM[0]..=PICK_DISTANCE_MM[1]).contains(&d),
            "{}: {d} mm",
            photo.label
        );
    }
    let approach: Vec<f64> = (30..30 + APPROACH_FRAMES)
        .map(|i| {
            let camera = camera_in_robot(&scene, i).expect("a camera");
            (camera.translation.vector - code_centre(&scene, 30)).norm()
        })
        .collect();
    assert!(
        (approach[0] - 800.0).abs() < 1e-6 && (approach[APPROACH_FRAMES - 1] - 250.0).abs() < 1e-6
    );
    assert!(approach.windows(2).all(|w| w[1] < w[0]), "{approach:?}");
    // Grasps 50-150 mm from the code; codes on three different faces.
    let mut normals = Vec::new();
    for t in &PRODUCT_TYPES {
        let code = marker_in_object(t);
        for g in &t.grasps {
            let d = (grasp_in_object(g).translation.vector - code.translation.vector).norm();
            assert!(
                (50.0..=150.0).contains(&d),
                "{}{}: {d} mm",
                t.prefix,
                g.name
            );
        }
        normals.push(code.rotation * Vector3::z());
    }
    assert!((normals[0] - normals[1]).norm() > 1.0 && (normals[1] - normals[2]).norm() > 1.0);
    // The site file it writes is one qrpose reads (the site crate's own tests check that).
    let yaml = study_site_yaml(&scene);
    assert!(
        yaml.contains("parent: flange") && yaml.contains("prefix: \"SKU-C-\""),
        "{yaml}"
    );
}

#[test]
fn the_truth_agrees_with_the_picture() {
    let full = study_scene(11, 6).expect("a scene");
    // Six picks (two of each product) and the approach's first and last frames.
    let mut scene = full.clone();
    scene.photos = full.photos[..6].to_vec();
    scene.photos.push(full.photos[6].clone());
    scene
        .photos
        .push(full.photos[6 + APPROACH_FRAMES - 1].clone());
    let effects = Effects {
        supersample: 2,
        noise: 1.0,
        blur_px: 0.5,
        encoding: Encoding::Jpeg(92),
        seed: 5,
        ..Effects::default()
    };
    let rendered = render_pick_scene(&scene, &effects).expect("rendered");
    assert_eq!(rendered.len(), 8);
    let mut worst_px = 0.0f64;
    for r in &rendered {
        let truth = &r.truth;
        assert_eq!(
            truth.products.len(),
            1,
            "{}: one product in view",
            truth.label
        );
        let product = &truth.products[0];
        // The frames agree: T_robot<-object = T_robot<-camera · T_camera<-object.
        let composed = iso(&truth.camera_in_robot) * iso(&product.object_in_camera);
        let direct = iso(&product.object_in_robot);
        assert!((composed.translation.vector - direct.translation.vector).norm() < 1e-6);
        assert!(composed.rotation.angle_to(&direct.rotation) < 1e-9);
        let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("a JPEG");
        let codes = detect_codes(&image, DetectorChoice::Auto).expect("detected");
        let found = codes
            .iter()
            .find(|c| c.candidate.payload.as_deref() == Some(product.payload.as_bytes()))
            .unwrap_or_else(|| {
                panic!(
                    "{}: {} not found among {:?}",
                    truth.label,
                    product.payload,
                    codes
                        .iter()
                        .map(|c| (c.candidate.payload.clone(), c.corners_px()))
                        .collect::<Vec<_>>()
                )
            });
        for (p, t) in found.corners_px().iter().zip(&product.code.corners_px) {
            let err = (p.u() - t[0]).hypot(p.v() - t[1]);
            worst_px = worst_px.max(err);
            assert!(err < 1.0, "{}: corner {err} px from the truth", truth.label);
        }
    }
    assert!(worst_px > 0.0, "the detector measured, it did not copy");
}

#[test]
fn a_scene_with_a_bad_pose_is_refused_with_its_field() {
    let mut scene = study_scene(1, 3).expect("a scene");
    scene.products[1].marker_in_object.quaternion_wxyz = [1.0, 0.1, 0.0, 0.0];
    let err = render_pick_scene(&scene, &Effects::default()).expect_err("refused");
    assert_eq!(
        err,
        PickSceneError::Pose {
            field: "/products/1/marker_in_object".to_owned()
        }
    );
}
