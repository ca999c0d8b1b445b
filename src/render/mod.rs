//! Synthetic photos of a QR code at a known pose, with their ground truth: the test and
//! benchmark source of every image-path number in this repository.
//!
//! Geometry (SPEC section 1): pixel (u, v) covers [u − 0.5, u + 0.5] × [v − 0.5, v + 0.5];
//! each pixel is the mean of `supersample`² rays through sub-pixel points
//! u + (a + 0.5)/s − 0.5. A ray is undistorted (the camera's Brown-Conrady model, so the
//! image is what a lens with that distortion would see), intersected with the marker plane
//! and looked up in the symbol: marker frame origin P2 (top-right), x from P3 towards P2,
//! y down the symbol, side l = the symbol without its quiet zone; module (i, j) of an
//! N-module symbol covers x ∈ −l + l/N·[i, i + 1], y ∈ l/N·[j, j + 1]. The quiet zone
//! (4 modules by default) is white; beyond it lies the background.
//!
//! Photometry, in order: reflectance (symbol dark/light levels, background clutter) ×
//! uneven lighting (a linear gradient and vignetting), then the lens blur (Gaussian,
//! σ px), sensor noise (Gaussian, grey levels), 8-bit quantisation, then JPEG at the given
//! quality (or PNG). Everything random comes from one seed.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use crate::detect::decode::GrayImage;
use crate::detect::finders::{finder_model_points, marker_point_of_module};
use crate::detect::homography::ModulePoint;
use crate::geometry::{
    camera::Camera,
    frames::{CameraPoint, MarkerPoint, MarkerToCamera, PixelPoint},
    marker::Marker,
};
use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Default quiet zone, modules (ISO/IEC 18004 asks for 4).
pub const DEFAULT_QUIET_ZONE_MODULES: f64 = 4.0;
/// Default supersampling per axis.
pub const DEFAULT_SUPERSAMPLE: u32 = 4;
/// Largest rendered image side, px.
pub const MAX_SIDE_PX: u32 = 8192;

/// Error correction level of the rendered symbol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum EcLevel {
    /// 7 %.
    L,
    /// 15 % (default).
    #[default]
    M,
    /// 25 %.
    Q,
    /// 30 %.
    H,
}

/// How to encode the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Encoding {
    /// JPEG at this quality (1-100).
    Jpeg(u8),
    /// Lossless PNG.
    Png,
}

/// Everything a render needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The symbol's content.
    pub payload: Vec<u8>,
    /// Error correction level.
    pub ec_level: EcLevel,
    /// The printed code.
    pub marker: Marker,
    /// The camera (intrinsics and distortion, px).
    pub camera: Camera,
    /// Image width, px.
    pub width_px: u32,
    /// Image height, px.
    pub height_px: u32,
    /// The marker's pose.
    pub pose: MarkerToCamera,
}

/// Image quality effects. `Default` is a clean, sharp, noiseless PNG.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Effects {
    /// Sub-samples per pixel and axis (anti-aliasing), 1-16.
    pub supersample: u32,
    /// Gaussian lens blur σ, px (0 = none).
    pub blur_px: f64,
    /// Gaussian sensor noise σ, grey levels (0 = none).
    pub noise: f64,
    /// Uneven lighting: relative illumination drop across the image, 0-0.9.
    pub lighting: f64,
    /// Number of random background shapes.
    pub clutter: u32,
    /// Grey level of the dark modules.
    pub dark_level: f64,
    /// Grey level of the light modules and the quiet zone.
    pub light_level: f64,
    /// Quiet zone, modules.
    pub quiet_zone_modules: f64,
    /// Output encoding.
    pub encoding: Encoding,
    /// Seed of every random choice.
    pub seed: u64,
}

impl Default for Effects {
    fn default() -> Self {
        Self {
            supersample: DEFAULT_SUPERSAMPLE,
            blur_px: 0.0,
            noise: 0.0,
            lighting: 0.0,
            clutter: 0,
            dark_level: 25.0,
            light_level: 225.0,
            quiet_zone_modules: DEFAULT_QUIET_ZONE_MODULES,
            encoding: Encoding::Png,
            seed: 0,
        }
    }
}

/// Why a scene cannot be rendered.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RenderError {
    /// The payload does not fit a QR symbol at this error correction level.
    #[error("cannot encode the payload as a QR symbol: {reason}")]
    Encode {
        /// What the encoder said.
        reason: String,
    },
    /// The image size is zero or above [`MAX_SIDE_PX`].
    #[error("image size {width_px} × {height_px} is outside 1..={MAX_SIDE_PX}")]
    ImageSize {
        /// Requested width, px.
        width_px: u32,
        /// Requested height, px.
        height_px: u32,
    },
    /// A corner of the symbol is behind the camera or outside the image.
    #[error("the symbol is not entirely in front of the camera and inside the image")]
    OutOfView,
    /// An effect parameter is out of range.
    #[error("effect {name} = {value} is out of range")]
    Effect {
        /// The effect.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// The image encoder failed.
    #[error("cannot encode the image: {reason}")]
    Image {
        /// What the encoder said.
        reason: String,
    },
}

/// The ground truth of a render. Corners in qr order (TL, TR, BR, BL), px.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroundTruth {
    /// Modules per side.
    pub module_count: usize,
    /// The symbol's corners, px, qr order.
    pub corners_px: [[f64; 2]; 4],
    /// The three finder patterns' outer corners, px: top-left finder (TL, TR, BR, BL), then
    /// top-right finder, then bottom-left finder.
    pub finder_corners_px: [[f64; 2]; 12],
    /// R of p_cam = R · p_marker + t, row-major.
    pub rotation_matrix: [[f64; 3]; 3],
    /// t: corner P2 (top-right) in the camera frame, mm.
    pub reference_point_mm: [f64; 3],
    /// The marker centre in the camera frame, mm.
    pub position_mm: [f64; 3],
}

/// A rendered photo.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendered {
    /// The pixels before encoding.
    pub image: GrayImage,
    /// The encoded file (JPEG or PNG).
    pub encoded: Vec<u8>,
    /// Where everything is.
    pub truth: GroundTruth,
}

/// The module matrix of a payload: (N, row-major dark flags).
///
/// # Errors
/// [`RenderError::Encode`] when the payload does not fit.
pub fn symbol_modules(
    payload: &[u8],
    ec_level: EcLevel,
) -> Result<(usize, Vec<bool>), RenderError> {
    let level = match ec_level {
        EcLevel::L => qrcode::EcLevel::L,
        EcLevel::M => qrcode::EcLevel::M,
        EcLevel::Q => qrcode::EcLevel::Q,
        EcLevel::H => qrcode::EcLevel::H,
    };
    let code = qrcode::QrCode::with_error_correction_level(payload, level).map_err(|e| {
        RenderError::Encode {
            reason: e.to_string(),
        }
    })?;
    let n = code.width();
    let dark = code
        .to_colors()
        .into_iter()
        .map(|c| c == qrcode::Color::Dark)
        .collect();
    Ok((n, dark))
}

/// Where a marker-plane point (x, y) lies in module coordinates (u right, v down).
fn module_coords(x_mm: f64, y_mm: f64, l_mm: f64, n: f64) -> (f64, f64) {
    ((x_mm + l_mm) / l_mm * n, y_mm / l_mm * n)
}

/// The marker-frame point of a module coordinate.
pub fn marker_point(u: f64, v: f64, marker: &Marker, n: usize) -> MarkerPoint {
    marker_point_of_module(ModulePoint::new(u, v), marker, n)
}

/// A random background shape (axis-aligned ellipse or rectangle) with its grey level.
struct Shape {
    cu: f64,
    cv: f64,
    ru: f64,
    rv: f64,
    ellipse: bool,
    level: f64,
}

impl Shape {
    fn contains(&self, u: f64, v: f64) -> bool {
        let (du, dv) = ((u - self.cu) / self.ru, (v - self.cv) / self.rv);
        if self.ellipse {
            du * du + dv * dv <= 1.0
        } else {
            du.abs() <= 1.0 && dv.abs() <= 1.0
        }
    }
}

fn check_effects(e: &Effects) -> Result<(), RenderError> {
    let checks: [(&'static str, f64, f64, f64); 6] = [
        ("supersample", f64::from(e.supersample), 1.0, 16.0),
        ("blur_px", e.blur_px, 0.0, 20.0),
        ("noise", e.noise, 0.0, 100.0),
        ("lighting", e.lighting, 0.0, 0.9),
        ("quiet_zone_modules", e.quiet_zone_modules, 0.0, 40.0),
        ("clutter", f64::from(e.clutter), 0.0, 1000.0),
    ];
    for (name, value, lo, hi) in checks {
        if !(value.is_finite() && value >= lo && value <= hi) {
            return Err(RenderError::Effect { name, value });
        }
    }
    if let Encoding::Jpeg(q) = e.encoding
        && !(1..=100).contains(&q)
    {
        return Err(RenderError::Effect {
            name: "jpeg_quality",
            value: f64::from(q),
        });
    }
    Ok(())
}

/// The ground truth of a scene: corners and finder corners projected by the camera.
///
/// # Errors
/// [`RenderError::Encode`], or [`RenderError::OutOfView`] when a corner is behind the
/// camera.
pub fn ground_truth(scene: &Scene) -> Result<GroundTruth, RenderError> {
    let (n, _) = symbol_modules(&scene.payload, scene.ec_level)?;
    let project = |u: f64, v: f64| -> Result<[f64; 2], RenderError> {
        let p = scene
            .camera
            .project(&scene.pose.transform(&marker_point(u, v, &scene.marker, n)))
            .ok_or(RenderError::OutOfView)?;
        Ok([p.u(), p.v()])
    };
    let nf = n as f64;
    let corners_px = [
        project(0.0, 0.0)?,
        project(nf, 0.0)?,
        project(nf, nf)?,
        project(0.0, nf)?,
    ];
    let mut finder_corners_px = [[0.0; 2]; 12];
    let finder_points = finder_model_points(n);
    for (k, p) in finder_points.iter().enumerate() {
        finder_corners_px[k] = project(p.u, p.v)?;
    }
    let r = scene.pose.rotation();
    let m = r.matrix();
    let t = scene.pose.translation_mm();
    let centre = scene.pose.transform(&scene.marker.centre()).0;
    Ok(GroundTruth {
        module_count: n,
        corners_px,
        finder_corners_px,
        rotation_matrix: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
        reference_point_mm: [t.x, t.y, t.z],
        position_mm: [centre.x, centre.y, centre.z],
    })
}

/// Renders a scene.
///
/// # Errors
/// Every [`RenderError`] variant, as its doc says.
pub fn render(scene: &Scene, effects: &Effects) -> Result<Rendered, RenderError> {
    check_effects(effects)?;
    let (w, h) = (scene.width_px, scene.height_px);
    if w == 0 || h == 0 || w > MAX_SIDE_PX || h > MAX_SIDE_PX {
        return Err(RenderError::ImageSize {
            width_px: w,
            height_px: h,
        });
    }
    let truth = ground_truth(scene)?;
    let inside = |p: &[f64; 2]| {
        p[0] >= -0.5 && p[1] >= -0.5 && p[0] <= f64::from(w) - 0.5 && p[1] <= f64::from(h) - 0.5
    };
    if !truth.corners_px.iter().all(inside) {
        return Err(RenderError::OutOfView);
    }
    let (n, modules) = symbol_modules(&scene.payload, scene.ec_level)?;
    let mut rng = StdRng::seed_from_u64(effects.seed);
    let (wu, hu) = (w as usize, h as usize);
    let shapes: Vec<Shape> = (0..effects.clutter)
        .map(|_| Shape {
            cu: rng.gen_range(0.0..f64::from(w)),
            cv: rng.gen_range(0.0..f64::from(h)),
            ru: rng.gen_range(5.0..f64::from(w) / 6.0),
            rv: rng.gen_range(5.0..f64::from(h) / 6.0),
            ellipse: rng.gen_bool(0.5),
            level: rng.gen_range(20.0..235.0),
        })
        .collect();
    let background_level = rng.gen_range(90.0..170.0);
    let background = |u: f64, v: f64| {
        shapes
            .iter()
            .rev()
            .find(|s| s.contains(u, v))
            .map_or(background_level, |s| s.level)
    };
    // Lighting: a gradient in a random direction plus vignetting.
    let angle = rng.gen_range(0.0..std::f64::consts::TAU);
    let (gx, gy) = (angle.cos(), angle.sin());
    let diag = f64::from(w).hypot(f64::from(h));
    let (cx_img, cy_img) = (f64::from(w) / 2.0, f64::from(h) / 2.0);
    let lighting = |u: f64, v: f64| {
        let along = ((u - cx_img) * gx + (v - cy_img) * gy) / diag + 0.5;
        let r2 = ((u - cx_img).powi(2) + (v - cy_img).powi(2)) / (diag * diag / 4.0);
        (1.0 - effects.lighting * along) * (1.0 - 0.3 * effects.lighting * r2)
    };
    // The marker plane in the camera frame: normal and P2.
    let r = scene.pose.rotation();
    let normal = r * Vector3::z();
    let t = scene.pose.translation_mm();
    let inv = scene.pose.inverse();
    let l = scene.marker.size_mm();
    let nf = n as f64;
    let qz = effects.quiet_zone_modules;
    let reflectance = |u: f64, v: f64| -> Option<f64> {
        let ray = scene.camera.normalize(&PixelPoint::new(u, v)).ok()?;
        let dir = Vector3::new(ray.x(), ray.y(), 1.0);
        let denom = normal.dot(&dir);
        if denom.abs() < 1e-12 {
            return None;
        }
        let lambda = normal.dot(&t) / denom;
        if lambda <= 0.0 {
            return None;
        }
        let p_marker = inv.transform(&CameraPoint(Point3::from(dir * lambda)));
        let (mu, mv) = module_coords(p_marker.0.x, p_marker.0.y, l, nf);
        if mu < -qz || mv < -qz || mu >= nf + qz || mv >= nf + qz {
            return None;
        }
        if mu < 0.0 || mv < 0.0 || mu >= nf || mv >= nf {
            return Some(effects.light_level);
        }
        let (i, j) = (mu.floor() as usize, mv.floor() as usize);
        Some(if modules[j * n + i] {
            effects.dark_level
        } else {
            effects.light_level
        })
    };
    // Pixels whose footprint may touch the symbol and its quiet zone get supersampled.
    let margin_px = 2.0;
    let outline: Vec<[f64; 2]> = [
        (-qz, -qz),
        (nf + qz, -qz),
        (nf + qz, nf + qz),
        (-qz, nf + qz),
    ]
    .iter()
    .filter_map(|&(u, v)| {
        scene
            .camera
            .project(&scene.pose.transform(&marker_point(u, v, &scene.marker, n)))
            .map(|p| [p.u(), p.v()])
    })
    .collect();
    let (umin, umax, vmin, vmax) = if outline.len() == 4 {
        outline.iter().fold(
            (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ),
            |(a, b, c, d), p| (a.min(p[0]), b.max(p[0]), c.min(p[1]), d.max(p[1])),
        )
    } else {
        (0.0, f64::from(w), 0.0, f64::from(h))
    };
    let s = effects.supersample;
    let sf = f64::from(s);
    let mut plane = vec![0.0f64; wu * hu];
    for y in 0..hu {
        for x in 0..wu {
            let (u, v) = (x as f64, y as f64);
            let near = u >= umin - margin_px
                && u <= umax + margin_px
                && v >= vmin - margin_px
                && v <= vmax + margin_px;
            let value = if near {
                let mut sum = 0.0;
                for a in 0..s {
                    for b in 0..s {
                        let su = u + (f64::from(a) + 0.5) / sf - 0.5;
                        let sv = v + (f64::from(b) + 0.5) / sf - 0.5;
                        sum += reflectance(su, sv).unwrap_or_else(|| background(su, sv));
                    }
                }
                sum / (sf * sf)
            } else {
                background(u, v)
            };
            plane[y * wu + x] = value * lighting(u, v);
        }
    }
    if effects.blur_px > 0.0 {
        plane = gaussian_blur(&plane, wu, hu, effects.blur_px);
    }
    let noise = Normal::new(0.0, effects.noise.max(1e-12)).map_err(|_| RenderError::Effect {
        name: "noise",
        value: effects.noise,
    })?;
    let pixels: Vec<u8> = plane
        .iter()
        .map(|&value| {
            let noisy = if effects.noise > 0.0 {
                value + noise.sample(&mut rng)
            } else {
                value
            };
            noisy.round().clamp(0.0, 255.0) as u8
        })
        .collect();
    let image = GrayImage::new(wu, hu, pixels).ok_or(RenderError::ImageSize {
        width_px: w,
        height_px: h,
    })?;
    let encoded = encode(&image, effects.encoding)?;
    Ok(Rendered {
        image,
        encoded,
        truth,
    })
}

/// Encodes a grayscale image as JPEG or PNG.
///
/// # Errors
/// [`RenderError::Image`] when the encoder fails.
pub fn encode(image: &GrayImage, encoding: Encoding) -> Result<Vec<u8>, RenderError> {
    let err = |e: image::ImageError| RenderError::Image {
        reason: e.to_string(),
    };
    let (Ok(w), Ok(h)) = (u32::try_from(image.width()), u32::try_from(image.height())) else {
        return Err(RenderError::ImageSize {
            width_px: u32::MAX,
            height_px: u32::MAX,
        });
    };
    let mut out = Vec::new();
    match encoding {
        Encoding::Jpeg(q) => {
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, q)
                .encode(image.pixels(), w, h, image::ExtendedColorType::L8)
                .map_err(err)?;
        }
        Encoding::Png => {
            use image::ImageEncoder;
            image::codecs::png::PngEncoder::new(&mut out)
                .write_image(image.pixels(), w, h, image::ExtendedColorType::L8)
                .map_err(err)?;
        }
    }
    Ok(out)
}

/// Separable Gaussian blur with clamped borders.
fn gaussian_blur(src: &[f64], w: usize, h: usize, sigma: f64) -> Vec<f64> {
    let radius = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
        .collect();
    let total: f64 = kernel.iter().sum();
    let kernel: Vec<f64> = kernel.iter().map(|k| k / total).collect();
    let clamp = |i: i64, n: usize| i.clamp(0, n as i64 - 1) as usize;
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            tmp[y * w + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, kv)| kv * src[y * w + clamp(x as i64 + k as i64 - radius, w)])
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, kv)| kv * tmp[clamp(y as i64 + k as i64 - radius, h) * w + x])
                .sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::euler::EulerXyz;

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
}
