//! Rendered video (`render::sequence`): each frame's truth against the codes projected
//! independently at the interpolated camera pose, capture times, the path's keyframes and
//! still segments, shake and determinism, codes partly out of view, facing away or behind
//! the camera, motion blur, the spec's JSON and refusals, and the built-in videos (codes in
//! view in most frames, read by the detector where the truth says they are).

use nalgebra::Vector3;
use qrpose_core::geometry::{euler::EulerXyz, frames::MarkerToCamera, marker::Marker};
use qrpose_sim::render::EcLevel;
use qrpose_sim::render::sequence::{
    BUILTIN_SEQUENCES, CameraSpec, EulerDeg, Interpolation, KeyframeSpec, Sequence,
    SequenceEffects, SequenceError, SequenceSpec, Shake, TrajectorySpec, WallSpec, WorldCode,
    builtin_sequence,
};

fn code(payload: &str, size_mm: f64, position_mm: [f64; 3], euler: [f64; 3]) -> WorldCode {
    WorldCode {
        payload: payload.to_owned(),
        ec_level: EcLevel::M,
        size_mm,
        position_mm,
        rotation_euler_xyz_deg: EulerDeg {
            alpha: euler[0],
            beta: euler[1],
            gamma: euler[2],
        },
    }
}

fn keyframe(time_ms: f64, position_mm: [f64; 3], look_at_mm: [f64; 3]) -> KeyframeSpec {
    KeyframeSpec {
        time_ms,
        position_mm,
        look_at_mm: Some(look_at_mm),
        roll_deg: 0.0,
        rotation_euler_xyz_deg: None,
    }
}

/// A small video: 320 × 240, three codes on a wall 600 mm ahead, a camera moving right and
/// closer in 1 s at 30 fps, turning as it goes.
fn small_spec() -> SequenceSpec {
    SequenceSpec {
        name: "small".into(),
        width_px: 320,
        height_px: 240,
        camera: CameraSpec {
            fx_px: 300.0,
            fy_px: 310.0,
            cx_px: Some(158.0),
            cy_px: None,
            distortion: None,
        },
        fps: 30.0,
        frames: None,
        duration_ms: None,
        codes: vec![
            code("LEFT", 60.0, [-150.0, 0.0, 600.0], [0.0, 15.0, 5.0]),
            code("MIDDLE", 80.0, [0.0, 30.0, 620.0], [-10.0, 0.0, -20.0]),
            code("RIGHT", 60.0, [160.0, -20.0, 600.0], [5.0, -20.0, 0.0]),
        ],
        trajectory: TrajectorySpec {
            keyframes: vec![
                keyframe(0.0, [-100.0, 0.0, 0.0], [-60.0, 0.0, 600.0]),
                keyframe(500.0, [0.0, 20.0, 100.0], [0.0, 10.0, 600.0]),
                keyframe(1000.0, [80.0, 0.0, 250.0], [120.0, 0.0, 600.0]),
            ],
            interpolation: Interpolation::Smooth,
            shake: Shake::default(),
        },
        wall: Some(WallSpec {
            position_mm: [0.0, 0.0, 650.0],
            rotation_euler_xyz_deg: EulerDeg::default(),
            size_mm: [1500.0, 1000.0],
            level: 150.0,
            shapes: 20,
        }),
        effects: SequenceEffects {
            supersample: 2,
            noise: 1.5,
            blur_px: 0.5,
            ..SequenceEffects::default()
        },
        seed: 7,
    }
}

/// A code's corners (qr order) projected by the sequence's camera at `pose`, computed here
/// from the spec alone.
fn projected_corners(seq: &Sequence, c: &WorldCode, frame: u32) -> Option<[[f64; 2]; 4]> {
    let marker = Marker::try_new(c.size_mm).expect("size");
    let e = c.rotation_euler_xyz_deg;
    let r = EulerXyz::from_degrees(e.alpha, e.beta, e.gamma).to_rotation();
    let to_world = marker.pose_centred_at(r, Vector3::from(c.position_mm));
    let camera_pose = seq.camera_pose(frame);
    let in_camera = MarkerToCamera(camera_pose.0.inverse() * to_world.0);
    let [p1, p2, p3, p4] = marker.object_points();
    let mut out = [[0.0; 2]; 4];
    for (slot, p) in out.iter_mut().zip([p3, p2, p1, p4]) {
        let px = seq.camera().project(&in_camera.transform(&p))?;
        *slot = [px.u(), px.v()];
    }
    Some(out)
}

#[test]
fn each_frame_holds_the_codes_projected_at_the_path_pose_and_its_capture_time() {
    let seq = Sequence::new(small_spec()).expect("valid");
    assert_eq!(seq.frame_count(), 31, "0 to 1000 ms at 30 fps");
    let inside = |p: &[f64; 2]| p[0] > -0.5 && p[0] < 319.5 && p[1] > -0.5 && p[1] < 239.5;
    let mut seen_partial = false;
    for k in 0..seq.frame_count() {
        let truth = seq.truth(k).expect("frame");
        assert_eq!(truth.index, k);
        assert!((truth.capture_time_ms - f64::from(k) * 1000.0 / 30.0).abs() < 1e-9);
        // Without shake the camera is the path's pose at the capture time.
        let on_path = seq.trajectory().pose_at(truth.capture_time_ms);
        assert!((on_path.centre_mm() - Vector3::from(truth.camera.position_mm)).norm() < 1e-9);
        for (i, c) in seq.spec().codes.iter().enumerate() {
            let corners = projected_corners(&seq, c, k).expect("in front");
            let listed = truth.codes.iter().find(|t| t.code_index == i);
            if corners.iter().any(inside) {
                let t = listed.unwrap_or_else(|| panic!("frame {k}: code {i} is in view"));
                assert_eq!(t.payload, c.payload);
                assert_eq!(t.size_mm, c.size_mm);
                for (a, b) in corners.iter().zip(&t.truth.corners_px) {
                    assert!(
                        (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-9,
                        "frame {k} code {i}"
                    );
                }
                assert_eq!(t.fully_in_view, corners.iter().all(inside));
                seen_partial |= !t.fully_in_view;
                let side = (corners[0][0] - corners[1][0]).hypot(corners[0][1] - corners[1][1]);
                assert!(t.side_px <= side + 1e-9 && t.side_px > 0.5 * side);
            } else if let Some(t) = listed {
                // No corner inside, yet listed: the symbol must still reach into the image.
                let (lo_u, hi_u) = (
                    corners.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min),
                    corners
                        .iter()
                        .map(|p| p[0])
                        .fold(f64::NEG_INFINITY, f64::max),
                );
                let (lo_v, hi_v) = (
                    corners.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min),
                    corners
                        .iter()
                        .map(|p| p[1])
                        .fold(f64::NEG_INFINITY, f64::max),
                );
                assert!(hi_u > -0.5 && lo_u < 319.5 && hi_v > -0.5 && lo_v < 239.5);
                assert!(!t.fully_in_view, "frame {k}: code {i}");
            }
        }
    }
    assert!(seen_partial, "the path cuts a code off at the image border");
}

#[test]
fn the_path_passes_through_its_keyframes_and_rests_on_a_still_segment() {
    let mut spec = small_spec();
    let k = &spec.trajectory.keyframes;
    spec.trajectory.keyframes = vec![
        k[0].clone(),
        k[1].clone(),
        KeyframeSpec {
            time_ms: 800.0,
            ..k[1].clone()
        },
        KeyframeSpec {
            time_ms: 1300.0,
            ..k[2].clone()
        },
    ];
    let seq = Sequence::new(spec.clone()).expect("valid");
    let path = seq.trajectory();
    for kf in &spec.trajectory.keyframes {
        let pose = path.pose_at(kf.time_ms);
        assert!((pose.centre_mm() - Vector3::from(kf.position_mm)).norm() < 1e-9);
        let axis = pose.rotation() * Vector3::z();
        let to_target =
            (Vector3::from(kf.look_at_mm.expect("look at")) - pose.centre_mm()).normalize();
        assert!((axis - to_target).norm() < 1e-9, "looks at its target");
        let down = pose.rotation() * Vector3::y();
        assert!(down.y > 0.0 && (pose.rotation() * Vector3::x()).y.abs() < 1e-12);
    }
    // Still between 500 and 800 ms, also for frames at those times.
    let rest = path.pose_at(500.0);
    for t in [520.0, 650.0, 799.0] {
        let p = path.pose_at(t);
        assert!((p.centre_mm() - rest.centre_mm()).norm() < 1e-9, "{t} ms");
        assert!(p.0.rotation.angle_to(&rest.0.rotation) < 1e-9);
    }
    // Through a keyframe between two moves, the velocity is continuous (smooth).
    let moving = Sequence::new(small_spec()).expect("valid");
    let at = |t: f64| moving.trajectory().pose_at(t).centre_mm();
    let (before, after) = ((at(500.0) - at(499.9)) / 0.1, (at(500.1) - at(500.0)) / 0.1);
    assert!(after.norm() > 0.1 && (before - after).norm() < 1e-3 * after.norm());
    // Before the start and after the end, the camera waits at the first and last keyframe.
    assert_eq!(path.pose_at(-50.0), path.pose_at(0.0));
    assert_eq!(path.pose_at(5000.0), path.pose_at(1300.0));
    // Linear: halfway in time, halfway in space.
    spec.trajectory.interpolation = Interpolation::Linear;
    let linear = Sequence::new(spec).expect("valid");
    let mid = linear.trajectory().pose_at(250.0).centre_mm();
    assert!((mid - Vector3::new(-50.0, 10.0, 50.0)).norm() < 1e-9);
}

#[test]
fn shake_is_about_its_sigma_and_every_frame_renders_alone_to_the_same_pixels() {
    let mut spec = small_spec();
    spec.frames = Some(300);
    spec.trajectory.shake = Shake {
        position_mm: 1.0,
        rotation_deg: 0.2,
    };
    let seq = Sequence::new(spec.clone()).expect("valid");
    let (mut sum_t, mut sum_r) = (0.0, 0.0);
    for k in 0..300 {
        let shaken = seq.camera_pose(k);
        let on_path = seq.trajectory().pose_at(seq.capture_time_ms(k));
        sum_t += (shaken.centre_mm() - on_path.centre_mm()).norm_squared();
        sum_r += shaken.0.rotation.angle_to(&on_path.0.rotation).powi(2);
    }
    // E|δt|² = 3σ², E|δθ|² = 3σ².
    let rms_t = (sum_t / 300.0 / 3.0).sqrt();
    let rms_r = (sum_r / 300.0 / 3.0).sqrt().to_degrees();
    assert!((rms_t - 1.0).abs() < 0.15, "{rms_t} mm");
    assert!((rms_r - 0.2).abs() < 0.03, "{rms_r}°");
    let again = Sequence::new(spec).expect("valid");
    let (a, b) = (
        seq.render_frame(12).expect("a"),
        seq.render_frame(3).expect("b"),
    );
    assert_eq!(again.render_frame(12).expect("a again"), a);
    assert_eq!(again.render_frames(2..4).expect("batch")[1], b);
    assert_ne!(a.image, b.image);
}

#[test]
fn codes_facing_away_or_behind_the_camera_are_neither_drawn_nor_listed() {
    let mut spec = small_spec();
    spec.trajectory.keyframes.truncate(1);
    spec.frames = Some(1);
    let base = Sequence::new(spec.clone()).expect("valid");
    // Facing away (turned 180° about y) in the middle of the picture, and behind the camera.
    spec.codes
        .push(code("BACK", 80.0, [-60.0, 60.0, 450.0], [0.0, 180.0, 0.0]));
    spec.codes
        .push(code("BEHIND", 80.0, [0.0, 0.0, -300.0], [0.0, 0.0, 0.0]));
    let more = Sequence::new(spec).expect("valid");
    let (a, b) = (
        base.render_frame(0).expect("a"),
        more.render_frame(0).expect("b"),
    );
    assert_eq!(a.image, b.image);
    assert_eq!(a.truth, b.truth);
}

#[test]
fn motion_blur_smears_the_picture_but_not_the_truth() {
    let mut spec = small_spec();
    let sharp = Sequence::new(spec.clone()).expect("valid");
    spec.effects.shutter_ms = 20.0;
    spec.effects.motion_samples = 4;
    let blurred = Sequence::new(spec).expect("valid");
    let (a, b) = (
        sharp.render_frame(15).expect("a"),
        blurred.render_frame(15).expect("b"),
    );
    assert_eq!(a.truth, b.truth);
    let differing = a
        .image
        .pixels()
        .iter()
        .zip(b.image.pixels())
        .filter(|(x, y)| x.abs_diff(**y) > 20)
        .count();
    assert!(
        differing > 200,
        "{differing} pixels changed by more than 20 levels"
    );
}

#[test]
fn the_spec_loads_from_json_and_refusals_name_the_field() {
    for name in BUILTIN_SEQUENCES {
        let spec = builtin_sequence(name).expect("built-in");
        let json = serde_json::to_string(&spec).expect("serialises");
        let back: SequenceSpec = serde_json::from_str(&json).expect("loads");
        assert_eq!(back, spec, "{name}");
    }
    assert!(builtin_sequence("nope").is_none());
    let minimal: SequenceSpec = serde_json::from_str(
        r#"{"codes": [{"payload": "A", "size_mm": 50, "position_mm": [0, 0, 500]}],
            "trajectory": {"keyframes": [{"time_ms": 0, "position_mm": [0, 0, 0]},
                                         {"time_ms": 2000, "position_mm": [0, 0, 100]}]}}"#,
    )
    .expect("defaults fill the rest");
    let seq = Sequence::new(minimal).expect("valid");
    assert_eq!(seq.frame_count(), 61);
    assert_eq!((seq.camera().fx(), seq.camera().cx()), (1000.0, 639.5));
    let field_of = |edit: &dyn Fn(&mut SequenceSpec)| {
        let mut spec = small_spec();
        edit(&mut spec);
        match Sequence::new(spec) {
            Err(SequenceError::Spec { field, .. }) => field,
            other => panic!("refused with a field, got {other:?}"),
        }
    };
    let at = |t: f64| move |s: &mut SequenceSpec| s.trajectory.keyframes[1].time_ms = t;
    assert_eq!(field_of(&at(0.0)), "/trajectory/keyframes/1/time_ms");
    assert_eq!(field_of(&|s| s.codes[2].size_mm = 0.0), "/codes/2/size_mm");
    let lens = |s: &mut SequenceSpec| {
        s.camera.distortion = Some(qrpose_sim::render::sequence::DistortionSpec {
            model: "fisheye".into(),
            coefficients: vec![0.0; 4],
        });
    };
    assert_eq!(field_of(&lens), "/camera/distortion/model");
    assert_eq!(
        field_of(&|s| s.effects.shutter_ms = 50.0),
        "/effects/shutter_ms"
    );
    assert_eq!(field_of(&|s| s.effects.noise = -1.0), "/effects/noise");
    let up =
        |s: &mut SequenceSpec| s.trajectory.keyframes[0].look_at_mm = Some([-100.0, 500.0, 0.0]);
    assert_eq!(field_of(&up), "/trajectory/keyframes/0/look_at_mm");
    assert!(matches!(
        Sequence::new(small_spec()).expect("valid").truth(31),
        Err(SequenceError::FrameIndex {
            index: 31,
            frames: 31
        })
    ));
}
