//! The annotated image as the service makes it ([`super::annotated_with`]): JPEGs made here
//! with `jpeg-encoder` from generated pixels, a fixed overlay. [`pinned`]: the bytes out,
//! pinned; [`fallback`]: when the splice is used, and what is drawn when it cannot be.

mod fallback;
mod pinned;

use super::overlay::{Label, OUTLINE, Overlay, Rgb, Segment, X_AXIS, Y_AXIS, Z_AXIS};
use jpeg_encoder::{ColorType, Encoder, SamplingFactor};

/// The test photos' width, px.
const WIDTH: u16 = 203;
/// The test photos' height, px.
const HEIGHT: u16 = 141;
/// The test photos' size as the detection's decode reports it, (width, height) px.
const SIZE_PX: (usize, usize) = (WIDTH as usize, HEIGHT as usize);

/// A photo-like RGB frame: smooth shading, edges and a little deterministic noise.
fn photo(width: u16, height: u16) -> Vec<u8> {
    let mut pixels = Vec::with_capacity(usize::from(width) * usize::from(height) * 3);
    for y in 0..u32::from(height) {
        for x in 0..u32::from(width) {
            let noise =
                (x.wrapping_mul(7919) ^ y.wrapping_mul(104_729)).wrapping_mul(2_654_435_761) >> 28;
            let edge = if (x / 23 + y / 19) % 3 == 0 {
                50.0
            } else {
                0.0
            };
            let (fx, fy) = (f64::from(x), f64::from(y));
            let channel = |phase: f64| {
                let v = 110.0
                    + 60.0 * (fx / 17.0 + phase).sin() * (fy / 23.0).cos()
                    + edge
                    + f64::from(noise);
                // Clamped to 0-255 and rounded: the cast cannot truncate.
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let byte = v.clamp(0.0, 255.0).round() as u8;
                byte
            };
            pixels.extend([channel(0.0), channel(1.0), channel(2.0)]);
        }
    }
    pixels
}

/// How a test JPEG is encoded.
#[derive(Debug, Clone, Copy)]
struct Options {
    sampling: SamplingFactor,
    grey: bool,
    restart: Option<u16>,
    quality: u8,
}

/// Colour, 4:2:0, quality 90, no restart markers.
const COLOUR_420: Options = Options {
    sampling: SamplingFactor::F_2_2,
    grey: false,
    restart: None,
    quality: 90,
};

/// [`photo`] encoded with `options`, after `configure` set anything else.
fn encode(options: Options, configure: impl FnOnce(&mut Encoder<&mut Vec<u8>>)) -> Vec<u8> {
    let rgb = photo(WIDTH, HEIGHT);
    let mut out = Vec::new();
    let mut encoder = Encoder::new(&mut out, options.quality);
    encoder.set_sampling_factor(options.sampling);
    if let Some(interval) = options.restart {
        encoder.set_restart_interval(interval);
    }
    configure(&mut encoder);
    if options.grey {
        let luma: Vec<u8> = rgb
            .chunks_exact(3)
            .map(|p| {
                u8::try_from((u16::from(p[0]) + u16::from(p[1]) + u16::from(p[2])) / 3)
                    .expect("a mean of bytes")
            })
            .collect();
        encoder
            .encode(&luma, WIDTH, HEIGHT, ColorType::Luma)
            .expect("encodes");
    } else {
        encoder
            .encode(&rgb, WIDTH, HEIGHT, ColorType::Rgb)
            .expect("encodes");
    }
    out
}

/// Strokes 3 px wide in every direction, a label and corner marks, some at the frame's
/// right and bottom edges (partial MCUs), none in the top rows nor in the last MCU (so
/// that the scan goes on after the last re-encoded MCU).
fn overlay() -> Overlay {
    let segment = |from_px: [f64; 2], to_px: [f64; 2], colour: Rgb| Segment {
        from_px,
        to_px,
        colour,
    };
    Overlay {
        segments: vec![
            segment([40.0, 60.0], [160.0, 70.0], OUTLINE),
            segment([160.0, 70.0], [150.0, 130.0], OUTLINE),
            segment([100.0, 100.0], [190.0, 100.0], X_AXIS),
            segment([100.0, 100.0], [100.0, 40.0], Y_AXIS),
            segment([100.0, 100.0], [60.0, 139.0], Z_AXIS),
            segment([195.0, 50.0], [202.0, 110.0], X_AXIS),
        ],
        labels: vec![Label {
            anchor_px: [30.0, 58.0],
            below: false,
            text: "SKU-1".to_owned(),
        }],
        corner_marks_px: vec![[40.0, 60.0], [160.0, 70.0], [201.0, 100.0]],
    }
}
