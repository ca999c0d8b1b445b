//! The marks the tests draw, pixel by pixel, as the qrpose service's overlay draws them
//! (its `annotate::raster`): strokes with flat caps, labels in the 8 × 8 font on a box,
//! hollow squares on corners. Solid colours, no anti-aliasing, so that every written pixel
//! has exactly its mark's colour.

// Pixel coordinates are rounded and clamped into the frame before every cast.
#![allow(clippy::cast_possible_truncation)]

use font8x8::legacy::BASIC_LEGACY;

/// The service's outline colour.
pub const OUTLINE: [u8; 3] = [255, 255, 0];
/// The service's x-axis colour.
pub const X_AXIS: [u8; 3] = [255, 0, 0];
/// The service's y-axis colour.
pub const Y_AXIS: [u8; 3] = [0, 255, 0];
/// The service's z-axis colour.
pub const Z_AXIS: [u8; 3] = [0, 0, 255];
/// The service's corner-mark colour.
pub const CORNER_MARK: [u8; 3] = [255, 0, 255];
/// The service's label text colour.
const LABEL_TEXT: [u8; 3] = [255, 255, 255];
/// The service's label box colour.
const LABEL_BOX: [u8; 3] = [0, 0, 0];

/// One recorded pixel write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelWrite {
    /// Column, px.
    pub x: u32,
    /// Row, px.
    pub y: u32,
    /// The colour written, (R, G, B).
    pub colour: [u8; 3],
}

/// The writes of a drawing, in order: which pixels the marks set, and to what. Writes
/// outside the canvas are dropped; of several writes to one pixel the last one counts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PixelWrites {
    width_px: usize,
    height_px: usize,
    writes: Vec<PixelWrite>,
}

impl PixelWrites {
    /// No writes yet on a `width_px` × `height_px` canvas.
    pub fn new(width_px: usize, height_px: usize) -> Self {
        Self {
            width_px,
            height_px,
            writes: Vec::new(),
        }
    }

    /// The writes, in drawing order.
    pub fn writes(&self) -> &[PixelWrite] {
        &self.writes
    }

    /// Records pixel (x, y) set to `colour` when it lies inside the canvas.
    pub fn put(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        let (Ok(x), Ok(y)) = (u32::try_from(x), u32::try_from(y)) else {
            return;
        };
        if (x as usize) < self.width_px && (y as usize) < self.height_px {
            self.writes.push(PixelWrite { x, y, colour });
        }
    }

    /// Every pixel whose centre lies within `width_px / 2` of the segment from `from_px`
    /// to `to_px`, measured perpendicular to it, between its two ends.
    pub fn segment(&mut self, from_px: [f64; 2], to_px: [f64; 2], width_px: f64, colour: [u8; 3]) {
        let ([x0, y0], [x1, y1]) = (from_px, to_px);
        let half = width_px / 2.0;
        let (dx, dy) = (x1 - x0, y1 - y0);
        let length_sq = dx * dx + dy * dy;
        let bounds = |a: f64, b: f64, size: usize| {
            let low = (a.min(b) - half).floor().max(0.0);
            let high = (a.max(b) + half).ceil().min(size as f64 - 1.0);
            (low as i64, high as i64)
        };
        let (x_low, x_high) = bounds(x0, x1, self.width_px);
        let (y_low, y_high) = bounds(y0, y1, self.height_px);
        for y in y_low..=y_high {
            for x in x_low..=x_high {
                let (px, py) = (x as f64 - x0, y as f64 - y0);
                let t = if length_sq > 0.0 {
                    (px * dx + py * dy) / length_sq
                } else {
                    0.0
                };
                if (0.0..=1.0).contains(&t) && (px - t * dx).hypot(py - t * dy) <= half {
                    self.put(x, y, colour);
                }
            }
        }
    }

    /// A hollow square `2 half_side + 1` px across with sides `thickness` px thick,
    /// centred on the pixel nearest `at_px`.
    pub fn corner_mark(&mut self, at_px: [f64; 2], half_side: i64, thickness: i64) {
        let (cx, cy) = (at_px[0].round() as i64, at_px[1].round() as i64);
        let inner = half_side - thickness;
        for dy in -half_side..=half_side {
            for dx in -half_side..=half_side {
                if dx.abs().max(dy.abs()) > inner {
                    self.put(cx + dx, cy + dy, CORNER_MARK);
                }
            }
        }
    }

    /// `text` (ASCII) in white on a black box whose bottom-left corner is `anchor_px`,
    /// one pixel per font pixel, the text 2 px inside the box.
    pub fn label(&mut self, anchor_px: [f64; 2], text: &str) {
        let chars = text.chars().count() as i64;
        let (box_width, box_height) = (chars * 8 + 4, 12);
        let left = anchor_px[0].round() as i64;
        let top = anchor_px[1].round() as i64 - box_height;
        for y in top..top + box_height {
            for x in left..left + box_width {
                self.put(x, y, LABEL_BOX);
            }
        }
        for (k, c) in (0_i64..).zip(text.chars()) {
            let glyph = BASIC_LEGACY.get(c as usize).copied().unwrap_or_default();
            for (row, bits) in (0_i64..).zip(glyph) {
                for column in 0..8 {
                    // font8x8: bit n of a row is column n.
                    if bits >> column & 1 == 1 {
                        self.put(left + 2 + k * 8 + column, top + 2 + row, LABEL_TEXT);
                    }
                }
            }
        }
    }
}
