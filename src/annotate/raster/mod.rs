//! Draws an [`Overlay`] onto a [`Canvas`]: an 8-bit RGB raster ([`RgbRaster`]), or a record of
//! the pixels written MCU by MCU ([`jpeg_overlay::Drawing`], for re-encoding only the JPEG
//! blocks they touch). Solid colours, no anti-aliasing, so that every drawn pixel has
//! exactly its primitive's colour (the pixel tests rely on it).
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
}

/// Where the drawing functions put their pixels: a raster, or a record of the writes.
pub trait Canvas {
    /// Width, px.
    fn width_px(&self) -> usize;
    /// Height, px.
    fn height_px(&self) -> usize;
    /// Sets pixel (x, y) to `colour` when it lies inside the canvas; a later write to the same
    /// pixel wins.
    fn put(&mut self, x: i64, y: i64, colour: Rgb);

    /// Sets the pixels `from..to` of row `y` that lie inside the canvas to `colour`, as
    /// [`Self::put`] on each, left to right.
    fn put_row(&mut self, from: i64, to: i64, y: i64, colour: Rgb) {
        for x in from..to {
            self.put(x, y, colour);
        }
    }
}

/// The pixel (x, y) of a `width_px` × `height_px` canvas, when it lies inside.
fn inside(x: i64, y: i64, width_px: usize, height_px: usize) -> Option<(usize, usize)> {
    let (x, y) = (usize::try_from(x).ok()?, usize::try_from(y).ok()?);
    (x < width_px && y < height_px).then_some((x, y))
}

impl Canvas for RgbRaster {
    fn width_px(&self) -> usize {
        self.width_px
    }

    fn height_px(&self) -> usize {
        self.height_px
    }

    fn put(&mut self, x: i64, y: i64, colour: Rgb) {
        let Some((x, y)) = inside(x, y, self.width_px, self.height_px) else {
            return;
        };
        let at = (y * self.width_px + x) * 3;
        if let Some(pixel) = self.pixels.get_mut(at..at + 3) {
            pixel.copy_from_slice(&colour.0);
        }
    }

    fn put_row(&mut self, from: i64, to: i64, y: i64, colour: Rgb) {
        let from = from.clamp(0, self.width_px as i64);
        let to = to.clamp(from, self.width_px as i64);
        let Some((_, y)) = inside(0, y, 1, self.height_px) else {
            return;
        };
        let row = y * self.width_px;
        let span = (row + from as usize) * 3..(row + to as usize) * 3;
        if let Some(pixels) = self.pixels.get_mut(span) {
            for pixel in pixels.chunks_exact_mut(3) {
                pixel.copy_from_slice(&colour.0);
            }
        }
    }
}

/// The splice's canvas: the same writes, recorded MCU by MCU.
impl Canvas for jpeg_overlay::Drawing {
    fn width_px(&self) -> usize {
        jpeg_overlay::Drawing::width_px(self)
    }

    fn height_px(&self) -> usize {
        jpeg_overlay::Drawing::height_px(self)
    }

    fn put(&mut self, x: i64, y: i64, colour: Rgb) {
        jpeg_overlay::Drawing::put(self, x, y, colour.0);
    }

    fn put_row(&mut self, from: i64, to: i64, y: i64, colour: Rgb) {
        jpeg_overlay::Drawing::put_row(self, from, to, y, colour.0);
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

/// Draws `overlay` onto `raster` (or records it): segments, then labels, then corner marks.
pub fn draw_overlay(raster: &mut impl Canvas, overlay: &Overlay, style: &Style) {
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
pub fn draw_segment(raster: &mut impl Canvas, segment: &Segment, width_px: f64) {
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
    let (x_low, x_high) = bounds(x0, x1, raster.width_px());
    let (y_low, y_high) = bounds(y0, y1, raster.height_px());
    for y in y_low..=y_high {
        let (from, to) = row_span(segment, half, y as f64).map_or((x_low, x_high), |(a, b)| {
            (
                a.floor().max(x_low as f64) as i64,
                b.ceil().min(x_high as f64) as i64,
            )
        });
        // Runs of pixels within the stroke, each written at once.
        let mut run: Option<i64> = None;
        for x in from..=to {
            let (px, py) = (x as f64 - x0, y as f64 - y0);
            let t = if length_sq > 0.0 {
                (px * dx + py * dy) / length_sq
            } else {
                0.0
            };
            let within = (0.0..=1.0).contains(&t) && near(px - t * dx, py - t * dy, half);
            match (within, run) {
                (true, None) => run = Some(x),
                (false, Some(start)) => {
                    raster.put_row(start, x, y, segment.colour);
                    run = None;
                }
                _ => {}
            }
        }
        if let Some(start) = run {
            raster.put_row(start, to + 1, y, segment.colour);
        }
    }
}

/// Whether the vector (dx, dy) is at most `half` long, as `dx.hypot(dy) <= half` decides it;
/// the squared length settles all but the lengths within a hair of `half`, without hypot.
fn near(dx: f64, dy: f64, half: f64) -> bool {
    let (squared, limit) = (dx * dx + dy * dy, half * half);
    if squared < limit * (1.0 - 1e-9) {
        true
    } else if squared > limit * (1.0 + 1e-9) {
        false
    } else {
        dx.hypot(dy) <= half
    }
}

/// The columns of row `y` worth testing for the stroke of `segment` (half width `half`),
/// as a superset: the stroke grown by 1 px on every side, cut by the row. `None` (test the
/// whole row) for a segment under 1 px long; an empty span (start after end) when the row
/// misses the grown stroke.
fn row_span(segment: &Segment, half: f64, y: f64) -> Option<(f64, f64)> {
    let [x0, y0] = segment.from_px;
    let (dx, dy) = (segment.to_px[0] - x0, segment.to_px[1] - y0);
    let length = dx.hypot(dy);
    if length < 1.0 {
        return None;
    }
    let py = y - y0;
    // Along the segment: -L ≤ px·dx + py·dy ≤ L² + L; across: |px·dy − py·dx| ≤ (half + 1)·L.
    let along = (-length - py * dy, length * length + length - py * dy);
    let across = (
        -(half + 1.0) * length + py * dx,
        (half + 1.0) * length + py * dx,
    );
    // Each as an interval of px, from a·px within (low, high).
    let solve = |a: f64, (low, high): (f64, f64)| {
        if a == 0.0 {
            if low <= 0.0 && 0.0 <= high {
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                (f64::INFINITY, f64::NEG_INFINITY)
            }
        } else {
            let (p, q) = (low / a, high / a);
            (p.min(q), p.max(q))
        }
    };
    let (a_low, a_high) = solve(dx, along);
    let (c_low, c_high) = solve(dy, across);
    Some((x0 + a_low.max(c_low), x0 + a_high.min(c_high)))
}

/// A hollow square centred on the pixel nearest `at_px`, so the corner itself stays visible.
pub fn draw_corner_mark(raster: &mut impl Canvas, at_px: [f64; 2], style: &Style) {
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
pub fn draw_label(raster: &mut impl Canvas, label: &Label, scale: i64) {
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
        raster.put_row(left, left + box_width, y, LABEL_BOX);
    }
    let origin_x = left + LABEL_PADDING * scale;
    let origin_y = top + LABEL_PADDING * scale;
    for (k, c) in (0_i64..).zip(label.text.chars()) {
        for (row, bits) in (0_i64..).zip(glyph(c)) {
            // font8x8: bit n of a row is column n, least significant bit leftmost. Each run
            // of set bits is written a pixel row at a time.
            let mut rest = u32::from(bits);
            while rest != 0 {
                let start = i64::from(rest.trailing_zeros());
                let length = i64::from((rest >> start).trailing_ones());
                rest &= !(((1_u32 << length) - 1) << start);
                let x = origin_x + (k * GLYPH_PX + start) * scale;
                let y = origin_y + row * scale;
                for sy in 0..scale {
                    raster.put_row(x, x + length * scale, y + sy, LABEL_TEXT);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
