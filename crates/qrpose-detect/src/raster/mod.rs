//! The raster every stage works on: [`GrayImage`] (an 8-bit grey image with integer pixel
//! access and bilinear sampling at sub-pixel positions) and the whole-image transforms of
//! the workspace: [`sharpen`] (an unsharp mask, or with amount −1 the Gaussian blur
//! itself), [`stretch_contrast`], [`invert`], [`upscale_double`], [`downscale_half`], and
//! the renderer's lens blur on a floating-point plane ([`gaussian_blur_plane`]).
//!
//! Pixel (u, v) covers [u − 0.5, u + 0.5] × [v − 0.5, v + 0.5], so pixel centres lie at
//! integer coordinates (docs/conventions.md).

mod blur;
mod filters;
mod gray;

pub use blur::{gaussian_blur_plane, sharpen};
pub use filters::{downscale_half, invert, stretch_contrast, upscale_double};
pub use gray::GrayImage;
