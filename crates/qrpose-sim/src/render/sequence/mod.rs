//! Rendered video with ground truth: a camera moving past codes placed in a world frame,
//! rendered frame by frame through the same rasteriser as a photo ([`super::render_scene`]),
//! with the truth of every code in view. The source of the stream's tests and benchmarks
//! (docs/rendering.md).
//!
//! A [`SequenceSpec`] (JSON-loadable; module `spec`) says what the video shows; a
//! [`Sequence`] is one checked and resolved, and answers per frame index k: the capture time
//! k · 1000 / fps ms ([`Sequence::capture_time_ms`]), the camera's pose
//! ([`Sequence::camera_pose`]: the [`Trajectory`] at that time, plus the frame's shake), the
//! truth ([`Sequence::truth`], without rendering) and the picture
//! ([`Sequence::render_frame`]). [`builtin_sequence`] names three ready-made videos
//! (`approach`, `still`, `pan`); [`Y4mWriter`] writes frames as a YUV4MPEG2 file, what
//! Chromium's fake camera plays.
//!
//! What a frame's truth holds ([`FrameTruth`]): every code whose printed face is towards the
//! camera, whose four corners are in front of it, and whose symbol overlaps the image at
//! least in part, with its corners (px, qr order), pose in the camera frame, size, whether
//! it is entirely inside the image, and its shortest side in the image. A code facing away,
//! behind the camera or out of the picture is not in the truth. Codes partly out of the
//! image are drawn in part (unlike [`super::render_scene`], which refuses them).
//!
//! Randomness: one seed. The wall's shapes and the lighting's direction are drawn once for
//! the whole video; frame k's noise and shake from seeds derived from (seed, k), so any frame
//! renders alone, in any order, to the same pixels.
//!
//! Layout: the file format in `spec`; the path, its interpolation and the shake in
//! `trajectory`; the truth and the drawing of one frame in `frame`; the built-in videos in
//! `builtin`; the YUV4MPEG2 writer in `y4m`.

mod builtin;
mod frame;
mod spec;
mod trajectory;
mod y4m;

pub use builtin::{BUILTIN_SEQUENCES, builtin_sequence};
pub use frame::{CameraTruth, CodeTruth, Frame, FrameTruth};
pub use spec::{
    CameraSpec, DistortionSpec, EulerDeg, Interpolation, KeyframeSpec, SequenceEffects,
    SequenceSpec, Shake, TrajectorySpec, WallSpec, WorldCode, default_fps, default_height_px,
    default_width_px,
};
pub use trajectory::{CameraToWorld, MAX_KEYFRAME_TURN_DEG, Trajectory, euler_rotation, shaken};
pub use y4m::{Y4mColour, Y4mError, Y4mWriter, y4m_frame_bytes, y4m_header};

use super::raster::{Lighting, Shape, check_effects, check_size};
use super::symbol::symbol_modules;
use super::{CodePlacement, Effects, Encoding, MultiScene, RenderError};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose_core::geometry::marker::Marker;
use rand::{SeedableRng, rngs::StdRng};
use thiserror::Error;

/// Largest frame rate, frames per second.
pub const MAX_FPS: f64 = 1000.0;
/// Most frames in a sequence.
pub const MAX_FRAMES: u32 = 1_000_000;
/// Most shapes on a wall.
pub const MAX_WALL_SHAPES: u32 = 10_000;

/// Why a sequence cannot be built or a frame rendered.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SequenceError {
    /// A field of the spec is out of range; `field` is its JSON pointer.
    #[error("{field}: {reason}")]
    Spec {
        /// The field, as a JSON pointer (`/codes/2/size_mm`).
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A frame index at or past the sequence's length.
    #[error("frame {index} is past the sequence's {frames} frames")]
    FrameIndex {
        /// The index asked for.
        index: u32,
        /// How many frames the sequence has.
        frames: u32,
    },
    /// The renderer refused (an image size or effect out of range, an encoder failure).
    #[error(transparent)]
    Render(#[from] RenderError),
}

fn spec_error(field: impl Into<String>, reason: impl Into<String>) -> SequenceError {
    SequenceError::Spec {
        field: field.into(),
        reason: reason.into(),
    }
}

/// Streams of derived seeds, one per use of randomness.
#[derive(Debug, Clone, Copy)]
enum Stream {
    Noise = 1,
    Shake = 2,
    Wall = 3,
    Lighting = 4,
}

/// SplitMix64's finaliser: a bijective mix of 64 bits.
fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of `stream` for frame `index` (0 for the whole video's draws).
fn derived_seed(seed: u64, stream: Stream, index: u32) -> u64 {
    splitmix64(splitmix64(seed ^ ((stream as u64) << 56)) ^ u64::from(index))
}

/// A code of the sequence, resolved.
#[derive(Debug, Clone, PartialEq)]
struct PlacedCode {
    payload: String,
    code: CodePlacement,
    /// p_world = T · p_marker.
    to_world: Isometry3<f64>,
}

/// Cells per side of a wall's lookup grid.
const WALL_GRID_CELLS: usize = 32;

/// The wall, resolved: its frame (origin at its centre, in its plane), half-sizes, level
/// and shapes (mm, from its top-left corner), with a grid of the shapes each cell meets.
#[derive(Debug, Clone, PartialEq)]
struct Wall {
    to_world: Isometry3<f64>,
    half_mm: [f64; 2],
    level: f64,
    shapes: Vec<Shape>,
    /// Per cell of a [`WALL_GRID_CELLS`]² grid over the wall (row-major), the indices of
    /// the shapes whose box meets it, in drawing order.
    grid: Vec<Vec<usize>>,
}

impl Wall {
    fn new(to_world: Isometry3<f64>, size_mm: [f64; 2], level: f64, shapes: Vec<Shape>) -> Self {
        let mut grid = vec![Vec::new(); WALL_GRID_CELLS * WALL_GRID_CELLS];
        let cell = |x: f64, size: f64| Self::cell_index(x, size);
        for (i, shape) in shapes.iter().enumerate() {
            let [u0, u1, v0, v1] = shape.bounds();
            for row in cell(v0, size_mm[1])..=cell(v1, size_mm[1]) {
                for col in cell(u0, size_mm[0])..=cell(u1, size_mm[0]) {
                    grid[row * WALL_GRID_CELLS + col].push(i);
                }
            }
        }
        Self {
            to_world,
            half_mm: [size_mm[0] / 2.0, size_mm[1] / 2.0],
            level,
            shapes,
            grid,
        }
    }

    /// The grid column (or row) of coordinate `x` on a side of `size` mm, clamped.
    fn cell_index(x: f64, size: f64) -> usize {
        let f = (x / size * WALL_GRID_CELLS as f64).floor();
        // Clamped into 0..WALL_GRID_CELLS before the cast.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let cell = f.clamp(0.0, (WALL_GRID_CELLS - 1) as f64) as usize;
        cell
    }

    /// The grey level at (x, y), mm from the wall's top-left corner.
    fn level_at(&self, x: f64, y: f64) -> f64 {
        let [hw, hh] = self.half_mm;
        let row = Self::cell_index(y, 2.0 * hh);
        let col = Self::cell_index(x, 2.0 * hw);
        self.grid[row * WALL_GRID_CELLS + col]
            .iter()
            .rev()
            .map(|&i| &self.shapes[i])
            .find(|s| s.contains(x, y))
            .map_or(self.level, Shape::level)
    }
}

/// A checked, resolved sequence: everything a frame needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Sequence {
    spec: SequenceSpec,
    camera: Camera,
    codes: Vec<PlacedCode>,
    trajectory: Trajectory,
    frames: u32,
    wall: Option<Wall>,
    /// The frame's effects but the seed.
    effects: Effects,
    lighting: Lighting,
}

fn finite(values: &[f64]) -> bool {
    values.iter().all(|x| x.is_finite())
}

/// The camera of a spec for its image size.
fn build_camera(spec: &SequenceSpec) -> Result<Camera, SequenceError> {
    let c = &spec.camera;
    let cx = c.cx_px.unwrap_or(f64::from(spec.width_px) / 2.0 - 0.5);
    let cy = c.cy_px.unwrap_or(f64::from(spec.height_px) / 2.0 - 0.5);
    let camera = Camera::from_pixels(c.fx_px, c.fy_px, cx, cy)
        .map_err(|e| spec_error("/camera", e.to_string()))?;
    let Some(d) = &c.distortion else {
        return Ok(camera);
    };
    let model = d
        .model
        .parse::<DistortionModel>()
        .map_err(|e| spec_error("/camera/distortion/model", e.to_string()))?;
    let distortion = Distortion::from_coefficients(model, &d.coefficients)
        .map_err(|e| spec_error("/camera/distortion/coefficients", e.to_string()))?;
    Ok(camera.with_distortion(distortion))
}

/// One code of a spec, resolved.
fn place_code(i: usize, c: &WorldCode) -> Result<PlacedCode, SequenceError> {
    let field = |name: &str| format!("/codes/{i}/{name}");
    let marker =
        Marker::try_new(c.size_mm).map_err(|e| spec_error(field("size_mm"), e.to_string()))?;
    symbol_modules(c.payload.as_bytes(), c.ec_level)
        .map_err(|e| spec_error(field("payload"), e.to_string()))?;
    if !finite(&c.position_mm) {
        return Err(spec_error(field("position_mm"), "not a finite point"));
    }
    let e = c.rotation_euler_xyz_deg;
    if !finite(&[e.alpha, e.beta, e.gamma]) {
        return Err(spec_error(field("rotation_euler_xyz_deg"), "not finite"));
    }
    let pose = marker.pose_centred_at(euler_rotation(&e), Vector3::from(c.position_mm));
    Ok(PlacedCode {
        payload: c.payload.clone(),
        code: CodePlacement {
            payload: c.payload.as_bytes().to_vec(),
            ec_level: c.ec_level,
            marker,
            pose,
        },
        to_world: pose.0,
    })
}

/// The wall of a spec, its shapes drawn from `seed`.
fn build_wall(w: &WallSpec, seed: u64) -> Result<Wall, SequenceError> {
    let [width, height] = w.size_mm;
    if !(finite(&w.size_mm) && width > 0.0 && height > 0.0) {
        return Err(spec_error("/wall/size_mm", "must be positive"));
    }
    if !finite(&w.position_mm) {
        return Err(spec_error("/wall/position_mm", "not a finite point"));
    }
    let e = w.rotation_euler_xyz_deg;
    if !finite(&[e.alpha, e.beta, e.gamma]) {
        return Err(spec_error("/wall/rotation_euler_xyz_deg", "not finite"));
    }
    if !(w.level.is_finite() && (0.0..=255.0).contains(&w.level)) {
        return Err(spec_error("/wall/level", "must be a grey level, 0-255"));
    }
    if w.shapes > MAX_WALL_SHAPES {
        return Err(spec_error(
            "/wall/shapes",
            format!("at most {MAX_WALL_SHAPES}"),
        ));
    }
    let mut rng = StdRng::seed_from_u64(seed);
    let max_radius = [width / 10.0, height / 10.0];
    let min_radius = 15.0_f64.min(max_radius[0].min(max_radius[1]) / 2.0);
    let shapes = (0..w.shapes)
        .map(|_| Shape::draw(&mut rng, [width, height], min_radius, max_radius))
        .collect();
    let rotation = UnitQuaternion::from_rotation_matrix(&euler_rotation(&e));
    let to_world =
        Isometry3::from_parts(Translation3::from(Vector3::from(w.position_mm)), rotation);
    Ok(Wall::new(to_world, w.size_mm, w.level, shapes))
}

/// The frame effects of a spec (seed 0; each frame sets its own), checked.
fn build_effects(spec: &SequenceSpec) -> Result<Effects, SequenceError> {
    let e = &spec.effects;
    let effects = Effects {
        supersample: e.supersample,
        blur_px: e.blur_px,
        noise: e.noise,
        lighting: e.lighting,
        clutter: 0,
        encoding: Encoding::Jpeg(e.jpeg_quality),
        ..Effects::default()
    };
    check_effects(&effects).map_err(|err| match err {
        RenderError::Effect { name, .. } => spec_error(format!("/effects/{name}"), err.to_string()),
        other => SequenceError::Render(other),
    })?;
    let interval_ms = 1000.0 / spec.fps;
    if !(e.shutter_ms.is_finite() && (0.0..=interval_ms).contains(&e.shutter_ms)) {
        return Err(spec_error(
            "/effects/shutter_ms",
            format!("must be 0-{interval_ms} ms (the frame interval)"),
        ));
    }
    if !(2..=16).contains(&e.motion_samples) {
        return Err(spec_error("/effects/motion_samples", "must be 2-16"));
    }
    if !(e.background_level.is_finite() && (0.0..=255.0).contains(&e.background_level)) {
        return Err(spec_error(
            "/effects/background_level",
            "must be a grey level, 0-255",
        ));
    }
    Ok(effects)
}

/// How many frames a spec asks for, given its resolved path.
fn frame_count(spec: &SequenceSpec, trajectory: &Trajectory) -> Result<u32, SequenceError> {
    let per_ms = spec.fps / 1000.0;
    let frames = match (spec.frames, spec.duration_ms) {
        (Some(n), _) => f64::from(n),
        (None, Some(d)) if d.is_finite() && d > 0.0 => (d * per_ms).round(),
        (None, Some(_)) => return Err(spec_error("/duration_ms", "must be positive")),
        (None, None) => (trajectory.end_ms() * per_ms + 1e-9).floor() + 1.0,
    };
    if !(1.0..=f64::from(MAX_FRAMES)).contains(&frames) {
        return Err(spec_error(
            "/frames",
            format!("the sequence must have 1-{MAX_FRAMES} frames, not {frames}"),
        ));
    }
    // In range, so the cast is exact.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    Ok(frames as u32)
}

impl Sequence {
    /// Checks and resolves a spec.
    ///
    /// # Errors
    /// [`SequenceError::Spec`] naming the first field out of range (the camera, a code's
    /// size or payload, a keyframe, the frame rate or count, the wall, an effect), and
    /// [`SequenceError::Render`] with [`RenderError::ImageSize`] for an image size out of
    /// range.
    pub fn new(spec: SequenceSpec) -> Result<Self, SequenceError> {
        check_size(spec.width_px, spec.height_px)?;
        if !(spec.fps.is_finite() && spec.fps > 0.0 && spec.fps <= MAX_FPS) {
            return Err(spec_error("/fps", format!("must be in (0, {MAX_FPS}]")));
        }
        let camera = build_camera(&spec)?;
        let codes = spec
            .codes
            .iter()
            .enumerate()
            .map(|(i, c)| place_code(i, c))
            .collect::<Result<Vec<_>, _>>()?;
        let trajectory = Trajectory::new(&spec.trajectory)?;
        let frames = frame_count(&spec, &trajectory)?;
        let effects = build_effects(&spec)?;
        let wall = spec
            .wall
            .as_ref()
            .map(|w| build_wall(w, derived_seed(spec.seed, Stream::Wall, 0)))
            .transpose()?;
        let mut rng = StdRng::seed_from_u64(derived_seed(spec.seed, Stream::Lighting, 0));
        let lighting = Lighting::draw(&mut rng, [spec.width_px, spec.height_px], effects.lighting);
        Ok(Self {
            spec,
            camera,
            codes,
            trajectory,
            frames,
            wall,
            effects,
            lighting,
        })
    }

    /// The spec this sequence was built from.
    pub fn spec(&self) -> &SequenceSpec {
        &self.spec
    }

    /// The camera (intrinsics and lens), the same in every frame.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The camera's path, without shake.
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }

    /// How many frames the video has.
    pub fn frame_count(&self) -> u32 {
        self.frames
    }

    /// When frame `index` is captured: index · 1000 / fps, ms.
    pub fn capture_time_ms(&self, index: u32) -> f64 {
        f64::from(index) * 1000.0 / self.spec.fps
    }

    /// The encoding of frames written as files (JPEG at the spec's quality).
    pub fn encoding(&self) -> Encoding {
        self.effects.encoding
    }

    /// The camera's pose in frame `index`: the path at its capture time, shaken by the
    /// frame's draw.
    pub fn camera_pose(&self, index: u32) -> CameraToWorld {
        let seed = derived_seed(self.spec.seed, Stream::Shake, index);
        let on_path = self.trajectory.pose_at(self.capture_time_ms(index));
        shaken(&on_path, &self.trajectory.shake(), seed)
    }

    /// Every code of the sequence as a camera at `pose` sees it (pose in the camera frame),
    /// in the spec's order, whether in view or not.
    pub fn scene(&self, pose: &CameraToWorld) -> MultiScene {
        MultiScene {
            camera: self.camera,
            width_px: self.spec.width_px,
            height_px: self.spec.height_px,
            codes: self
                .codes
                .iter()
                .map(|c| CodePlacement {
                    pose: pose.object_pose(&c.to_world),
                    ..c.code.clone()
                })
                .collect(),
        }
    }
}
