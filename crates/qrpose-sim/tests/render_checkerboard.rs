//! Checkerboards (`render_checkerboard`): the truth against the pose through a distorting
//! lens, the squares' colours and one edge's coverage against the geometry, the same
//! background, lighting and noise as a code rendered with the same effects and seed, and
//! the boards refused.

use nalgebra::{Rotation3, Vector3};
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose_core::geometry::euler::EulerXyz;
use qrpose_core::geometry::frames::{MarkerPoint, MarkerToCamera};
use qrpose_core::geometry::marker::Marker;
use qrpose_sim::render::{
    BoardScene, Checkerboard, EcLevel, Effects, Encoding, RenderError, Scene, render,
    render_checkerboard,
};

fn barrel_camera() -> Camera {
    let lens = Distortion::from_coefficients(
        DistortionModel::PlumbBob,
        &[-0.25, 0.08, 0.001, -0.0005, 0.0],
    )
    .expect("valid lens");
    Camera::from_pixels(1000.0, 1005.0, 652.0, 349.0)
        .expect("valid camera")
        .with_distortion(lens)
}

fn board(squares: u32) -> Checkerboard {
    Checkerboard {
        squares,
        size_mm: 120.0,
        border_mm: 15.0,
    }
}

fn tilted_scene() -> BoardScene {
    let marker = Marker::try_new(120.0).expect("valid size");
    BoardScene {
        board: board(10),
        camera: barrel_camera(),
        width_px: 1280,
        height_px: 720,
        pose: marker.pose_centred_at(
            EulerXyz::from_degrees(25.0, -20.0, 15.0).to_rotation(),
            Vector3::new(150.0, -60.0, 450.0),
        ),
    }
}

#[test]
fn the_truth_is_the_pose_through_the_lens() {
    let scene = tilted_scene();
    let r = render_checkerboard(&scene, &Effects::default()).expect("renders");
    let t = &r.truth;
    assert_eq!(t.inner_corners_px.len(), 81);
    assert_eq!(t.inner_corners_mm.len(), 81);
    // Board (x right, y down from the top-left corner) to marker frame: (x − l, y).
    let project = |x: f64, y: f64| {
        let p = MarkerPoint(nalgebra::Point3::new(x - 120.0, y, 0.0));
        let px = scene
            .camera
            .project(&scene.pose.transform(&p))
            .expect("in front");
        [px.u(), px.v()]
    };
    for (px, mm) in t.inner_corners_px.iter().zip(&t.inner_corners_mm) {
        let q = project(mm[0], mm[1]);
        assert!((px[0] - q[0]).abs() < 1e-9 && (px[1] - q[1]).abs() < 1e-9);
    }
    // Row by row from the top-left: index 10 is one square right of and two below it.
    assert_eq!(t.inner_corners_mm[10], [24.0, 24.0]);
    assert_eq!(t.inner_corners_mm[1], [24.0, 12.0]);
    let corners = [(0.0, 0.0), (120.0, 0.0), (120.0, 120.0), (0.0, 120.0)];
    for (got, (x, y)) in t.corners_px.iter().zip(corners) {
        assert_eq!(*got, project(x, y));
    }
    let centre = scene
        .pose
        .transform(&MarkerPoint(nalgebra::Point3::new(-60.0, 60.0, 0.0)));
    assert!((Vector3::from(t.position_mm) - centre.0.coords).norm() < 1e-9);
}

#[test]
fn squares_alternate_and_an_edge_covers_its_pixel_as_the_geometry_says() {
    // Fronto-parallel, no lens: 10 squares of 10 mm at 1 m are 10 px each; the board's left
    // edge at u = 100.25, so pixel 100 (covering [99.5, 100.5]) is 25 % board.
    let camera = Camera::from_pixels(1000.0, 1000.0, 0.0, 0.0).expect("valid camera");
    let left_u = 100.25;
    let top_v = 50.0;
    let scene = BoardScene {
        board: Checkerboard {
            squares: 10,
            size_mm: 100.0,
            border_mm: 20.0,
        },
        camera,
        width_px: 260,
        height_px: 200,
        // The marker frame's origin is the top-right corner.
        pose: MarkerToCamera::new(
            Rotation3::identity(),
            Vector3::new(left_u + 100.0, top_v, 1000.0),
        ),
    };
    let effects = Effects {
        supersample: 16,
        ..Effects::default()
    };
    let r = render_checkerboard(&scene, &effects).expect("renders");
    let (dark, light) = (effects.dark_level, effects.light_level);
    // Square (col, row) is centred at (105.25 + 10 col, 55 + 10 row) px.
    for row in 0..10_usize {
        for col in 0..10_usize {
            let (u, v) = (105 + 10 * col, 55 + 10 * row);
            let want = if (row + col).is_multiple_of(2) {
                dark
            } else {
                light
            };
            assert!(
                (f64::from(r.image.get(u, v)) - want).abs() <= 0.5,
                "square ({col}, {row})"
            );
        }
    }
    // The top row's first square is dark; the border (20 mm = 20 px) left of it is light.
    let v = 55;
    let expected_100 = 0.75 * light + 0.25 * dark;
    assert!((f64::from(r.image.get(100, v)) - expected_100).abs() <= 0.5);
    assert!((f64::from(r.image.get(85, v)) - light).abs() <= 0.5);
    // Beyond the border: the background, neither module level.
    let bg = f64::from(r.image.get(70, v));
    assert!(
        (bg - light).abs() > 10.0 && (bg - dark).abs() > 10.0,
        "{bg}"
    );
}

#[test]
fn a_board_and_a_code_with_the_same_effects_share_background_lighting_and_noise() {
    let effects = Effects {
        blur_px: 0.8,
        noise: 2.0,
        lighting: 0.2,
        clutter: 20,
        encoding: Encoding::Jpeg(90),
        seed: 7,
        ..Effects::default()
    };
    let board_scene = tilted_scene();
    let marker = Marker::try_new(120.0).expect("valid size");
    let code_scene = Scene {
        payload: b"https://example.com/qrpose/calibration/120mm".to_vec(),
        ec_level: EcLevel::M,
        marker,
        camera: board_scene.camera,
        width_px: 1280,
        height_px: 720,
        // Elsewhere in the image: the left half, the board being in the right half.
        pose: marker.pose_centred_at(Rotation3::identity(), Vector3::new(-250.0, 0.0, 600.0)),
    };
    let b = render_checkerboard(&board_scene, &effects).expect("renders");
    let c = render(&code_scene, &effects).expect("renders");
    let (w, h) = (1280, 720);
    let pixel = |img: &qrpose_detect::decode::GrayImage, x: usize, y: usize| img.get(x, y);
    // Columns 0-39 and 1240-1279 hold neither target: the pixels before the JPEG match.
    let mut compared = 0;
    for y in 0..h {
        for x in (0..40).chain(w - 40..w) {
            assert_eq!(pixel(&b.image, x, y), pixel(&c.image, x, y), "({x}, {y})");
            compared += 1;
        }
    }
    assert_eq!(compared, 80 * 720);
    // And with another seed they differ there (the noise is drawn anew).
    let other = render(&code_scene, &Effects { seed: 8, ..effects }).expect("renders");
    assert_ne!(&b.image.pixels()[..40], &other.image.pixels()[..40]);
}

#[test]
fn refuses_invalid_boards_and_boards_out_of_view() {
    let mut scene = tilted_scene();
    for bad in [
        board(1),
        board(65),
        Checkerboard {
            size_mm: 0.0,
            ..board(10)
        },
        Checkerboard {
            border_mm: -1.0,
            ..board(10)
        },
        Checkerboard {
            border_mm: f64::NAN,
            ..board(10)
        },
    ] {
        scene.board = bad;
        assert!(matches!(
            render_checkerboard(&scene, &Effects::default()),
            Err(RenderError::Checkerboard { .. })
        ));
    }
    scene.board = board(10);
    scene.pose = MarkerToCamera::new(Rotation3::identity(), Vector3::new(900.0, 0.0, 450.0));
    assert_eq!(
        render_checkerboard(&scene, &Effects::default()),
        Err(RenderError::OutOfView)
    );
}
