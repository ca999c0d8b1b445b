//! The sequence file ([`SequenceSpec`]): what a rendered video shows, as JSON. A camera
//! (intrinsics and an optional lens model, as the `--scene` file of `qrpose-sim render` writes
//! it), the image size, the frame rate and length, codes placed in a world frame, the
//! camera's path through that frame ([`TrajectorySpec`]), an optional textured wall behind
//! the codes ([`WallSpec`]), the image effects ([`SequenceEffects`]) and one seed.
//!
//! World frame: that of a camera at the origin with identity rotation (x right, y down,
//! z forward, mm; docs/conventions.md), so a code with identity rotation faces a camera
//! looking along +z squarely and upright. Rotations are R = Rx(alpha)·Ry(beta)·Rz(gamma)
//! ([`EulerDeg`]), of the code's frame into the world for a code and of the camera's frame
//! into the world for a keyframe.
//!
//! Every field but `codes` and `trajectory` may be left out; the defaults are those of the
//! `Default` impls and the `default_*` functions below (1280 × 720, fx = fy = 1000 px with
//! the principal point at the image centre, 30 fps, a clean image).

use super::super::{DEFAULT_SUPERSAMPLE, EcLevel};
use serde::{Deserialize, Serialize};

/// A rendered video: camera, codes in the world, the camera's path, effects and a seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SequenceSpec {
    /// A name for the record (the built-ins carry theirs).
    #[serde(default)]
    pub name: String,
    /// Image width, px.
    #[serde(default = "default_width_px")]
    pub width_px: u32,
    /// Image height, px.
    #[serde(default = "default_height_px")]
    pub height_px: u32,
    /// The camera (principal point: the image centre when left out).
    #[serde(default)]
    pub camera: CameraSpec,
    /// Frames per second; frame k is captured at k · 1000 / fps ms.
    #[serde(default = "default_fps")]
    pub fps: f64,
    /// Number of frames. When left out: `duration_ms` · fps / 1000 rounded, or, without a
    /// duration, every frame up to the last keyframe's time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<u32>,
    /// Length of the video, ms (see `frames`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_ms: Option<f64>,
    /// The codes, drawn in this order (a later one over an earlier one where they overlap).
    pub codes: Vec<WorldCode>,
    /// The camera's path.
    pub trajectory: TrajectorySpec,
    /// A textured wall behind the codes (none: a uniform background).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wall: Option<WallSpec>,
    /// Image effects, the same for every frame (only the noise differs).
    #[serde(default)]
    pub effects: SequenceEffects,
    /// Seed of every random choice: the wall's shapes, the lighting's direction, and each
    /// frame's noise and shake (derived from it and the frame's index).
    #[serde(default)]
    pub seed: u64,
}

/// Default image width, px.
pub fn default_width_px() -> u32 {
    1280
}

/// Default image height, px.
pub fn default_height_px() -> u32 {
    720
}

/// Default frame rate, frames per second.
pub fn default_fps() -> f64 {
    30.0
}

/// The camera of a sequence, as the `--scene` file of `qrpose-sim render` writes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Horizontal focal length, px.
    pub fx_px: f64,
    /// Vertical focal length, px.
    pub fy_px: f64,
    /// Principal point, px (default: (width − 1) / 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cx_px: Option<f64>,
    /// Principal point, px (default: (height − 1) / 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cy_px: Option<f64>,
    /// The lens model and its coefficients (none: a pinhole).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<DistortionSpec>,
}

impl Default for CameraSpec {
    fn default() -> Self {
        Self {
            fx_px: 1000.0,
            fy_px: 1000.0,
            cx_px: None,
            cy_px: None,
            distortion: None,
        }
    }
}

/// A lens model and its coefficients in OpenCV's order (docs/calibration.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistortionSpec {
    /// `plumb_bob` (default), `rational_polynomial` or `equidistant`.
    #[serde(default = "default_lens_model")]
    pub model: String,
    /// k1, k2, p1, p2, k3 (plumb_bob); k1 … k6 with p1, p2 after k2 (rational_polynomial);
    /// k1 … k4 (equidistant).
    pub coefficients: Vec<f64>,
}

fn default_lens_model() -> String {
    "plumb_bob".to_owned()
}

/// R = Rx(alpha)·Ry(beta)·Rz(gamma), degrees (docs/conventions.md).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EulerDeg {
    /// About x, degrees.
    #[serde(default)]
    pub alpha: f64,
    /// About y, degrees.
    #[serde(default)]
    pub beta: f64,
    /// About z, degrees.
    #[serde(default)]
    pub gamma: f64,
}

/// A code placed in the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorldCode {
    /// The symbol's content (UTF-8 text). Two codes may say the same.
    pub payload: String,
    /// Error correction level, `L`, `M` (default), `Q` or `H`.
    #[serde(default)]
    pub ec_level: EcLevel,
    /// Side of the symbol, mm (finder edge to finder edge, quiet zone excluded).
    pub size_mm: f64,
    /// The code's centre in the world, mm.
    pub position_mm: [f64; 3],
    /// The code's rotation into the world (identity: facing +z's camera squarely).
    #[serde(default)]
    pub rotation_euler_xyz_deg: EulerDeg,
}

/// The camera's path: keyframes of its pose, interpolated, plus an optional shake.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectorySpec {
    /// At least one, in strictly increasing time. Before the first and after the last the
    /// camera stays at that keyframe. Two consecutive keyframes with the same pose make a
    /// still segment (the camera stops there without overshoot).
    pub keyframes: Vec<KeyframeSpec>,
    /// How positions are interpolated between keyframes.
    #[serde(default)]
    pub interpolation: Interpolation,
    /// Per-frame random shake on top of the path (none by default).
    #[serde(default)]
    pub shake: Shake,
}

/// Where the camera is at one time. Its orientation: looking at `look_at_mm` (the image's
/// v axis as close to world +y, down, as the direction allows; then turned by `roll_deg`
/// about the optical axis), or `rotation_euler_xyz_deg`, or, with neither, looking along
/// world +z.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeSpec {
    /// Time since the start of the video, ms.
    pub time_ms: f64,
    /// The camera centre in the world, mm.
    pub position_mm: [f64; 3],
    /// A world point on the optical axis, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub look_at_mm: Option<[f64; 3]>,
    /// Turn about the optical axis after `look_at_mm`, degrees (clockwise in the image
    /// for positive values, as Rz of the camera frame).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub roll_deg: f64,
    /// The camera's rotation into the world, instead of `look_at_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation_euler_xyz_deg: Option<EulerDeg>,
}

// serde's skip_serializing_if hands the field by reference.
#[allow(clippy::trivially_copy_pass_by_ref)]
fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

/// How positions are interpolated between keyframes. Rotations are always interpolated by
/// slerp at the same fraction of the segment's time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// A cubic Hermite curve with Catmull-Rom tangents (continuous velocity; zero velocity
    /// beside a still segment).
    #[default]
    Smooth,
    /// Straight lines at constant speed between keyframes.
    Linear,
}

/// Random shake added to each frame's camera pose, drawn anew per frame (white, not
/// smoothed): a translation and a small rotation in the camera frame, each axis Gaussian.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shake {
    /// σ of each translation axis, mm.
    #[serde(default)]
    pub position_mm: f64,
    /// σ of each axis of the rotation vector, degrees.
    #[serde(default)]
    pub rotation_deg: f64,
}

/// A flat rectangle in the world behind the codes, in its own grey level and with random
/// shapes on it (boxes, labels, shadows) that move with the world. Codes are drawn over the
/// wall whatever their depth, so place them on it or in front of it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallSpec {
    /// The wall's centre in the world, mm.
    pub position_mm: [f64; 3],
    /// The wall's rotation into the world (identity: the z = constant plane).
    #[serde(default)]
    pub rotation_euler_xyz_deg: EulerDeg,
    /// Width and height, mm.
    pub size_mm: [f64; 2],
    /// The wall's own grey level, 0-255.
    #[serde(default = "default_wall_level")]
    pub level: f64,
    /// Random shapes on it (rectangles and ellipses, 15 mm to a tenth of the wall across,
    /// grey 20-235), drawn from the sequence's seed.
    #[serde(default)]
    pub shapes: u32,
}

fn default_wall_level() -> f64 {
    150.0
}

/// The image effects of every frame. `Default` is a clean, sharp, noiseless image at JPEG
/// quality 90.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SequenceEffects {
    /// Sub-samples per pixel and axis near the codes (anti-aliasing), 1-16.
    #[serde(default = "default_supersample")]
    pub supersample: u32,
    /// Gaussian lens blur σ, px.
    #[serde(default)]
    pub blur_px: f64,
    /// Gaussian sensor noise σ, grey levels, drawn anew for every frame.
    #[serde(default)]
    pub noise: f64,
    /// Uneven lighting fixed to the image (gradient and vignetting), 0-0.9.
    #[serde(default)]
    pub lighting: f64,
    /// JPEG quality of the frames written as files, 1-100.
    #[serde(default = "default_jpeg_quality")]
    pub jpeg_quality: u8,
    /// Exposure time for motion blur, ms (0: none; at most the frame interval). The frame
    /// is the mean of `motion_samples` renders spread evenly over the exposure, centred on
    /// the capture time; the truth is at the capture time.
    #[serde(default)]
    pub shutter_ms: f64,
    /// Renders averaged per frame when `shutter_ms` > 0, 2-16.
    #[serde(default = "default_motion_samples")]
    pub motion_samples: u32,
    /// Grey level beyond the wall (or everywhere off the codes without a wall), 0-255.
    #[serde(default = "default_background_level")]
    pub background_level: f64,
}

impl Default for SequenceEffects {
    fn default() -> Self {
        Self {
            supersample: DEFAULT_SUPERSAMPLE,
            blur_px: 0.0,
            noise: 0.0,
            lighting: 0.0,
            jpeg_quality: default_jpeg_quality(),
            shutter_ms: 0.0,
            motion_samples: default_motion_samples(),
            background_level: default_background_level(),
        }
    }
}

fn default_supersample() -> u32 {
    DEFAULT_SUPERSAMPLE
}

fn default_jpeg_quality() -> u8 {
    90
}

fn default_motion_samples() -> u32 {
    4
}

fn default_background_level() -> f64 {
    120.0
}
