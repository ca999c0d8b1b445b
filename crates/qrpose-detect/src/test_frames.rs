//! Frames for the unit tests: a QR code drawn module by module, no blur, at whole pixels.

use crate::raster::GrayImage;

/// A QR code of `text` drawn with its top-left module's corner at pixel (`x0`, `y0`),
/// `module_px` px per module; the quiet zone is whatever surrounds it.
pub(crate) struct DrawnCode {
    /// Modules per side.
    pub(crate) modules: usize,
    colours: Vec<qrcode::Color>,
    pub(crate) module_px: usize,
    pub(crate) x0: usize,
    pub(crate) y0: usize,
}

impl DrawnCode {
    pub(crate) fn new(text: &str, module_px: usize, x0: usize, y0: usize) -> Self {
        let code = qrcode::QrCode::new(text.as_bytes()).expect("a QR code");
        Self {
            modules: code.width(),
            colours: code.to_colors(),
            module_px,
            x0,
            y0,
        }
    }

    /// Whether pixel (x, y) lies on a dark module.
    pub(crate) fn dark(&self, x: usize, y: usize) -> bool {
        let (Some(dx), Some(dy)) = (x.checked_sub(self.x0), y.checked_sub(self.y0)) else {
            return false;
        };
        let (mx, my) = (dx / self.module_px, dy / self.module_px);
        mx < self.modules
            && my < self.modules
            && self.colours[my * self.modules + mx] == qrcode::Color::Dark
    }

    /// A `w` × `h` frame of grey `light` with the code's dark modules in grey `dark`.
    pub(crate) fn frame(&self, w: usize, h: usize, dark: u8, light: u8) -> GrayImage {
        let pixels = (0..w * h)
            .map(|i| if self.dark(i % w, i / w) { dark } else { light })
            .collect();
        GrayImage::new(w, h, pixels).expect("a size")
    }
}
