//! The rasteriser: a scene and its effects to pixels ([`render`]). Background clutter and
//! uneven lighting, the symbol supersampled through the camera's distortion, then the lens
//! blur ([`qrpose_detect::filters::gaussian_blur_plane`], on the `f64` plane), sensor
//! noise and 8-bit quantisation; the file is written by [`super::encode`].

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use super::symbol::{ground_truth, marker_point, module_coords, symbol_modules};
use super::{Effects, Encoding, MAX_SIDE_PX, RenderError, Rendered, Scene, encode};
use nalgebra::{Point3, Vector3};
use qrpose_core::geometry::frames::{CameraPoint, PixelPoint};
use qrpose_detect::decode::GrayImage;
use qrpose_detect::filters::gaussian_blur_plane;
use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};

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
        plane =
            gaussian_blur_plane(&plane, wu, hu, effects.blur_px).ok_or(RenderError::ImageSize {
                width_px: w,
                height_px: h,
            })?;
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
