//! The raster every stage works on: [`GrayImage`] (module `gray`: 8-bit grey, integer pixel
//! access, bilinear sampling at sub-pixel positions) and the whole-image transforms of the
//! workspace (module `filters`: unsharp mask and Gaussian blur, contrast stretch, negative,
//! double and half scale).
//!
//! Pixel (u, v) covers [u − 0.5, u + 0.5] × [v − 0.5, v + 0.5], so pixel centres lie at
//! integer coordinates (docs/conventions.md).

pub mod filters;
pub mod gray;

pub use gray::GrayImage;
