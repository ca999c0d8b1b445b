//! The planar ambiguity as reported: the alternative pose, its probability, and the flag.

use nalgebra::Vector3;
use qrpose::estimate::{
    DISTINCT_ROTATION_DEG, ReprojectionParams, Solver, ValidSolver, Warning, estimate_pose,
};
use qrpose::geometry::{
    camera::Camera,
    euler::{EulerXyz, angle_between},
    frames::MarkerToCamera,
    marker::{CornerOrder, Marker},
    quad::ImageQuad,
};
use qrpose_sim::dataset::{DatasetSpec, generate};

fn exact_quad(camera: &Camera, marker: &Marker, pose: &MarkerToCamera) -> ImageQuad {
    let corners = marker
        .object_points()
        .map(|m| camera.project(&pose.transform(&m)).expect("in front"));
    ImageQuad::try_new(corners, CornerOrder::Paper).expect("valid quad")
}

/// The pose estimated from the exact corners of `pose`.
fn estimate_exact(pose: &MarkerToCamera, params: &ValidSolver) -> qrpose::estimate::PoseEstimate {
    let (camera, marker) = setup();
    estimate_pose(
        &exact_quad(&camera, &marker, pose),
        &camera,
        &marker,
        params,
    )
    .expect("pose")
}

fn setup() -> (Camera, Marker) {
    (
        Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("camera"),
        Marker::try_new(50.0).expect("marker"),
    )
}

#[test]
fn a_clearly_tilted_marker_is_not_ambiguous() {
    let pose = MarkerToCamera::new(
        EulerXyz::from_degrees(35.0, 10.0, 20.0).to_rotation(),
        Vector3::new(0.0, 0.0, 400.0),
    );
    let e = estimate_exact(&pose, &ValidSolver::default());
    let a = e
        .diagnostics
        .ambiguity
        .expect("reprojection reports the ambiguity");
    assert!(
        !a.ambiguous && a.alternative_probability.is_some_and(|p| p < 1e-6),
        "{a:?}"
    );
    assert!(
        a.ratio < 1e-6 && a.rotation_difference_rad.to_degrees() > 10.0,
        "{a:?}"
    );
    assert!(!e.diagnostics.warnings.contains(&Warning::PoseAmbiguous));
}

#[test]
fn a_small_near_frontal_marker_is_ambiguous_at_half_a_pixel_of_noise() {
    // 50 mm at 1.5 m is 33 px wide: tilting it 4° one way or the other moves its corners by
    // far less than 0.5 px, so the two poses cannot be told apart.
    let pose = MarkerToCamera::new(
        EulerXyz::from_degrees(4.0, 0.0, 30.0).to_rotation(),
        Vector3::new(20.0, 10.0, 1500.0),
    );
    let e = estimate_exact(&pose, &ValidSolver::default());
    let a = e.diagnostics.ambiguity.expect("ambiguity");
    assert!(
        a.ambiguous && a.alternative_probability.is_some_and(|p| p > 0.3),
        "{a:?}"
    );
    assert!(e.diagnostics.warnings.contains(&Warning::PoseAmbiguous));
    // The mirror pose really is the same square tilted the other way about the view ray.
    assert!(angle_between(&a.alternative.rotation(), &pose.rotation()).to_degrees() > 4.0);
    // With a detector ten times more precise the same view is no longer ambiguous.
    let precise = Solver::Reprojection(ReprojectionParams {
        corner_sigma_px: 0.01,
        ..ReprojectionParams::default()
    })
    .validate()
    .expect("a valid corner noise");
    let e = estimate_exact(&pose, &precise);
    assert!(!e.diagnostics.ambiguity.expect("ambiguity").ambiguous);
}

#[test]
fn poses_left_unflagged_are_rarely_the_wrong_pick() {
    // Seeded: 1000 noisy views (σ = 0.5 px, 50 mm at 200-1500 mm, tilt ≤ 60°).
    let spec = DatasetSpec {
        cases: 1000,
        seed: 99,
        ..DatasetSpec::default()
    };
    let (camera, marker) = (
        spec.camera().expect("camera"),
        spec.marker().expect("marker"),
    );
    let (mut unflagged, mut unflagged_wrong, mut wrong) = (0, 0, 0);
    for c in generate(&spec).expect("dataset") {
        let quad = ImageQuad::try_new(c.noisy_px, CornerOrder::Qr).expect("valid quad");
        let e = estimate_pose(&quad, &camera, &marker, &ValidSolver::default()).expect("pose");
        let a = e.diagnostics.ambiguity.expect("ambiguity");
        // Candidates within DISTINCT_ROTATION_DEG are one solution: either pick costs less.
        let distinct = a.rotation_difference_rad.to_degrees() > DISTINCT_ROTATION_DEG;
        let is_wrong = distinct
            && angle_between(&e.pose.rotation(), &c.truth.rotation())
                > angle_between(&a.alternative.rotation(), &c.truth.rotation());
        wrong += usize::from(is_wrong);
        if !a.ambiguous {
            unflagged += 1;
            unflagged_wrong += usize::from(is_wrong);
        }
    }
    assert!(
        wrong > 50,
        "the dataset must contain wrong picks to catch ({wrong})"
    );
    assert!(
        unflagged > 300,
        "most poses should be usable ({unflagged} of 1000)"
    );
    assert!(
        unflagged_wrong * 100 <= unflagged,
        "{unflagged_wrong} wrong among {unflagged} unflagged poses"
    );
}
