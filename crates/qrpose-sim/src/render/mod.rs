//! Synthetic photos of QR codes at known poses, with their ground truth: the test and
//! benchmark source of every image-path number in this repository. One code per frame
//! ([`Scene`], [`render`]) or several ([`MultiScene`], [`render_scene`]; [`random_scene`]
//! places 2-6 non-overlapping codes at random); [`render`] is [`render_scene`] with one code,
//! so both go through the same rasteriser and give the same pixels.
//!
//! Geometry (docs/conventions.md): pixel (u, v) covers [u − 0.5, u + 0.5] × [v − 0.5, v + 0.5];
//! each pixel is the mean of `supersample`² rays through sub-pixel points
//! u + (a + 0.5)/s − 0.5. A ray is undistorted (the camera's lens model: `plumb_bob`,
//! `rational_polynomial` or the `equidistant` fisheye, so the image is what a lens with that
//! distortion would see; a fisheye pixel 90° or more off the axis sees the background),
//! intersected with the marker plane
//! and looked up in the symbol: marker frame origin P2 (top-right), x from P3 towards P2,
//! y down the symbol, side l = the symbol without its quiet zone; module (i, j) of an
//! N-module symbol covers x ∈ −l + l/N·[i, i + 1], y ∈ l/N·[j, j + 1]. The quiet zone
//! (4 modules by default) is white; beyond it lies the background.
//!
//! Photometry, in order: reflectance (symbol dark/light levels, background clutter) ×
//! uneven lighting (a linear gradient and vignetting), then the lens blur (Gaussian,
//! σ px), sensor noise (Gaussian, grey levels), 8-bit quantisation, then JPEG at the given
//! quality (or PNG). Everything random comes from one seed.
//!
//! Several codes: each is drawn in the order given, a later one on top of an earlier one
//! (its quiet zone included). The ground truth of every code is where it was placed, whether
//! or not another code hides part of it: occlusion is the caller's business, and
//! [`codes_overlap`] / [`MultiScene::overlapping_pairs`] tell whether two codes' image
//! outlines (quiet zones included) meet.
//!
//! Layout: the single-code scene, effect and result types here; the multi-code scene, its
//! ground truth and the overlap helpers in module `scene`; the random scene generator in
//! module `random`; the symbol's modules and the ground truth in module `symbol`; the
//! rasteriser (background, lighting, supersampled symbols, lens blur by
//! [`qrpose_detect::raster::gaussian_blur_plane`], noise, quantisation) in module `raster`;
//! the file encoding in module `encoding`. Every public item is re-exported here, but for
//! rendered video: a camera moving past codes placed in a world frame, frame by frame, with
//! the truth of every code in view, in the public module [`sequence`] (docs/rendering.md).
//! Hand-eye sessions (a camera on a robot arm, true and reported flange poses, the code's
//! pose in each photo) are in the public module [`hand_eye`] (docs/hand-eye.md).
//! Module `checkerboard` draws printed checkerboards with the same rasteriser and effects
//! ([`render_checkerboard`]), the reference target of the calibration comparison.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

mod checkerboard;
mod encoding;
pub mod hand_eye;
mod random;
mod raster;
mod scene;
pub mod sequence;
mod symbol;
#[cfg(test)]
mod tests;

pub use checkerboard::{
    BoardScene, BoardTruth, Checkerboard, MAX_BOARD_SQUARES, RenderedBoard, board_truth,
    render_checkerboard,
};
pub use encoding::{Encoding, encode};
pub use random::{SceneRanges, random_scene};
pub use raster::{render, render_scene};
pub use scene::{
    CodePlacement, MultiScene, RenderedScene, code_outline_px, codes_overlap, quad_separation_px,
    quads_overlap,
};
pub use symbol::{code_ground_truth, ground_truth, marker_point, symbol_modules};

use qrpose_core::geometry::{camera::Camera, frames::MarkerToCamera, marker::Marker};
use qrpose_detect::decode::GrayImage;
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
    /// One code of a [`MultiScene`] cannot be rendered ([`render`] reports the inner error
    /// of its one code instead).
    #[error("code {index}: {error}")]
    Code {
        /// The code's position in [`MultiScene::codes`], 0-based.
        index: usize,
        /// Why.
        error: Box<RenderError>,
    },
    /// A [`SceneRanges`] field is out of range (empty, not finite, or outside its limits).
    #[error("scene range {name} = {value} is out of range")]
    Range {
        /// The field.
        name: &'static str,
        /// The value given (of a `[min, max]` field, its min).
        value: f64,
    },
    /// A [`Checkerboard`] with fewer than 2 or more than [`MAX_BOARD_SQUARES`] squares a
    /// side, a size that is not finite and positive, or a border that is not finite and
    /// non-negative.
    #[error("invalid checkerboard: {squares} squares, {size_mm} mm, border {border_mm} mm")]
    Checkerboard {
        /// Squares per side.
        squares: u32,
        /// Outer side, mm.
        size_mm: f64,
        /// Border, mm.
        border_mm: f64,
    },
    /// [`random_scene`] could not fit the codes it drew into the image without overlaps.
    #[error("cannot place {codes} codes without overlap in the image")]
    Placement {
        /// How many codes were drawn.
        codes: usize,
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
