//! The rasteriser: a scene and its effects to pixels ([`render_scene`]; [`render`] is the
//! same with one code). Background clutter and uneven lighting, each code supersampled
//! through the camera's distortion (later codes over earlier ones), then the lens blur
//! ([`qrpose_detect::raster::gaussian_blur_plane`], on the `f64` plane), sensor noise and
//! 8-bit quantisation; the file is written by [`super::encode`]. The pieces (a code ready to
//! draw, the lighting, the plane over any background, the finishing effects) are shared
//! with [`super::sequence`], whose frames have codes partly out of view, a wall fixed to the
//! world as background, and several drawings averaged for motion blur, and with
//! [`super::render_checkerboard`], whose squares are drawn as a symbol's modules are.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use super::scene::at_code;
use super::symbol::{code_ground_truth, marker_point, module_coords, symbol_modules};
use super::{
    CodePlacement, Effects, Encoding, MAX_SIDE_PX, MultiScene, RenderError, Rendered,
    RenderedScene, Scene, encode,
};
use nalgebra::{Point3, Vector3};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::{CameraPoint, CameraToMarker, MarkerToCamera, PixelPoint};
use qrpose_core::geometry::marker::Marker;
use qrpose_detect::decode::GrayImage;
use qrpose_detect::raster::gaussian_blur_plane;
use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};

/// A random background shape (axis-aligned ellipse or rectangle) with its grey level, in
/// whatever 2-D coordinates its user draws it in (image px, or mm on a wall).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Shape {
    cu: f64,
    cv: f64,
    ru: f64,
    rv: f64,
    ellipse: bool,
    level: f64,
}

impl Shape {
    /// A shape centred in `[0, width) × [0, height)`, with half-sizes in
    /// `[min_radius, max_radius)` per axis and a grey level in 20-235.
    pub(super) fn draw(
        rng: &mut StdRng,
        [width, height]: [f64; 2],
        min_radius: f64,
        max_radius: [f64; 2],
    ) -> Self {
        Self {
            cu: rng.gen_range(0.0..width),
            cv: rng.gen_range(0.0..height),
            ru: rng.gen_range(min_radius..max_radius[0]),
            rv: rng.gen_range(min_radius..max_radius[1]),
            ellipse: rng.gen_bool(0.5),
            level: rng.gen_range(20.0..235.0),
        }
    }

    /// The grey level of the topmost of `shapes` (the last drawn) at (u, v), if any.
    pub(super) fn level_at(shapes: &[Shape], u: f64, v: f64) -> Option<f64> {
        shapes
            .iter()
            .rev()
            .find(|s| s.contains(u, v))
            .map(|s| s.level)
    }

    /// The shape's grey level.
    pub(super) fn level(&self) -> f64 {
        self.level
    }

    /// The shape's bounding box: (u min, u max, v min, v max).
    pub(super) fn bounds(&self) -> [f64; 4] {
        [
            self.cu - self.ru,
            self.cu + self.ru,
            self.cv - self.rv,
            self.cv + self.rv,
        ]
    }

    /// Whether (u, v) lies on the shape.
    pub(super) fn contains(&self, u: f64, v: f64) -> bool {
        let (du, dv) = ((u - self.cu) / self.ru, (v - self.cv) / self.rv);
        if self.ellipse {
            du * du + dv * dv <= 1.0
        } else {
            du.abs() <= 1.0 && dv.abs() <= 1.0
        }
    }
}

/// Whether every effect is in range.
pub(super) fn check_effects(e: &Effects) -> Result<(), RenderError> {
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

/// A code ready to be drawn: its modules, its plane in the camera frame, and the image box
/// (px, quiet zone included) outside which it is not looked for.
pub(super) struct Prepared {
    n: usize,
    modules: Vec<bool>,
    normal: Vector3<f64>,
    t: Vector3<f64>,
    inv: CameraToMarker,
    l: f64,
    umin: f64,
    umax: f64,
    vmin: f64,
    vmax: f64,
}

/// Pixels within this distance of a code's box get supersampled.
pub(super) const MARGIN_PX: f64 = 2.0;

/// Points per side of a code's outline (corner included) over which its image box is
/// taken: enough that a fisheye's bowed side stays within [`MARGIN_PX`] of the box.
const OUTLINE_SAMPLES_PER_SIDE: u32 = 16;

impl Prepared {
    /// The code ready to be drawn by `camera` in a `width_px` × `height_px` image, with `qz`
    /// modules of quiet zone. A code whose outline does not project entirely (part of it at
    /// or behind the camera) is looked for in the whole image.
    ///
    /// # Errors
    /// [`RenderError::Encode`].
    pub(super) fn new(
        camera: &Camera,
        size: [u32; 2],
        code: &CodePlacement,
        qz: f64,
    ) -> Result<Self, RenderError> {
        let grid = symbol_modules(&code.payload, code.ec_level)?;
        Ok(Self::with_modules(
            camera,
            size,
            (&code.marker, &code.pose),
            grid,
            qz,
        ))
    }

    /// Any grid of `n` × `n` dark or light cells (row-major `modules`) drawn as a symbol's
    /// modules are, with `qz` cells of light margin: a QR symbol's modules, or the squares
    /// of a checkerboard ([`super::render_checkerboard`]).
    pub(super) fn with_modules(
        camera: &Camera,
        [width_px, height_px]: [u32; 2],
        (marker, pose): (&Marker, &MarkerToCamera),
        (n, modules): (usize, Vec<bool>),
        qz: f64,
    ) -> Self {
        let nf = n as f64;
        // Pixels whose footprint may touch the symbol and its quiet zone get supersampled.
        // Lens distortion bows the outline's sides (a fisheye by tens of pixels), so the box
        // is taken over points along every side, not only the corners.
        let corners = [
            (-qz, -qz),
            (nf + qz, -qz),
            (nf + qz, nf + qz),
            (-qz, nf + qz),
        ];
        let along_sides = (0..4).flat_map(|side| {
            let ((u0, v0), (u1, v1)) = (corners[side], corners[(side + 1) % 4]);
            (0..OUTLINE_SAMPLES_PER_SIDE).map(move |k| {
                let f = f64::from(k) / f64::from(OUTLINE_SAMPLES_PER_SIDE);
                (u0 + f * (u1 - u0), v0 + f * (v1 - v0))
            })
        });
        let outline: Vec<[f64; 2]> = along_sides
            .filter_map(|(u, v)| {
                camera
                    .project(&pose.transform(&marker_point(u, v, marker, n)))
                    .map(|p| [p.u(), p.v()])
            })
            .collect();
        let all_projected = outline.len() == 4 * OUTLINE_SAMPLES_PER_SIDE as usize;
        let (umin, umax, vmin, vmax) = if all_projected {
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
            (0.0, f64::from(width_px), 0.0, f64::from(height_px))
        };
        Self {
            n,
            modules,
            normal: pose.rotation() * Vector3::z(),
            t: pose.translation_mm(),
            inv: pose.inverse(),
            l: marker.size_mm(),
            umin,
            umax,
            vmin,
            vmax,
        }
    }

    /// Whether any pixel of a `width_px` × `height_px` image may see this code (its image
    /// box, with the supersampling margin, meets the image).
    pub(super) fn may_be_seen(&self, [width_px, height_px]: [u32; 2]) -> bool {
        self.umax + MARGIN_PX >= -0.5
            && self.vmax + MARGIN_PX >= -0.5
            && self.umin - MARGIN_PX <= f64::from(width_px) - 0.5
            && self.vmin - MARGIN_PX <= f64::from(height_px) - 0.5
    }

    /// Whether pixel (u, v) may see this code.
    fn near(&self, u: f64, v: f64) -> bool {
        u >= self.umin - MARGIN_PX
            && u <= self.umax + MARGIN_PX
            && v >= self.vmin - MARGIN_PX
            && v <= self.vmax + MARGIN_PX
    }

    /// The reflectance the ray (x, y, 1) meets on this code, `None` off the code and its
    /// quiet zone.
    fn reflectance(&self, dir: &Vector3<f64>, effects: &Effects) -> Option<f64> {
        let denom = self.normal.dot(dir);
        if denom.abs() < 1e-12 {
            return None;
        }
        let lambda = self.normal.dot(&self.t) / denom;
        if lambda <= 0.0 {
            return None;
        }
        let p_marker = self.inv.transform(&CameraPoint(Point3::from(dir * lambda)));
        let nf = self.n as f64;
        let qz = effects.quiet_zone_modules;
        let (mu, mv) = module_coords(p_marker.0.x, p_marker.0.y, self.l, nf);
        if mu < -qz || mv < -qz || mu >= nf + qz || mv >= nf + qz {
            return None;
        }
        if mu < 0.0 || mv < 0.0 || mu >= nf || mv >= nf {
            return Some(effects.light_level);
        }
        let (i, j) = (mu.floor() as usize, mv.floor() as usize);
        Some(if self.modules[j * self.n + i] {
            effects.dark_level
        } else {
            effects.light_level
        })
    }
}

/// Renders a single-code scene: [`render_scene`] with its one code.
///
/// # Errors
/// Every [`RenderError`] variant, as its doc says, except [`RenderError::Code`] (the error
/// of the one code is returned as it is) and the random scene's.
pub fn render(scene: &Scene, effects: &Effects) -> Result<Rendered, RenderError> {
    let RenderedScene {
        image,
        encoded,
        truth,
    } = render_scene(&MultiScene::from(scene), effects).map_err(|e| match e {
        RenderError::Code { error, .. } => *error,
        other => other,
    })?;
    // One code in, one ground truth out.
    let truth = truth.into_iter().next().ok_or(RenderError::OutOfView)?;
    Ok(Rendered {
        image,
        encoded,
        truth,
    })
}

/// Renders a scene of several codes, drawn in order (a later code, quiet zone included,
/// over an earlier one). Each code's ground truth is where it was placed, hidden or not.
///
/// # Errors
/// [`RenderError::Effect`], [`RenderError::ImageSize`], [`RenderError::Image`], and
/// [`RenderError::Code`] around [`RenderError::Encode`] or [`RenderError::OutOfView`] (a
/// corner of that code behind the camera or outside the image).
pub fn render_scene(scene: &MultiScene, effects: &Effects) -> Result<RenderedScene, RenderError> {
    check_effects(effects)?;
    let (w, h) = (scene.width_px, scene.height_px);
    check_size(w, h)?;
    let inside = |p: &[f64; 2]| {
        p[0] >= -0.5 && p[1] >= -0.5 && p[0] <= f64::from(w) - 0.5 && p[1] <= f64::from(h) - 0.5
    };
    let mut truth = Vec::with_capacity(scene.codes.len());
    let mut codes = Vec::with_capacity(scene.codes.len());
    for (i, code) in scene.codes.iter().enumerate() {
        let t = code_ground_truth(&scene.camera, code).map_err(at_code(i))?;
        if !t.corners_px.iter().all(inside) {
            return Err(at_code(i)(RenderError::OutOfView));
        }
        let p = Prepared::new(&scene.camera, [w, h], code, effects.quiet_zone_modules)
            .map_err(at_code(i))?;
        truth.push(t);
        codes.push(p);
    }
    let (image, encoded) = draw_photo(&scene.camera, [w, h], &codes, effects)?;
    Ok(RenderedScene {
        image,
        encoded,
        truth,
    })
}

/// A photo of prepared codes (or boards) over the background: clutter, background level
/// and lighting, then noise, all drawn from `effects.seed` in that order (so one seed gives
/// the same background, lighting and noise whatever is drawn), the plane finished
/// and encoded.
///
/// # Errors
/// [`RenderError::ImageSize`], [`RenderError::Effect`], [`RenderError::Image`].
pub(super) fn draw_photo(
    camera: &Camera,
    [w, h]: [u32; 2],
    codes: &[Prepared],
    effects: &Effects,
) -> Result<(GrayImage, Vec<u8>), RenderError> {
    let mut rng = StdRng::seed_from_u64(effects.seed);
    let (wf, hf) = (f64::from(w), f64::from(h));
    let shapes: Vec<Shape> = (0..effects.clutter)
        .map(|_| Shape::draw(&mut rng, [wf, hf], 5.0, [wf / 6.0, hf / 6.0]))
        .collect();
    let background_level = rng.gen_range(90.0..170.0);
    let lighting = Lighting::draw(&mut rng, [w, h], effects.lighting);
    let background = |u: f64, v: f64| Shape::level_at(&shapes, u, v).unwrap_or(background_level);
    let plane = draw_plane(camera, [w, h], codes, effects, &background, &lighting);
    let image = finish(plane, [w, h], effects, &mut rng)?;
    let encoded = encode(&image, effects.encoding)?;
    Ok((image, encoded))
}

/// Refuses an image side of zero or above [`MAX_SIDE_PX`].
pub(super) fn check_size(width_px: u32, height_px: u32) -> Result<(), RenderError> {
    if width_px == 0 || height_px == 0 || width_px > MAX_SIDE_PX || height_px > MAX_SIDE_PX {
        return Err(RenderError::ImageSize {
            width_px,
            height_px,
        });
    }
    Ok(())
}

/// Uneven lighting, fixed to the image: a linear gradient in a random direction plus
/// vignetting, dropping the illumination by up to `amount` (0-0.9).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Lighting {
    amount: f64,
    gx: f64,
    gy: f64,
    diag: f64,
    cx: f64,
    cy: f64,
}

impl Lighting {
    /// The gradient's direction drawn from `rng` for a `width_px` × `height_px` image.
    pub(super) fn draw(rng: &mut StdRng, [width_px, height_px]: [u32; 2], amount: f64) -> Self {
        let angle = rng.gen_range(0.0..std::f64::consts::TAU);
        let (wf, hf) = (f64::from(width_px), f64::from(height_px));
        Self {
            amount,
            gx: angle.cos(),
            gy: angle.sin(),
            diag: wf.hypot(hf),
            cx: wf / 2.0,
            cy: hf / 2.0,
        }
    }

    /// The relative illumination at pixel (u, v), 0.1-1.
    fn at(&self, u: f64, v: f64) -> f64 {
        let (du, dv) = (u - self.cx, v - self.cy);
        let along = (du * self.gx + dv * self.gy) / self.diag + 0.5;
        let r2 = (du * du + dv * dv) / (self.diag * self.diag / 4.0);
        (1.0 - self.amount * along) * (1.0 - 0.3 * self.amount * r2)
    }
}

/// The reflectance × lighting plane of a `width_px` × `height_px` image (row-major): each
/// pixel near a code the mean of `supersample`² sub-pixel rays (the topmost code a ray meets,
/// else `background` at the sub-pixel point), every other pixel `background` at its centre.
pub(super) fn draw_plane(
    camera: &Camera,
    [width_px, height_px]: [u32; 2],
    codes: &[Prepared],
    effects: &Effects,
    background: &dyn Fn(f64, f64) -> f64,
    lighting: &Lighting,
) -> Vec<f64> {
    let (wu, hu) = (width_px as usize, height_px as usize);
    // The topmost code a sub-pixel ray meets, among those near its pixel.
    let reflectance = |near: &[&Prepared], u: f64, v: f64| -> Option<f64> {
        let ray = camera.normalize(&PixelPoint::new(u, v)).ok()?;
        let dir = Vector3::new(ray.x(), ray.y(), 1.0);
        near.iter().rev().find_map(|c| c.reflectance(&dir, effects))
    };
    let s = effects.supersample;
    let sf = f64::from(s);
    let mut plane = vec![0.0f64; wu * hu];
    let mut near: Vec<&Prepared> = Vec::with_capacity(codes.len());
    for y in 0..hu {
        for x in 0..wu {
            let (u, v) = (x as f64, y as f64);
            near.clear();
            near.extend(codes.iter().filter(|c| c.near(u, v)));
            let value = if near.is_empty() {
                background(u, v)
            } else {
                let mut sum = 0.0;
                for a in 0..s {
                    for b in 0..s {
                        let su = u + (f64::from(a) + 0.5) / sf - 0.5;
                        let sv = v + (f64::from(b) + 0.5) / sf - 0.5;
                        sum += reflectance(&near, su, sv).unwrap_or_else(|| background(su, sv));
                    }
                }
                sum / (sf * sf)
            };
            plane[y * wu + x] = value * lighting.at(u, v);
        }
    }
    plane
}

/// A plane to pixels: the lens blur ([`gaussian_blur_plane`], σ = `blur_px`), sensor noise
/// drawn from `rng` (σ = `noise` grey levels), rounding and clamping to 0-255.
///
/// # Errors
/// [`RenderError::ImageSize`] when the plane is not `width_px` × `height_px`, and
/// [`RenderError::Effect`] for a noise σ the normal distribution refuses.
pub(super) fn finish(
    mut plane: Vec<f64>,
    [width_px, height_px]: [u32; 2],
    effects: &Effects,
    rng: &mut StdRng,
) -> Result<GrayImage, RenderError> {
    let (wu, hu) = (width_px as usize, height_px as usize);
    let size_error = RenderError::ImageSize {
        width_px,
        height_px,
    };
    if effects.blur_px > 0.0 {
        plane = gaussian_blur_plane(&plane, wu, hu, effects.blur_px).ok_or(size_error.clone())?;
    }
    let noise = Normal::new(0.0, effects.noise.max(1e-12)).map_err(|_| RenderError::Effect {
        name: "noise",
        value: effects.noise,
    })?;
    let pixels: Vec<u8> = plane
        .iter()
        .map(|&value| {
            let noisy = if effects.noise > 0.0 {
                value + noise.sample(rng)
            } else {
                value
            };
            noisy.round().clamp(0.0, 255.0) as u8
        })
        .collect();
    GrayImage::new(wu, hu, pixels).ok_or(size_error)
}
