//! `locate_markers` (the detect crate's photo-to-pose call) on rendered photos, whose ground
//! truth the renderer knows.

use nalgebra::Vector3;
use qrpose_core::estimate::{Method, ValidSolver};
use qrpose_core::geometry::{camera::Camera, euler::EulerXyz, marker::Marker};
use qrpose_detect::pipeline::{Options, Points, Setup, locate_markers};
use qrpose_sim::render::{EcLevel, Effects, Rendered, Scene, render};

/// Position tolerance on a clean rendered photo at 300 mm, mm.
const POSITION_TOL_MM: f64 = 1.0;

fn photo(setup: &Setup) -> Rendered {
    let pose = setup.sizes.pose_centred_at(
        EulerXyz::from_degrees(15.0, -20.0, 10.0).to_rotation(),
        Vector3::new(10.0, -5.0, 300.0),
    );
    let scene = Scene {
        payload: b"PIPE-1".to_vec(),
        ec_level: EcLevel::M,
        marker: setup.sizes,
        camera: setup.camera,
        width_px: 640,
        height_px: 480,
        pose,
    };
    render(&scene, &Effects::default()).expect("renders")
}

fn setup(method: Method) -> Setup {
    Setup {
        camera: Camera::from_pixels(900.0, 900.0, 319.5, 239.5).expect("valid camera"),
        sizes: Marker::try_new(40.0).expect("valid size"),
        solver: ValidSolver::default_for(method),
    }
}

#[test]
fn every_method_and_point_set_finds_the_rendered_pose() {
    let cases = [
        (Method::Reprojection, Points::Corners),
        (Method::Reprojection, Points::Finders),
        (Method::DepthNewton, Points::Corners),
    ];
    for (method, points) in cases {
        let setup = setup(method);
        let rendered = photo(&setup);
        let options = Options {
            points,
            ..Options::default()
        };
        let located = locate_markers(&rendered.image, &setup, &options).expect("detector built");
        assert_eq!(located.markers.len(), 1, "{method:?} {points:?}");
        let marker = &located.markers[0];
        assert_eq!(marker.points_used, points, "{method:?}");
        assert_eq!(marker.code.candidate.text.as_deref(), Some("PIPE-1"));
        let estimate = marker.pose.as_ref().expect("a pose");
        assert_eq!(estimate.diagnostics.method, method);
        let truth = Vector3::from(rendered.truth.position_mm);
        let error_mm = (estimate.centre_mm - truth).norm();
        assert!(
            error_mm < POSITION_TOL_MM,
            "{method:?} {points:?}: {error_mm} mm"
        );
        assert!(located.detect_ms > 0.0 && located.estimate_ms >= 0.0);
    }
}

#[test]
fn a_photo_without_a_code_locates_nothing() {
    let setup = setup(Method::Reprojection);
    let blank = qrpose_detect::decode::GrayImage::new(320, 240, vec![200; 320 * 240])
        .expect("a valid image");
    let located = locate_markers(&blank, &setup, &Options::default()).expect("detector built");
    assert!(located.markers.is_empty());
}
