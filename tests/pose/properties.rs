//! Property tests: exact projections of random poses come back.
//!
//! Poses: tilt up to 60° about any in-plane axis, any in-plane rotation, marker centre
//! anywhere in a 1280×720 or 1920×1080 image, distance 50-3000 mm, marker 10-100 mm (never
//! larger than the distance), its face at most 80° oblique to the viewing ray. Cameras in the
//! pixel and the sensor form, with and without lens distortion (then all corners inside the
//! image, where a lens model is valid, and every corner's ray recoverable from its pixel). `depth-newton` and `reprojection` must return the pose to 1e-6.

use nalgebra::{Rotation3, Unit, Vector3};
use proptest::prelude::*;
use qrpose::api::{
    estimate_corners,
    request::{
        CameraDto, CornerOrderDto, CornersRequest, DistortionDto, MarkerDto, MethodDto, SolverDto,
    },
    response::PoseResponse,
};
use qrpose::geometry::{
    camera::{Camera, PlumbBob},
    euler::angle_between,
    frames::MarkerToCamera,
    marker::{CornerOrder, Marker},
};

/// Rotation error allowed on exact input, degrees.
const MAX_ROTATION_ERROR_DEG: f64 = 1e-6;
/// Centre error allowed on exact input, per mm of distance (3 µm at 3 m).
const MAX_POSITION_ERROR_REL: f64 = 1e-6;
/// Poses whose printed face is more oblique than this to the viewing ray are not generated:
/// beyond 90° the camera would see the back of the marker (refused as mirrored).
const MAX_OBLIQUITY_DEG: f64 = 80.0;

#[derive(Debug, Clone)]
struct Scenario {
    image_px: (f64, f64),
    sensor_form: bool,
    distortion: Option<PlumbBob>,
    centre_px: (f64, f64),
    distance_mm: f64,
    size_mm: f64,
    tilt_deg: f64,
    tilt_axis_deg: f64,
    spin_deg: f64,
}

fn scenario() -> impl Strategy<Value = Scenario> {
    (
        prop_oneof![Just((1280.0, 720.0)), Just((1920.0, 1080.0))],
        any::<bool>(),
        prop::option::of((
            -0.3..0.1f64,
            -0.05..0.1f64,
            -1e-3..1e-3f64,
            -1e-3..1e-3f64,
            -0.02..0.02f64,
        )),
        (0.0..1.0f64, 0.0..1.0f64),
        50.0..3000.0f64,
        10.0..100.0f64,
        (0.0..60.0f64, 0.0..360.0f64, -180.0..180.0f64),
    )
        .prop_map(
            |(
                image_px,
                sensor_form,
                d,
                (fu, fv),
                distance_mm,
                size_mm,
                (tilt_deg, tilt_axis_deg, spin_deg),
            )| {
                Scenario {
                    image_px,
                    sensor_form,
                    distortion: d.map(|(k1, k2, p1, p2, k3)| PlumbBob { k1, k2, p1, p2, k3 }),
                    centre_px: (fu * (image_px.0 - 1.0), fv * (image_px.1 - 1.0)),
                    distance_mm,
                    size_mm: size_mm.min(0.8 * distance_mm),
                    tilt_deg,
                    tilt_axis_deg,
                    spin_deg,
                }
            },
        )
}

/// fx = fy = 1000 px·(width / 1280), i.e. a 65° horizontal field of view; in the sensor
/// form the same through f = 4 mm and the matching pitch.
fn camera_dto(s: &Scenario) -> CameraDto {
    let f_px = 1000.0 * s.image_px.0 / 1280.0;
    let (cx, cy) = ((s.image_px.0 - 1.0) / 2.0, (s.image_px.1 - 1.0) / 2.0);
    let distortion = s.distortion.map(|d| DistortionDto {
        k1: d.k1,
        k2: d.k2,
        p1: d.p1,
        p2: d.p2,
        k3: d.k3,
        ..DistortionDto::default()
    });
    if s.sensor_form {
        CameraDto {
            focal_length_mm: Some(4.0),
            pixel_size_um: Some(4000.0 / f_px),
            cx_px: Some(cx),
            cy_px: Some(cy),
            distortion,
            ..Default::default()
        }
    } else {
        CameraDto {
            fx_px: Some(f_px),
            fy_px: Some(f_px),
            cx_px: Some(cx),
            cy_px: Some(cy),
            distortion,
            ..Default::default()
        }
    }
}

fn truth(s: &Scenario, camera: &Camera, marker: &Marker) -> MarkerToCamera {
    let axis_angle = s.tilt_axis_deg.to_radians();
    let axis = Unit::new_normalize(Vector3::new(axis_angle.cos(), axis_angle.sin(), 0.0));
    let r = Rotation3::from_axis_angle(&axis, s.tilt_deg.to_radians())
        * Rotation3::from_axis_angle(&Vector3::z_axis(), s.spin_deg.to_radians());
    let ray = Vector3::new(
        (s.centre_px.0 - camera.cx()) / camera.fx(),
        (s.centre_px.1 - camera.cy()) / camera.fy(),
        1.0,
    );
    let centre = ray.normalize() * s.distance_mm;
    marker.pose_centred_at(r, centre)
}

fn solve(s: &Scenario, method: MethodDto) -> Result<(PoseResponse, MarkerToCamera), TestCaseError> {
    let camera_dto = camera_dto(s);
    let (camera, _) = camera_dto
        .to_camera(qrpose::api::request::CornersUnit::Px)
        .map_err(|p| TestCaseError::fail(p.detail))?;
    let marker = Marker::try_new(s.size_mm).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let pose = truth(s, &camera, &marker);
    let centre = pose.transform(&marker.centre()).0.coords;
    let normal = pose.rotation() * Vector3::z();
    let obliquity_deg = normal.angle(&centre).to_degrees();
    if obliquity_deg > MAX_OBLIQUITY_DEG {
        return Err(TestCaseError::reject(
            "the marker's face is turned away from the camera",
        ));
    }
    let paper: Vec<_> = marker
        .object_points()
        .iter()
        .map(|m| camera.project(&pose.transform(m)))
        .collect();
    let paper: Vec<_> = paper
        .into_iter()
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| TestCaseError::reject("behind"))?;
    let inside = |p: &qrpose::geometry::frames::PixelPoint| {
        (-0.5..s.image_px.0 - 0.5).contains(&p.u()) && (-0.5..s.image_px.1 - 0.5).contains(&p.v())
    };
    if s.distortion.is_some() && !paper.iter().all(inside) {
        // A lens model is only calibrated (and only monotonic) inside the image.
        return Err(TestCaseError::reject(
            "a distorted corner falls outside the image",
        ));
    }
    // Random coefficients can fold over inside the field of view; a corner beyond the fold
    // shares its pixel with a nearer ray, and no method can tell which one was meant.
    let round_trips = marker.object_points().iter().all(|m| {
        let ray = pose.transform(m).normalized();
        let back = camera
            .project(&pose.transform(m))
            .and_then(|px| camera.normalize(&px).ok());
        ray.zip(back)
            .is_some_and(|(a, b)| (a.0 - b.0).norm() < 1e-9)
    });
    if !round_trips {
        return Err(TestCaseError::reject(
            "a corner lies beyond the fold of the lens model",
        ));
    }
    let qr = CornerOrder::Qr.from_paper([paper[0], paper[1], paper[2], paper[3]]);
    let request = CornersRequest {
        corners_px: Some(qr.iter().map(|p| vec![p.u(), p.v()]).collect()),
        corners_mm: None,
        corner_order: CornerOrderDto::Qr,
        camera: camera_dto,
        marker: Some(MarkerDto { size_mm: s.size_mm }),
        payload: None,
        solver: SolverDto {
            method,
            ..SolverDto::default()
        },
        prior: None,
        flange_pose: None,
        min_grasp_probability: None,
    };
    let response = estimate_corners(&request, None)
        .map_err(|p| TestCaseError::fail(format!("{}: {}", p.title, p.detail)))?;
    Ok((response, pose))
}

fn check(s: &Scenario, method: MethodDto) -> Result<(), TestCaseError> {
    let (r, pose) = solve(s, method)?;
    let m = r.rotation.matrix;
    let estimated = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_fn(|i, j| m[i][j]));
    let rotation_error_deg = angle_between(&estimated, &pose.rotation()).to_degrees();
    let marker = Marker::try_new(s.size_mm).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let centre = pose.transform(&marker.centre()).0.coords;
    let p = r.position_mm;
    let position_error_mm = (Vector3::new(p.x, p.y, p.z) - centre).norm();
    prop_assert!(
        r.diagnostics.converged,
        "{method:?} did not converge: {:?}",
        r.diagnostics
    );
    prop_assert!(
        rotation_error_deg <= MAX_ROTATION_ERROR_DEG,
        "{method:?}: rotation error {rotation_error_deg:e} deg"
    );
    prop_assert!(
        position_error_mm <= MAX_POSITION_ERROR_REL * s.distance_mm,
        "{method:?}: position error {position_error_mm:e} mm at {} mm",
        s.distance_mm
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn reprojection_recovers_exact_projections(s in scenario()) {
        check(&s, MethodDto::Reprojection)?;
    }

    #[test]
    fn depth_newton_recovers_exact_projections(s in scenario()) {
        check(&s, MethodDto::DepthNewton)?;
    }
}
