//! Multi-code frames (`render_scene`, `random_scene`): every code's ground truth against its
//! pose, drawing order, the overlap helpers, the random generator's determinism and
//! placement, and a detector reading the codes of a rendered frame.

use nalgebra::Vector3;
use qrpose_core::geometry::{camera::Camera, euler::EulerXyz, marker::Marker};
use qrpose_detect::decode::{DecodeLimits, decode_gray};
use qrpose_detect::{Backend, DetectorChoice, detect_codes};
use qrpose_sim::render::{
    CodePlacement, DEFAULT_QUIET_ZONE_MODULES, EcLevel, Effects, Encoding, MultiScene, RenderError,
    SceneRanges, code_outline_px, codes_overlap, quad_separation_px, quads_overlap, random_scene,
    render_scene,
};

fn code(payload: &str, size_mm: f64, centre_mm: [f64; 3], euler_deg: [f64; 3]) -> CodePlacement {
    let marker = Marker::try_new(size_mm).expect("valid size");
    let r = EulerXyz::from_degrees(euler_deg[0], euler_deg[1], euler_deg[2]).to_rotation();
    CodePlacement {
        payload: payload.as_bytes().to_vec(),
        ec_level: EcLevel::M,
        marker,
        pose: marker.pose_centred_at(r, Vector3::new(centre_mm[0], centre_mm[1], centre_mm[2])),
    }
}

/// Three 50 mm codes side by side 450 mm away, each turned differently, 1280 × 720.
fn three_codes() -> MultiScene {
    MultiScene {
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("valid camera"),
        width_px: 1280,
        height_px: 720,
        codes: vec![
            code(
                "LEFT-CODE",
                50.0,
                [-200.0, -40.0, 450.0],
                [10.0, 20.0, 15.0],
            ),
            code("MIDDLE-CODE", 50.0, [0.0, 30.0, 450.0], [-15.0, 0.0, -30.0]),
            code(
                "RIGHT-CODE",
                50.0,
                [200.0, -20.0, 450.0],
                [0.0, -20.0, 100.0],
            ),
        ],
    }
}

fn effects(seed: u64) -> Effects {
    Effects {
        supersample: 3,
        blur_px: 0.7,
        noise: 1.5,
        lighting: 0.2,
        clutter: 8,
        encoding: Encoding::Jpeg(90),
        seed,
        ..Effects::default()
    }
}

fn max_corner_error_px(found: &[[f64; 2]; 4], truth: &[[f64; 2]; 4]) -> f64 {
    found
        .iter()
        .zip(truth)
        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
        .fold(0.0, f64::max)
}

/// Whether (u, v) lies inside the convex quad `q` shrunk by `margin` px (either winding).
fn inside(q: &[[f64; 2]; 4], u: f64, v: f64, margin: f64) -> bool {
    let sides: Vec<f64> = (0..4)
        .map(|i| {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
            (ex * (v - a[1]) - ey * (u - a[0])) / ex.hypot(ey)
        })
        .collect();
    sides.iter().all(|&d| d > margin) || sides.iter().all(|&d| d < -margin)
}

#[test]
// The finder centres are in the image, rounded before the cast.
#[allow(clippy::cast_possible_truncation)]
fn three_codes_render_each_with_the_truth_of_its_own_pose() {
    let scene = three_codes();
    let r = render_scene(&scene, &effects(1)).expect("renders");
    assert_eq!((r.image.width(), r.image.height()), (1280, 720));
    assert_eq!(r.truth.len(), 3);
    assert!(
        scene
            .overlapping_pairs(DEFAULT_QUIET_ZONE_MODULES)
            .expect("in front")
            .is_empty()
    );
    let qr_of_paper = [2, 1, 0, 3];
    for (c, truth) in scene.codes.iter().zip(&r.truth) {
        for (paper, corner) in c.marker.object_points().iter().enumerate() {
            let p = scene
                .camera
                .project(&c.pose.transform(corner))
                .expect("in front");
            let q = truth.corners_px[qr_of_paper[paper]];
            assert!((p.u() - q[0]).abs() < 1e-9 && (p.v() - q[1]).abs() < 1e-9);
        }
        let centre = c.pose.transform(&c.marker.centre()).0;
        for k in 0..3 {
            assert!((truth.position_mm[k] - centre[k]).abs() < 1e-9);
        }
        // The top-left finder's centre module is dark in the image.
        let f = &truth.finder_corners_px[0..4];
        let (u, v) = (
            f.iter().map(|p| p[0]).sum::<f64>() / 4.0,
            f.iter().map(|p| p[1]).sum::<f64>() / 4.0,
        );
        let grey = r.image.get(u.round() as usize, v.round() as usize);
        assert!(grey < 90, "finder centre at ({u:.1}, {v:.1}) is {grey}");
    }
    assert_eq!(r.truth, scene.ground_truth().expect("in view"));
}

#[test]
fn a_later_code_is_drawn_over_an_earlier_one() {
    let base = three_codes();
    let under = code("UNDER", 80.0, [-20.0, 0.0, 450.0], [0.0, 0.0, 0.0]);
    let over = code("OVER", 50.0, [20.0, 10.0, 430.0], [0.0, 10.0, 20.0]);
    let both = MultiScene {
        codes: vec![under.clone(), over.clone()],
        ..base.clone()
    };
    assert_eq!(both.overlapping_pairs(4.0).expect("in front"), vec![(0, 1)]);
    assert!(codes_overlap(&both.camera, &under, &over, 0.0).expect("in front"));
    let clean = Effects {
        lighting: 0.3,
        clutter: 20,
        seed: 3,
        ..Effects::default()
    };
    let r = render_scene(&both, &clean).expect("renders");
    let alone = render_scene(
        &MultiScene {
            codes: vec![over],
            ..base
        },
        &clean,
    )
    .expect("renders");
    assert_eq!(
        r.truth[1], alone.truth[0],
        "each code's truth is where it was placed"
    );
    // Inside the top code's outline the frame is the top code alone.
    let outline = code_outline_px(&both.camera, &both.codes[1], 4.0).expect("in front");
    let mut checked = 0;
    for y in 0..720 {
        for x in 0..1280 {
            if inside(&outline, x as f64, y as f64, 1.0) {
                assert_eq!(r.image.get(x, y), alone.image.get(x, y), "pixel ({x}, {y})");
                checked += 1;
            }
        }
    }
    assert!(checked > 10_000, "{checked} pixels checked");
}

#[test]
fn quads_overlap_by_their_separation() {
    let square = |x: f64, y: f64, s: f64| [[x, y], [x + s, y], [x + s, y + s], [x, y + s]];
    let a = square(0.0, 0.0, 10.0);
    assert!((quad_separation_px(&a, &square(13.0, 2.0, 5.0)) - 3.0).abs() < 1e-12);
    assert!(!quads_overlap(&a, &square(13.0, 2.0, 5.0)));
    assert!(
        quads_overlap(&a, &square(10.0, 0.0, 5.0)),
        "touching counts"
    );
    assert!(quads_overlap(&a, &square(2.0, 2.0, 3.0)), "contained");
    // A diamond whose bounding box meets the square's but which stays apart from it.
    let diamond = [[16.0, 10.0], [21.0, 15.0], [16.0, 20.0], [11.0, 15.0]];
    assert!(!quads_overlap(&a, &diamond));
    let reversed = [diamond[3], diamond[2], diamond[1], diamond[0]];
    assert!(!quads_overlap(&reversed, &a), "either winding");
}

#[test]
fn a_code_out_of_view_is_named_by_its_index() {
    let mut scene = three_codes();
    scene.codes[2] = code("GONE", 50.0, [900.0, 0.0, 450.0], [0.0, 0.0, 0.0]);
    match render_scene(&scene, &Effects::default()) {
        Err(RenderError::Code { index: 2, error }) => assert_eq!(*error, RenderError::OutOfView),
        other => panic!("{other:?}"),
    }
}

#[test]
fn random_scenes_are_deterministic_in_range_and_never_overlap() {
    let ranges = SceneRanges::default();
    let mut counts = std::collections::BTreeSet::new();
    for seed in 0..40 {
        let s = random_scene(seed, &ranges).expect("places");
        assert_eq!(
            random_scene(seed, &ranges).expect("places"),
            s,
            "seed {seed}"
        );
        assert_eq!((s.width_px, s.height_px), (1280, 720));
        assert!((950.0..=1050.0).contains(&s.camera.fx()) && s.camera.fx() == s.camera.fy());
        assert!((2..=6).contains(&s.codes.len()), "{} codes", s.codes.len());
        counts.insert(s.codes.len());
        assert!(
            s.overlapping_pairs(DEFAULT_QUIET_ZONE_MODULES)
                .expect("in front")
                .is_empty()
        );
        for c in &s.codes {
            assert!((30.0..=120.0).contains(&c.marker.size_mm()));
            let centre = c.pose.transform(&c.marker.centre()).0.coords;
            assert!((300.0 - 1e-9..=2000.0 + 1e-9).contains(&centre.norm()));
            let normal = c.pose.rotation() * Vector3::z();
            let tilt = normal.angle(&centre).to_degrees();
            assert!(tilt <= 35.0 + 1e-9, "tilt {tilt}");
            for p in code_outline_px(&s.camera, c, DEFAULT_QUIET_ZONE_MODULES).expect("in front") {
                assert!(
                    p[0] > 0.0 && p[1] > 0.0 && p[0] < 1279.0 && p[1] < 719.0,
                    "{p:?}"
                );
            }
        }
    }
    assert!(counts.len() >= 3, "code counts drawn: {counts:?}");
    assert_ne!(
        random_scene(1, &ranges).expect("places"),
        random_scene(2, &ranges).expect("places")
    );
}

#[test]
fn random_scene_refuses_bad_ranges_and_impossible_placements() {
    let bad = SceneRanges {
        size_mm: [120.0, 30.0],
        ..SceneRanges::default()
    };
    assert_eq!(
        random_scene(0, &bad),
        Err(RenderError::Range {
            name: "size_mm",
            value: 120.0
        })
    );
    let crowded = SceneRanges {
        codes: [40, 40],
        size_mm: [120.0, 120.0],
        distance_mm: [300.0, 300.0],
        attempts: 5,
        ..SceneRanges::default()
    };
    assert_eq!(
        random_scene(0, &crowded),
        Err(RenderError::Placement { codes: 40 })
    );
}

#[test]
fn a_random_scene_renders_with_one_truth_per_code() {
    let s = random_scene(7, &SceneRanges::default()).expect("places");
    let r = render_scene(&s, &effects(7)).expect("renders");
    assert_eq!(r.truth.len(), s.codes.len());
    assert_eq!(r.truth, s.ground_truth().expect("in view"));
}

#[test]
fn rxing_reads_the_codes_of_a_rendered_three_code_frame() {
    let scene = three_codes();
    let r = render_scene(&scene, &effects(5)).expect("renders");
    let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("decodes the JPEG");
    let codes = detect_codes(&image, DetectorChoice::Only(Backend::Rxing)).expect("rxing");
    let mut read = 0;
    for (placed, truth) in scene.codes.iter().zip(&r.truth) {
        let Some(found) = codes
            .iter()
            .find(|c| c.candidate.payload.as_deref() == Some(placed.payload.as_slice()))
        else {
            continue;
        };
        read += 1;
        let corners = found.corners_px().map(|p| [p.u(), p.v()]);
        let err = max_corner_error_px(&corners, &truth.corners_px);
        assert!(err < 1.0, "corner error {err} px");
    }
    assert!(read >= 2, "read {read} of 3 codes");
}
