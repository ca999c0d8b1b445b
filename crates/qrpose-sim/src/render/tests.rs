//! Tests of the renderer through its public functions: ground truth against the pose,
//! one edge's coverage against the geometry, a symbol out of view, a fisheye's bowed side,
//! and a single-code render pinned to its pixels (the same through [`render`] and
//! [`render_scene`]).

use super::*;
use nalgebra::Vector3;
use qrpose_core::geometry::euler::EulerXyz;

fn scene(alpha_deg: f64, gamma_deg: f64) -> Scene {
    Scene {
        payload: b"qrpose render test".to_vec(),
        ec_level: EcLevel::M,
        marker: Marker::try_new(40.0).expect("valid size"),
        camera: Camera::from_pixels(800.0, 800.0, 319.5, 239.5).expect("valid camera"),
        width_px: 640,
        height_px: 480,
        pose: MarkerToCamera::new(
            EulerXyz::from_degrees(alpha_deg, 0.0, gamma_deg).to_rotation(),
            Vector3::new(20.0, -20.0, 300.0),
        ),
    }
}

#[test]
fn ground_truth_corners_reproject_the_pose_exactly() {
    let s = scene(20.0, 35.0);
    let truth = ground_truth(&s).expect("in view");
    let corners = s.marker.object_points(); // P1..P4
    let qr_of_paper = [2, 1, 0, 3];
    for (paper, corner) in corners.iter().enumerate() {
        let p = s
            .camera
            .project(&s.pose.transform(corner))
            .expect("in front");
        let q = truth.corners_px[qr_of_paper[paper]];
        assert!(
            (p.u() - q[0]).abs() < 1e-9 && (p.v() - q[1]).abs() < 1e-9,
            "P{}",
            paper + 1
        );
    }
    let finder = truth.finder_corners_px;
    assert_eq!(
        finder[0], truth.corners_px[0],
        "TL finder TL is the symbol TL"
    );
    assert_eq!(
        finder[5], truth.corners_px[1],
        "TR finder TR is the symbol TR"
    );
    assert_eq!(
        finder[11], truth.corners_px[3],
        "BL finder BL is the symbol BL"
    );
}

#[test]
fn a_noiseless_fronto_parallel_edge_sits_where_the_geometry_says() {
    // Identity rotation, P2 placed so that the symbol's left edge falls at u = 100.25, where
    // 16 × 16 supersampling measures the 25 % coverage of pixel 100 exactly.
    let camera = Camera::from_pixels(1000.0, 1000.0, 0.0, 0.0).expect("valid camera");
    let marker = Marker::try_new(50.0).expect("valid size");
    let z = 500.0;
    let left_u = 100.25;
    let s = Scene {
        payload: b"edge".to_vec(),
        ec_level: EcLevel::M,
        marker,
        camera,
        width_px: 240,
        height_px: 200,
        pose: MarkerToCamera::new(
            nalgebra::Rotation3::identity(),
            Vector3::new(left_u * z / 1000.0 + 50.0, 40.0 * z / 1000.0, z),
        ),
    };
    let effects = Effects {
        supersample: 16,
        ..Effects::default()
    };
    let r = render(&s, &effects).expect("renders");
    assert!((r.truth.corners_px[0][0] - left_u).abs() < 1e-9);
    // Row through the middle of the top-left finder's ring (dark from u = 100.25 on):
    // pixel 100 covers [99.5, 100.5], 25 % dark; pixel 101 is fully dark.
    let v = (r.truth.corners_px[0][1]
        + 0.5 * (r.truth.corners_px[3][1] - r.truth.corners_px[0][1]) / 21.0)
        .round() as usize;
    let expected_100 = 0.75 * effects.light_level + 0.25 * effects.dark_level;
    let got_100 = f64::from(r.image.get(100, v));
    assert!(
        (got_100 - expected_100).abs() <= 0.5,
        "pixel 100: {got_100} vs {expected_100}"
    );
    assert!((f64::from(r.image.get(101, v)) - effects.dark_level).abs() <= 0.5);
    assert!((f64::from(r.image.get(99, v)) - effects.light_level).abs() <= 0.5);
}

#[test]
fn refuses_a_symbol_outside_the_image() {
    let mut s = scene(0.0, 0.0);
    s.pose = MarkerToCamera::new(
        nalgebra::Rotation3::identity(),
        Vector3::new(400.0, 0.0, 300.0),
    );
    assert_eq!(render(&s, &Effects::default()), Err(RenderError::OutOfView));
}

/// FNV-1a of a byte string (a stable fingerprint of a render's pixels).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// FNV-1a of [`pinned_scene`]'s pixels with [`pinned_effects`], from the single-code renderer
/// as it was before the multi-code one replaced it (the new one gives the same bytes).
const PINNED_PIXELS_FNV1A: u64 = 8_570_194_075_281_222_094;

/// A small single-code scene, tilted and off-centre.
fn pinned_scene() -> Scene {
    let marker = Marker::try_new(40.0).expect("valid size");
    Scene {
        width_px: 160,
        height_px: 120,
        camera: Camera::from_pixels(300.0, 300.0, 79.5, 59.5).expect("valid camera"),
        pose: marker.pose_centred_at(
            EulerXyz::from_degrees(-15.0, 10.0, 25.0).to_rotation(),
            Vector3::new(5.0, -3.0, 250.0),
        ),
        marker,
        ..scene(0.0, 0.0)
    }
}

/// Clutter and uneven lighting, no blur or noise: only the renderer, the symbol encoder and
/// the seeded clutter decide the pixels.
fn pinned_effects() -> Effects {
    Effects {
        supersample: 3,
        lighting: 0.4,
        clutter: 12,
        seed: 11,
        ..Effects::default()
    }
}

#[test]
fn a_single_code_render_keeps_its_pixels_and_its_truth() {
    let s = pinned_scene();
    let r = render(&s, &pinned_effects()).expect("renders");
    assert_eq!(fnv1a(r.image.pixels()), PINNED_PIXELS_FNV1A);
    let truth = ground_truth(&s).expect("in view");
    assert_eq!(r.truth, truth);
    let qr_of_paper = [2, 1, 0, 3];
    for (paper, corner) in s.marker.object_points().iter().enumerate() {
        let p = s
            .camera
            .project(&s.pose.transform(corner))
            .expect("in front");
        let q = r.truth.corners_px[qr_of_paper[paper]];
        assert!((p.u() - q[0]).abs() < 1e-9 && (p.v() - q[1]).abs() < 1e-9);
    }
    let one = render_scene(&MultiScene::from(&s), &pinned_effects()).expect("renders");
    assert_eq!(one.image, r.image, "render is render_scene with one code");
    assert_eq!(one.encoded, r.encoded);
    assert_eq!(one.truth, vec![r.truth]);
}

#[test]
fn render_reports_the_error_of_its_one_code_unwrapped() {
    let mut s = scene(0.0, 0.0);
    s.payload = vec![b'x'; 4000];
    assert!(matches!(
        render(&s, &Effects::default()),
        Err(RenderError::Encode { .. })
    ));
    let multi = MultiScene::from(&s);
    assert!(matches!(
        render_scene(&multi, &Effects::default()),
        Err(RenderError::Code { index: 0, error }) if matches!(*error, RenderError::Encode { .. })
    ));
}

/// A fisheye bows a far-off-axis code's sides outward past the box of its corners; the
/// rasteriser must still draw them (fisheye lenses).
#[test]
fn a_fisheye_draws_the_bowed_side_of_a_code_far_off_the_axis() {
    let camera = Camera::from_pixels(420.0, 420.0, 639.5, 399.5)
        .expect("valid camera")
        .with_distortion(qrpose_core::geometry::camera::Distortion::from(
            qrpose_core::geometry::camera::Equidistant {
                k1: -0.00566,
                k2: 0.04186,
                k3: -0.03869,
                k4: 0.00673,
            },
        ));
    let marker = Marker::try_new(50.0).expect("valid size");
    let off_axis_rad = 60f64.to_radians();
    let centre = Vector3::new(off_axis_rad.tan(), 0.0, 1.0).normalize() * 110.0;
    let s = Scene {
        payload: b"BOW".to_vec(),
        ec_level: EcLevel::L,
        marker,
        camera,
        width_px: 1280,
        height_px: 800,
        pose: marker.pose_centred_at(EulerXyz::from_degrees(0.0, 0.0, 0.0).to_rotation(), centre),
    };
    let effects = Effects::default();
    let (n, _) = symbol_modules(&s.payload, s.ec_level).expect("encodes");
    let qz = effects.quiet_zone_modules;
    let nf = n as f64;
    let pixel = |u: f64, v: f64| {
        camera
            .project(&s.pose.transform(&marker_point(u, v, &marker, n)))
            .expect("in front")
    };
    // The outline's right side: its corners, and its middle one module inside the quiet zone.
    let corner_u = pixel(nf + qz, -qz).u().max(pixel(nf + qz, nf + qz).u());
    let inside = pixel(nf + qz - 1.0, nf / 2.0);
    let bow_px = inside.u() - corner_u;
    assert!(
        bow_px > 2.0 * super::raster::MARGIN_PX,
        "bow {bow_px} px: not a test of the box"
    );
    let rendered = render(&s, &effects).expect("renders");
    let (x, y) = (inside.u().round() as usize, inside.v().round() as usize);
    let level = rendered.image.get(x, y);
    assert!(
        (f64::from(level) - effects.light_level).abs() < 2.0,
        "quiet zone at ({x}, {y}), {bow_px} px past the corners: grey level {level}"
    );
}
