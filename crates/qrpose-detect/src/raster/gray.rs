//! The raster every other module works on: [`GrayImage`], an 8-bit grayscale image with
//! integer pixel access and bilinear sampling at sub-pixel positions.
//!
//! Pixel (u, v) covers [u − 0.5, u + 0.5] × [v − 0.5, v + 0.5], so pixel centres lie at
//! integer coordinates (docs/conventions.md). [`crate::decode`] makes one from image bytes;
//! the filters of [`crate::raster`] transform one; the detectors and
//! [`crate::refine::refine_corners`] read one.

// Pixel indices are floats floored inside the image before the cast, so truncation cannot
// occur.
#![allow(clippy::cast_possible_truncation)]

/// An 8-bit grayscale raster, row-major, one byte per pixel (0 black, 255 white). Pixel
/// (u, v) covers [u − 0.5, u + 0.5] × [v − 0.5, v + 0.5] (docs/conventions.md).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GrayImage {
    width: usize,
    height: usize,
    pixels: Vec<u8>,
}

impl GrayImage {
    /// A raster from its pixels; `None` unless `pixels.len() == width · height` and both are
    /// positive.
    pub fn new(width: usize, height: usize, pixels: Vec<u8>) -> Option<Self> {
        (width > 0 && height > 0 && width.checked_mul(height) == Some(pixels.len())).then_some(
            Self {
                width,
                height,
                pixels,
            },
        )
    }
    /// Width, px.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height, px.
    pub fn height(&self) -> usize {
        self.height
    }
    /// The pixels, row-major.
    pub fn pixels(&self) -> &[u8] {
        &self.pixels
    }
    /// The value at integer pixel (x, y); 0 outside (callers stay inside).
    pub fn get(&self, x: usize, y: usize) -> u8 {
        if x < self.width && y < self.height {
            self.pixels[y * self.width + x]
        } else {
            0
        }
    }
    /// Bilinear interpolation at (u, v) px (pixel centres at integers); `None` outside the
    /// image.
    pub fn sample(&self, u: f64, v: f64) -> Option<f64> {
        let max_u = (self.width - 1) as f64;
        let max_v = (self.height - 1) as f64;
        if !(u >= 0.0 && v >= 0.0 && u <= max_u && v <= max_v) {
            return None;
        }
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let (x0, y0) = (u0 as usize, v0 as usize);
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        let p = |x: usize, y: usize| f64::from(self.pixels[y * self.width + x]);
        let top = p(x0, y0) * (1.0 - fu) + p(x1, y0) * fu;
        let bottom = p(x0, y1) * (1.0 - fu) + p(x1, y1) * fu;
        Some(top * (1.0 - fv) + bottom * fv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_sample_uses_pixel_centres_at_integers() {
        let img = GrayImage::new(2, 2, vec![0, 100, 200, 255]).expect("2 × 2");
        assert_eq!(img.sample(0.0, 0.0), Some(0.0));
        assert_eq!(img.sample(0.5, 0.0), Some(50.0));
        assert_eq!(img.sample(1.0, 1.0), Some(255.0));
        assert_eq!(img.sample(-0.1, 0.0), None);
        assert_eq!(img.sample(1.01, 0.0), None);
    }
}
