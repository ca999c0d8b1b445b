//! Random multi-code scenes for tests and benchmarks: [`random_scene`] draws a camera and
//! 2-6 codes (by default 30-120 mm, 0.3-2 m away, tilted up to 35° from the line of sight,
//! any roll) in a 1280 × 720 frame, none overlapping another or the image border, from one
//! seed ([`SceneRanges`] sets the ranges).
//!
//! Placement is by rejection: a code is drawn (size, distance, image position of its centre,
//! tilt, roll) until its outline, quiet zone included, lies inside the image and at least
//! [`SceneRanges::gap_px`] from every code already placed; when a code cannot be placed in
//! [`SceneRanges::attempts`] draws the whole placement starts again. The placed codes are
//! therefore the ranges' draws conditioned on fitting (large, near codes are rarer than the
//! ranges alone would give).

use super::scene::{code_outline_px, quad_separation_px};
use super::symbol::code_ground_truth;
use super::{CodePlacement, EcLevel, MAX_SIDE_PX, MultiScene, RenderError};
use nalgebra::{Rotation3, Unit, Vector3};
use qrpose_core::geometry::{camera::Camera, frames::PixelPoint, marker::Marker};
use rand::{Rng, SeedableRng, rngs::StdRng};
use serde::{Deserialize, Serialize};

/// How many times the whole placement starts again before [`random_scene`] gives up.
const RESTARTS: u32 = 50;
/// Characters of the random payload suffix (QR alphanumeric mode).
const PAYLOAD_CHARS: &[u8] = b"0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ";

/// The ranges [`random_scene`] draws from, each `[min, max]` inclusive and uniform.
/// `Default` is the multi-code benchmark's scene (`scripts/multicode_bench.py`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneRanges {
    /// Image width, px.
    pub width_px: u32,
    /// Image height, px.
    pub height_px: u32,
    /// Focal length fx = fy, px; the principal point is the image centre, no distortion.
    pub focal_px: [f64; 2],
    /// Number of codes.
    pub codes: [usize; 2],
    /// Code side, mm (quiet zone excluded).
    pub size_mm: [f64; 2],
    /// Distance from the camera centre to the code centre, mm.
    pub distance_mm: [f64; 2],
    /// Largest angle between a code's normal and its line of sight, degrees (0-80).
    pub max_tilt_deg: f64,
    /// Error correction level of every code.
    pub ec_level: EcLevel,
    /// Quiet zone counted in each code's outline, modules (that of the render's
    /// [`super::Effects`]).
    pub quiet_zone_modules: f64,
    /// Smallest distance between two outlines, and between an outline and the image border,
    /// px.
    pub gap_px: f64,
    /// Smallest side of a code's symbol in the image, px (0: no limit; 40 or so keeps every
    /// code readable).
    pub min_side_px: f64,
    /// Draws per code before the placement starts again.
    pub attempts: u32,
}

impl Default for SceneRanges {
    fn default() -> Self {
        Self {
            width_px: 1280,
            height_px: 720,
            focal_px: [950.0, 1050.0],
            codes: [2, 6],
            size_mm: [30.0, 120.0],
            distance_mm: [300.0, 2000.0],
            max_tilt_deg: 35.0,
            ec_level: EcLevel::M,
            quiet_zone_modules: super::DEFAULT_QUIET_ZONE_MODULES,
            gap_px: 4.0,
            min_side_px: 0.0,
            attempts: 200,
        }
    }
}

fn check_range(name: &'static str, r: [f64; 2], lo: f64, hi: f64) -> Result<(), RenderError> {
    let ok = r[0].is_finite() && r[1].is_finite() && lo <= r[0] && r[0] <= r[1] && r[1] <= hi;
    if ok {
        Ok(())
    } else {
        Err(RenderError::Range { name, value: r[0] })
    }
}

fn check(ranges: &SceneRanges) -> Result<(), RenderError> {
    let (w, h) = (ranges.width_px, ranges.height_px);
    if w == 0 || h == 0 || w > MAX_SIDE_PX || h > MAX_SIDE_PX {
        return Err(RenderError::ImageSize {
            width_px: w,
            height_px: h,
        });
    }
    let codes = ranges.codes.map(|c| c as f64);
    check_range("focal_px", ranges.focal_px, f64::MIN_POSITIVE, 1e6)?;
    check_range("codes", codes, 1.0, 100.0)?;
    check_range("size_mm", ranges.size_mm, f64::MIN_POSITIVE, 1e5)?;
    check_range("distance_mm", ranges.distance_mm, f64::MIN_POSITIVE, 1e7)?;
    let max_tilt = ranges.max_tilt_deg;
    check_range("max_tilt_deg", [max_tilt, max_tilt], 0.0, 80.0)?;
    let qz = ranges.quiet_zone_modules;
    check_range("quiet_zone_modules", [qz, qz], 0.0, 40.0)?;
    check_range("gap_px", [ranges.gap_px, ranges.gap_px], 0.0, 1e4)?;
    let side = ranges.min_side_px;
    check_range("min_side_px", [side, side], 0.0, 1e4)?;
    if ranges.attempts == 0 {
        return Err(RenderError::Range {
            name: "attempts",
            value: 0.0,
        });
    }
    Ok(())
}

/// One draw of code `payload`'s size and pose; `None` when the draw does not fit.
fn draw_code(
    rng: &mut StdRng,
    camera: &Camera,
    ranges: &SceneRanges,
    payload: &[u8],
    placed: &[[[f64; 2]; 4]],
) -> Option<(CodePlacement, [[f64; 2]; 4])> {
    let (w, h) = (f64::from(ranges.width_px), f64::from(ranges.height_px));
    let size = rng.gen_range(ranges.size_mm[0]..=ranges.size_mm[1]);
    let distance = rng.gen_range(ranges.distance_mm[0]..=ranges.distance_mm[1]);
    let (u, v) = (rng.gen_range(-0.5..w - 0.5), rng.gen_range(-0.5..h - 0.5));
    let tilt = rng.gen_range(0.0..=ranges.max_tilt_deg).to_radians();
    let azimuth = rng.gen_range(0.0..std::f64::consts::TAU);
    let roll = rng.gen_range(0.0..std::f64::consts::TAU);
    let ray = camera.normalize(&PixelPoint::new(u, v)).ok()?;
    let sight = Vector3::new(ray.x(), ray.y(), 1.0).normalize();
    // Facing the camera (normal along the line of sight), tilted about an in-plane axis,
    // rolled about the normal.
    let face = Rotation3::rotation_between(&Vector3::z(), &sight)?;
    let axis = Unit::new_normalize(Vector3::new(azimuth.cos(), azimuth.sin(), 0.0));
    let r = face
        * Rotation3::from_axis_angle(&axis, tilt)
        * Rotation3::from_axis_angle(&Vector3::z_axis(), roll);
    let marker = Marker::try_new(size).ok()?;
    let code = CodePlacement {
        payload: payload.to_vec(),
        ec_level: ranges.ec_level,
        marker,
        pose: marker.pose_centred_at(r, sight * distance),
    };
    let outline = code_outline_px(camera, &code, ranges.quiet_zone_modules).ok()?;
    let g = ranges.gap_px;
    let inside = outline
        .iter()
        .all(|p| p[0] >= g - 0.5 && p[1] >= g - 0.5 && p[0] <= w - 0.5 - g && p[1] <= h - 0.5 - g);
    if !inside || placed.iter().any(|o| quad_separation_px(o, &outline) < g) {
        return None;
    }
    if ranges.min_side_px > 0.0 {
        let c = code_ground_truth(camera, &code).ok()?.corners_px;
        let shortest = (0..4)
            .map(|i| (c[i][0] - c[(i + 1) % 4][0]).hypot(c[i][1] - c[(i + 1) % 4][1]))
            .fold(f64::INFINITY, f64::min);
        if shortest < ranges.min_side_px {
            return None;
        }
    }
    Some((code, outline))
}

/// A random scene: a camera (fx = fy drawn from [`SceneRanges::focal_px`], principal point
/// at the image centre) and a number of codes drawn from `ranges`, whose outlines (quiet
/// zones included) neither overlap nor touch the image border. Code `i` says
/// `S<seed>-C<i>-` followed by 0-16 random alphanumerics. The same seed and ranges give the
/// same scene.
///
/// # Errors
/// [`RenderError::ImageSize`] or [`RenderError::Range`] for ranges out of range, and
/// [`RenderError::Placement`] when the codes do not fit after every restart (codes too many
/// or too large for the image).
pub fn random_scene(seed: u64, ranges: &SceneRanges) -> Result<MultiScene, RenderError> {
    check(ranges)?;
    let mut rng = StdRng::seed_from_u64(seed);
    let focal = rng.gen_range(ranges.focal_px[0]..=ranges.focal_px[1]);
    let (w, h) = (ranges.width_px, ranges.height_px);
    let camera = Camera::from_pixels(
        focal,
        focal,
        f64::from(w) / 2.0 - 0.5,
        f64::from(h) / 2.0 - 0.5,
    )
    .map_err(|_| RenderError::Range {
        name: "focal_px",
        value: focal,
    })?;
    let count = rng.gen_range(ranges.codes[0]..=ranges.codes[1]);
    let payloads: Vec<Vec<u8>> = (0..count)
        .map(|i| {
            let mut p = format!("S{seed}-C{i}-").into_bytes();
            let extra = rng.gen_range(0..=16);
            p.extend((0..extra).map(|_| PAYLOAD_CHARS[rng.gen_range(0..PAYLOAD_CHARS.len())]));
            p
        })
        .collect();
    for _ in 0..RESTARTS {
        let mut codes = Vec::with_capacity(count);
        let mut outlines = Vec::with_capacity(count);
        for payload in &payloads {
            let found = (0..ranges.attempts)
                .find_map(|_| draw_code(&mut rng, &camera, ranges, payload, &outlines));
            let Some((code, outline)) = found else {
                break;
            };
            codes.push(code);
            outlines.push(outline);
        }
        if codes.len() == count {
            return Ok(MultiScene {
                camera,
                width_px: w,
                height_px: h,
                codes,
            });
        }
    }
    Err(RenderError::Placement { codes: count })
}
