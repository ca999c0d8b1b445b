//! The JPEG splice (the `jpeg-overlay` crate, crates/jpeg-overlay) on arbitrary bytes: the
//! file is parsed and its entropy-coded data re-read and rewritten, so it must never panic,
//! and a file it splices must still decode (with the service's decoder) when the original
//! did: the service returns the spliced bytes as they are.
#![no_main]

use jpeg_overlay::{Drawing, Jpeg};
use libfuzzer_sys::fuzz_target;
use qrpose_detect::decode::{DecodeLimits, decode_gray};

/// Small limits, so that a declared size cannot make the fuzzer allocate gigabytes (the
/// service splices only frames its decoder accepted, within its pixel limit).
const LIMITS: DecodeLimits = DecodeLimits {
    max_encoded_bytes: 1 << 20,
    max_pixels: 1 << 20,
};

/// The service's overlay colours: outline, axes, corner marks, label text and box.
const OUTLINE: [u8; 3] = [255, 255, 0];
const X_AXIS: [u8; 3] = [255, 0, 0];
const Y_AXIS: [u8; 3] = [0, 255, 0];
const Z_AXIS: [u8; 3] = [0, 0, 255];
const CORNER_MARK: [u8; 3] = [255, 0, 255];
const LABEL_TEXT: [u8; 3] = [255, 255, 255];
const LABEL_BOX: [u8; 3] = [0, 0, 0];

/// A stroke `width` px wide from `from` to `to` (px), as squares every half pixel along it.
fn stroke(drawing: &mut Drawing, from: [f64; 2], to: [f64; 2], width: i64, colour: [u8; 3]) {
    let steps = ((to[0] - from[0]).hypot(to[1] - from[1]) * 2.0).ceil().min(1e5) as i64;
    for k in 0..=steps {
        let t = k as f64 / steps.max(1) as f64;
        let x = (from[0] + t * (to[0] - from[0])).round() as i64;
        let y = (from[1] + t * (to[1] - from[1])).round() as i64;
        for dy in 0..width {
            drawing.put_row(x - width / 2, x - width / 2 + width, y - width / 2 + dy, colour);
        }
    }
}

/// A hollow square 9 px across, 1 px thick, centred on `at` (px).
fn corner_mark(drawing: &mut Drawing, at: [f64; 2]) {
    let (x, y) = (at[0].round() as i64, at[1].round() as i64);
    drawing.put_row(x - 4, x + 5, y - 4, CORNER_MARK);
    drawing.put_row(x - 4, x + 5, y + 4, CORNER_MARK);
    for dy in -3..=3 {
        drawing.put(x - 4, y + dy, CORNER_MARK);
        drawing.put(x + 4, y + dy, CORNER_MARK);
    }
}

/// A label: a black box, `text`'s bits as white pixels in it (8 per character and row, as
/// dense as the service's bitmap font).
fn label(drawing: &mut Drawing, bottom_left: [f64; 2], text: &[u8]) {
    let (left, bottom) = (bottom_left[0].round() as i64, bottom_left[1].round() as i64);
    let width = 8 * text.len() as i64 + 4;
    for y in bottom - 12..bottom {
        drawing.put_row(left, left + width, y, LABEL_BOX);
    }
    for row in 0..8_i64 {
        for (k, &c) in (0_i64..).zip(text) {
            let bits = c.rotate_left(row as u32);
            for column in 0..8 {
                if bits >> column & 1 == 1 {
                    drawing.put(left + 2 + 8 * k + column, bottom - 10 + row, LABEL_TEXT);
                }
            }
        }
    }
}

/// Every kind of mark the service draws, placed relative to the frame's size: strokes in
/// each direction, some past the edges, a label and corner marks.
fn draw(drawing: &mut Drawing) {
    let (width_px, height_px) = (drawing.width_px() as f64, drawing.height_px() as f64);
    let at = |u: f64, v: f64| [u * width_px, v * height_px];
    let width = (width_px.min(height_px) / 360.0).clamp(1.0, 8.0) as i64 + 1;
    stroke(drawing, at(0.2, 0.3), at(0.8, 0.35), width, OUTLINE);
    stroke(drawing, at(0.8, 0.35), at(0.75, 1.2), width, OUTLINE);
    stroke(drawing, at(0.5, 0.5), at(0.9, 0.5), width, X_AXIS);
    stroke(drawing, at(0.5, 0.5), at(0.5, -0.1), width, Y_AXIS);
    stroke(drawing, at(0.5, 0.5), at(0.3, 0.7), width, Z_AXIS);
    label(drawing, at(0.1, 0.25), b"SKU-1");
    for mark in [at(0.2, 0.3), at(0.8, 0.35), [0.0, 0.0]] {
        corner_mark(drawing, mark);
    }
}

fuzz_target!(|bytes: &[u8]| {
    let Ok(jpeg) = Jpeg::parse(bytes) else {
        return;
    };
    if jpeg.width_px() * jpeg.height_px() > LIMITS.max_pixels as usize {
        return;
    }
    let mut drawing = jpeg.canvas();
    draw(&mut drawing);
    let Ok(spliced) = jpeg.splice(&drawing) else {
        return;
    };
    if let Ok(original) = decode_gray(bytes, &LIMITS) {
        let annotated = decode_gray(&spliced.bytes, &LIMITS)
            .expect("a JPEG that decoded still decodes once spliced");
        assert_eq!(
            (annotated.width(), annotated.height()),
            (original.width(), original.height())
        );
    }
});
