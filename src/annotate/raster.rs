//! Draws an [`Overlay`] onto an 8-bit RGB raster: solid colours, no anti-aliasing, so that
//! every drawn pixel has exactly its primitive's colour (the pixel tests rely on it).
//!
//! Sizes grow with the image ([`Style::for_image`]) so the overlay reads the same on a phone
//! frame and a 4K one. Pixel coordinates follow docs/conventions.md, Pixels: integer
//! coordinates are pixel centres.

// Pixel coordinates are rounded and clamped into the raster before every cast.
#![allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]

use super::overlay::{CORNER_MARK, LABEL_BOX, LABEL_TEXT, Label, Overlay, Rgb, Segment};
use font8x8::legacy::BASIC_LEGACY;

/// A row-major RGB raster, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbRaster {
    width_px: usize,
    height_px: usize,
    pixels: Vec<u8>,
}

impl RgbRaster {
    /// A raster over `pixels` (row-major RGB); `None` when the length does not match.
    pub fn new(width_px: usize, height_px: usize, pixels: Vec<u8>) -> Option<Self> {
        (width_px.checked_mul(height_px)?.checked_mul(3)? == pixels.len()).then_some(Self {
            width_px,
            height_px,
            pixels,
        })
    }

    /// Width, px.
    pub fn width_px(&self) -> usize {
        self.width_px
    }

    /// Height, px.
    pub fn height_px(&self) -> usize {
        self.height_px
    }

    /// The pixels, row-major RGB.
    pub fn pixels(&self) -> &[u8] {
        &self.pixels
    }

    /// The pixels, owned.
    pub fn into_pixels(self) -> Vec<u8> {
        self.pixels
    }

    /// Sets pixel (x, y) when it lies inside the raster.
    fn put(&mut self, x: i64, y: i64, colour: Rgb) {
        if x < 0 || y < 0 || x as usize >= self.width_px || y as usize >= self.height_px {
            return;
        }
        let at = (y as usize * self.width_px + x as usize) * 3;
        self.pixels[at..at + 3].copy_from_slice(&colour.0);
    }
}

/// Line width, mark size and text scale for one image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Style {
    /// Width of outline and axis strokes, px.
    pub stroke_px: f64,
    /// Half the side of a corner mark's square, px.
    pub mark_half_side_px: i64,
    /// Thickness of a corner mark's square, px.
    pub mark_thickness_px: i64,
    /// Pixels per font pixel (the font is 8 × 8).
    pub text_scale: i64,
}

/// The image side (the shorter one, px) over which the style grows by one step.
const STYLE_STEP_PX: usize = 360;
/// Font cell side, font pixels.
const GLYPH_PX: i64 = 8;
/// Padding around a label's text, font pixels.
const LABEL_PADDING: i64 = 2;

impl Style {
    /// The style for a `width_px` × `height_px` image: 3 px strokes, 11 px marks and 16 px
    /// text at 720 p, one step more per 360 px of the shorter side.
    pub fn for_image(width_px: usize, height_px: usize) -> Self {
        let steps = (width_px.min(height_px) / STYLE_STEP_PX).clamp(1, 8) as i64;
        Self {
            stroke_px: (steps + 1) as f64,
            mark_half_side_px: 3 + steps,
            mark_thickness_px: steps,
            text_scale: steps,
        }
    }

    /// A label's height, px.
    pub fn label_height_px(&self) -> f64 {
        ((GLYPH_PX + 2 * LABEL_PADDING) * self.text_scale) as f64
    }
}

/// Draws `overlay` onto `raster`: segments, then labels, then corner marks.
pub fn draw_overlay(raster: &mut RgbRaster, overlay: &Overlay, style: &Style) {
    for segment in &overlay.segments {
        draw_segment(raster, segment, style.stroke_px);
    }
    for label in &overlay.labels {
        draw_label(raster, label, style.text_scale);
    }
    for at in &overlay.corner_marks_px {
        draw_corner_mark(raster, *at, style);
    }
}

/// Every pixel whose centre lies within `width_px / 2` of the segment, measured
/// perpendicular to it, between its two ends (flat caps: the stroke ends where the segment
/// does).
pub fn draw_segment(raster: &mut RgbRaster, segment: &Segment, width_px: f64) {
    let [x0, y0] = segment.from_px;
    let [x1, y1] = segment.to_px;
    if ![x0, y0, x1, y1].iter().all(|c| c.is_finite()) {
        return;
    }
    let half = width_px / 2.0;
    let (dx, dy) = (x1 - x0, y1 - y0);
    let length_sq = dx * dx + dy * dy;
    let bounds = |a: f64, b: f64, size: usize| {
        let low = (a.min(b) - half).floor().max(0.0);
        let high = (a.max(b) + half).ceil().min(size as f64 - 1.0);
        (low as i64, high as i64)
    };
    let (x_low, x_high) = bounds(x0, x1, raster.width_px);
    let (y_low, y_high) = bounds(y0, y1, raster.height_px);
    for y in y_low..=y_high {
        for x in x_low..=x_high {
            let (px, py) = (x as f64 - x0, y as f64 - y0);
            let t = if length_sq > 0.0 {
                (px * dx + py * dy) / length_sq
            } else {
                0.0
            };
            if !(0.0..=1.0).contains(&t) {
                continue;
            }
            let distance = (px - t * dx).hypot(py - t * dy);
            if distance <= half {
                raster.put(x, y, segment.colour);
            }
        }
    }
}

/// A hollow square centred on the pixel nearest `at_px`, so the corner itself stays visible.
pub fn draw_corner_mark(raster: &mut RgbRaster, at_px: [f64; 2], style: &Style) {
    if !at_px.iter().all(|c| c.is_finite()) {
        return;
    }
    let (cx, cy) = (at_px[0].round() as i64, at_px[1].round() as i64);
    let outer = style.mark_half_side_px;
    let inner = outer - style.mark_thickness_px;
    for dy in -outer..=outer {
        for dx in -outer..=outer {
            if dx.abs().max(dy.abs()) > inner {
                raster.put(cx + dx, cy + dy, CORNER_MARK);
            }
        }
    }
}

/// The 8 × 8 glyph of an ASCII character; `?` for anything else.
fn glyph(c: char) -> [u8; 8] {
    let index = if c.is_ascii() && !c.is_ascii_control() {
        c as usize
    } else {
        '?' as usize
    };
    BASIC_LEGACY[index]
}

/// The label's text, white on a black box, `scale` px per font pixel.
pub fn draw_label(raster: &mut RgbRaster, label: &Label, scale: i64) {
    if !label.anchor_px.iter().all(|c| c.is_finite()) {
        return;
    }
    let chars = label.text.chars().count() as i64;
    let box_width = (chars * GLYPH_PX + 2 * LABEL_PADDING) * scale;
    let box_height = (GLYPH_PX + 2 * LABEL_PADDING) * scale;
    let left = label.anchor_px[0].round() as i64;
    let top = if label.below {
        label.anchor_px[1].round() as i64
    } else {
        label.anchor_px[1].round() as i64 - box_height
    };
    for y in top..top + box_height {
        for x in left..left + box_width {
            raster.put(x, y, LABEL_BOX);
        }
    }
    let origin_x = left + LABEL_PADDING * scale;
    let origin_y = top + LABEL_PADDING * scale;
    for (k, c) in (0_i64..).zip(label.text.chars()) {
        for (row, bits) in (0_i64..).zip(glyph(c)) {
            for column in 0..GLYPH_PX {
                // font8x8: bit n of a row is column n, least significant bit leftmost.
                if bits >> column & 1 == 0 {
                    continue;
                }
                let x = origin_x + (k * GLYPH_PX + column) * scale;
                let y = origin_y + row * scale;
                for sy in 0..scale {
                    for sx in 0..scale {
                        raster.put(x + sx, y + sy, LABEL_TEXT);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::annotate::overlay::X_AXIS;

    fn blank(width_px: usize, height_px: usize) -> RgbRaster {
        RgbRaster::new(width_px, height_px, vec![0; width_px * height_px * 3]).expect("sized")
    }

    fn coloured(raster: &RgbRaster, colour: Rgb) -> Vec<(usize, usize)> {
        let w = raster.width_px();
        raster
            .pixels()
            .chunks_exact(3)
            .enumerate()
            .filter(|(_, p)| *p == colour.0)
            .map(|(i, _)| (i % w, i / w))
            .collect()
    }

    #[test]
    fn a_horizontal_stroke_covers_its_width_and_stops_at_its_ends() {
        let mut raster = blank(40, 20);
        let segment = Segment {
            from_px: [5.0, 10.0],
            to_px: [30.0, 10.0],
            colour: X_AXIS,
        };
        draw_segment(&mut raster, &segment, 3.0);
        let pixels = coloured(&raster, X_AXIS);
        assert_eq!(pixels.len(), 26 * 3, "rows 9..=11, columns 5..=30");
        assert!(
            pixels
                .iter()
                .all(|&(x, y)| (5..=30).contains(&x) && (9..=11).contains(&y))
        );
    }

    #[test]
    fn a_corner_mark_is_centred_on_its_corner_and_clipped_at_the_border() {
        let mut raster = blank(30, 30);
        let style = Style::for_image(1280, 720);
        draw_corner_mark(&mut raster, [10.4, 12.6], &style);
        let pixels = coloured(&raster, CORNER_MARK);
        let n = pixels.len() as f64;
        let mean_x = pixels.iter().map(|p| p.0 as f64).sum::<f64>() / n;
        let mean_y = pixels.iter().map(|p| p.1 as f64).sum::<f64>() / n;
        assert_eq!((mean_x, mean_y), (10.0, 13.0));
        draw_corner_mark(&mut raster, [-100.0, 0.0], &style);
        draw_corner_mark(&mut raster, [f64::NAN, 0.0], &style);
    }

    #[test]
    fn a_label_draws_text_inside_its_box() {
        let mut raster = blank(200, 40);
        let label = Label {
            anchor_px: [4.0, 30.0],
            below: false,
            text: "SKU-1é".to_owned(),
        };
        draw_label(&mut raster, &label, 2);
        let text = coloured(&raster, LABEL_TEXT);
        assert!(!text.is_empty());
        let box_width = (6 * 8 + 4) * 2;
        assert!(
            text.iter()
                .all(|&(x, y)| (4..4 + box_width).contains(&x) && (6..30).contains(&y))
        );
    }

    #[test]
    fn the_style_grows_with_the_image() {
        let small = Style::for_image(640, 480);
        let large = Style::for_image(3840, 2160);
        assert!(large.stroke_px > small.stroke_px);
        assert!(large.label_height_px() > small.label_height_px());
    }
}
