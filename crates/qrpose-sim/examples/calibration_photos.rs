//! Rendered calibration photos with known truth (the calibration comparison's,
//! `scripts/calibration_compare.py`): 15 views of one printed 120 mm QR code (version 4)
//! and, from the very same 15 poses, a printed checkerboard of the same outer size
//! (10 × 10 squares of 12 mm, 81 inner corners, a light border as wide as the code's quiet
//! zone), both drawn by qrpose-sim's rasteriser with the same camera, effects and seed.
//!
//! The camera: 1280 × 720, fx 1000, fy 1005, cx 652, cy 349 px, `plumb_bob` k1 −0.25,
//! k2 0.08, p1 0.001, p2 −0.0005, k3 0 (barrel distortion, off-centre principal point).
//! The views: the target's centre near 15 image positions (the four corners, the four
//! edges, the centre and six more inside, each shifted at random by up to 4 % of the image),
//! 0.3-0.7 m deep, tilted 10-40° about a random in-plane axis and spun at random about its
//! normal, redrawn until the target with its quiet zone is inside the image by 4 px. The
//! effects: supersampling 4, lens blur σ 0.8 px, sensor noise σ 2 grey levels, uneven
//! lighting 0.2, 20 background shapes, JPEG quality 90; view k of set `seed` draws its
//! background and noise from seed · 1000 + k, the same for its code and its board.
//!
//! ```text
//! cargo run --release -p qrpose-sim --example calibration_photos -- OUT_DIR [SEED]
//! ```
//!
//! Writes OUT_DIR/qr_00.jpg … qr_14.jpg, board_00.jpg … board_14.jpg and truth.json (the
//! camera, the effects, the code and the board, and per view both truths: corners and
//! finder corners of the code, inner corners of the board in px and mm, the pose). SEED
//! (default 0) picks the poses and the noise: the same seed gives the same files.

use nalgebra::{Rotation3, Unit, Vector3};
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose_core::geometry::frames::{MarkerToCamera, PixelPoint};
use qrpose_core::geometry::marker::Marker;
use qrpose_sim::render::{
    BoardScene, Checkerboard, DEFAULT_QUIET_ZONE_MODULES, EcLevel, Effects, Encoding, Scene,
    marker_point, render, render_checkerboard, symbol_modules,
};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde_json::json;
use std::f64::consts::PI;
use std::path::PathBuf;

const WIDTH_PX: u32 = 1280;
const HEIGHT_PX: u32 = 720;
const CODE_MM: f64 = 120.0;
const BOARD_SQUARES: u32 = 10;
/// 50 bytes: a version-4 symbol (33 modules) at level M.
const PAYLOAD: &str = "https://example.com/qrpose/calibration-target/120mm";
/// Pixels the target with its quiet zone keeps from the image's edge.
const MARGIN_PX: f64 = 4.0;
const LENS: [f64; 5] = [-0.25, 0.08, 0.001, -0.0005, 0.0];

/// Image positions of the views' centres, fractions of width and height.
const POSITIONS: [(f64, f64); 15] = [
    (0.12, 0.14),
    (0.88, 0.14),
    (0.88, 0.86),
    (0.12, 0.86),
    (0.5, 0.15),
    (0.88, 0.5),
    (0.5, 0.85),
    (0.12, 0.5),
    (0.5, 0.5),
    (0.3, 0.35),
    (0.7, 0.35),
    (0.7, 0.65),
    (0.3, 0.65),
    (0.42, 0.55),
    (0.6, 0.45),
];

fn camera() -> Camera {
    let lens = Distortion::from_coefficients(DistortionModel::PlumbBob, &LENS).expect("valid lens");
    Camera::from_pixels(1000.0, 1005.0, 652.0, 349.0)
        .expect("valid camera")
        .with_distortion(lens)
}

fn effects(seed: u64) -> Effects {
    Effects {
        supersample: 4,
        blur_px: 0.8,
        noise: 2.0,
        lighting: 0.2,
        clutter: 20,
        encoding: Encoding::Jpeg(90),
        seed,
        ..Effects::default()
    }
}

/// Whether the target (with `qz` modules of margin, `n` modules a side) is inside the image
/// by [`MARGIN_PX`], its outline sampled densely (distortion bows its sides).
fn inside(camera: &Camera, pose: &MarkerToCamera, marker: &Marker, n: usize, qz: f64) -> bool {
    let nf = n as f64;
    let corners = [
        (-qz, -qz),
        (nf + qz, -qz),
        (nf + qz, nf + qz),
        (-qz, nf + qz),
    ];
    (0..4).all(|side| {
        let ((u0, v0), (u1, v1)) = (corners[side], corners[(side + 1) % 4]);
        (0..32).all(|k| {
            let f = f64::from(k) / 32.0;
            let p = marker_point(u0 + f * (u1 - u0), v0 + f * (v1 - v0), marker, n);
            camera.project(&pose.transform(&p)).is_some_and(|px| {
                px.u() >= MARGIN_PX - 0.5
                    && px.v() >= MARGIN_PX - 0.5
                    && px.u() <= f64::from(WIDTH_PX) - 0.5 - MARGIN_PX
                    && px.v() <= f64::from(HEIGHT_PX) - 0.5 - MARGIN_PX
            })
        })
    })
}

/// A view near `at`: (pose, depth mm, tilt deg).
fn draw_view(
    rng: &mut StdRng,
    camera: &Camera,
    marker: &Marker,
    n: usize,
    at: (f64, f64),
) -> (MarkerToCamera, f64, f64) {
    for _ in 0..100_000 {
        let fu = at.0 + 0.04 * rng.gen_range(-1.0..=1.0);
        let fv = at.1 + 0.04 * rng.gen_range(-1.0..=1.0);
        let depth = rng.gen_range(300.0..=700.0);
        let tilt: f64 = rng.gen_range(10f64.to_radians()..=40f64.to_radians());
        let azimuth: f64 = rng.gen_range(0.0..2.0 * PI);
        let spin = rng.gen_range(0.0..2.0 * PI);
        let axis = Unit::new_normalize(Vector3::new(azimuth.cos(), azimuth.sin(), 0.0));
        let r = Rotation3::from_axis_angle(&axis, tilt)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), spin);
        let pixel = PixelPoint::new(fu * f64::from(WIDTH_PX), fv * f64::from(HEIGHT_PX));
        let ray = camera.normalize(&pixel).expect("an invertible lens");
        let pose = marker.pose_centred_at(r, ray.at_depth(depth).0.coords);
        if inside(camera, &pose, marker, n, DEFAULT_QUIET_ZONE_MODULES) {
            return (pose, depth, tilt.to_degrees());
        }
    }
    panic!("no view near {at:?} keeps the target inside the image");
}

fn main() {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(
        args.next()
            .expect("usage: calibration_photos OUT_DIR [SEED]"),
    );
    let seed: u64 = args
        .next()
        .map_or(0, |s| s.parse().expect("SEED: an integer"));
    std::fs::create_dir_all(&out).expect("creates OUT_DIR");
    let camera = camera();
    let marker = Marker::try_new(CODE_MM).expect("valid size");
    let (n, _) = symbol_modules(PAYLOAD.as_bytes(), EcLevel::M).expect("encodes");
    let quiet_zone_mm = DEFAULT_QUIET_ZONE_MODULES * CODE_MM / n as f64;
    let board = Checkerboard {
        squares: BOARD_SQUARES,
        size_mm: CODE_MM,
        border_mm: quiet_zone_mm,
    };
    let mut rng = StdRng::seed_from_u64(seed);
    let views: Vec<_> = POSITIONS
        .iter()
        .map(|&at| draw_view(&mut rng, &camera, &marker, n, at))
        .collect();
    let rendered: Vec<_> = views
        .par_iter()
        .enumerate()
        .map(|(k, &(pose, depth_mm, tilt_deg))| {
            let fx = effects(seed * 1000 + k as u64);
            let code = Scene {
                payload: PAYLOAD.as_bytes().to_vec(),
                ec_level: EcLevel::M,
                marker,
                camera,
                width_px: WIDTH_PX,
                height_px: HEIGHT_PX,
                pose,
            };
            let board_scene = BoardScene {
                board,
                camera,
                width_px: WIDTH_PX,
                height_px: HEIGHT_PX,
                pose,
            };
            let qr = render(&code, &fx).expect("renders the code");
            let b = render_checkerboard(&board_scene, &fx).expect("renders the board");
            let (qr_image, board_image) = (format!("qr_{k:02}.jpg"), format!("board_{k:02}.jpg"));
            std::fs::write(out.join(&qr_image), &qr.encoded).expect("writes");
            std::fs::write(out.join(&board_image), &b.encoded).expect("writes");
            json!({
                "index": k, "qr_image": qr_image, "board_image": board_image,
                "depth_mm": depth_mm, "tilt_deg": tilt_deg, "effects_seed": fx.seed,
                "qr": qr.truth, "board": b.truth,
            })
        })
        .collect();
    let fx = effects(0);
    let truth = json!({
        "seed": seed,
        "image_size_px": [WIDTH_PX, HEIGHT_PX],
        "camera": {
            "fx_px": camera.fx(), "fy_px": camera.fy(), "cx_px": camera.cx(), "cy_px": camera.cy(),
            "distortion": {"model": "plumb_bob", "coefficients": LENS},
        },
        "effects": {
            "supersample": fx.supersample, "blur_px": fx.blur_px, "noise": fx.noise,
            "lighting": fx.lighting, "clutter": fx.clutter, "jpeg_quality": 90,
            "seed": "set seed · 1000 + view index",
        },
        "code": {
            "payload": PAYLOAD, "ec_level": "M", "size_mm": CODE_MM, "module_count": n,
            "quiet_zone_modules": DEFAULT_QUIET_ZONE_MODULES,
        },
        "board": board,
        "views": rendered,
    });
    let text = serde_json::to_string_pretty(&truth).expect("serialises");
    std::fs::write(out.join("truth.json"), text).expect("writes truth.json");
    println!(
        "{}: 15 views (version {} code, {} modules; board {} × {} squares) seed {seed}",
        out.display(),
        (n - 17) / 4,
        n,
        BOARD_SQUARES,
        BOARD_SQUARES
    );
}
