//! The annotated JPEG's splice (`qrpose::annotate::jpeg_splice`) on arbitrary bytes: the
//! client's JPEG is parsed and its entropy-coded data re-read and rewritten, so it must
//! never panic, and a file it splices must still decode when the original did (the service
//! returns the spliced bytes as they are).
#![no_main]

use libfuzzer_sys::fuzz_target;
use qrpose::annotate::jpeg_splice::Jpeg;
use qrpose::annotate::overlay::{
    Label, OUTLINE, Overlay, Segment, X_AXIS, Y_AXIS, Z_AXIS,
};
use qrpose::annotate::raster::{Style, draw_overlay};
use qrpose_detect::decode::{DecodeLimits, decode_gray};

/// Small limits, so that a declared size cannot make the fuzzer allocate gigabytes (the
/// service splices only frames its decoder accepted, within its pixel limit).
const LIMITS: DecodeLimits = DecodeLimits {
    max_encoded_bytes: 1 << 20,
    max_pixels: 1 << 20,
};

/// Every kind of mark the service draws, placed relative to the frame's size: strokes in
/// each direction, some past the edges, a label and corner marks.
fn overlay(width_px: f64, height_px: f64) -> Overlay {
    let at = |u: f64, v: f64| [u * width_px, v * height_px];
    let segment = |from_px, to_px, colour| Segment {
        from_px,
        to_px,
        colour,
    };
    Overlay {
        segments: vec![
            segment(at(0.2, 0.3), at(0.8, 0.35), OUTLINE),
            segment(at(0.8, 0.35), at(0.75, 1.2), OUTLINE),
            segment(at(0.5, 0.5), at(0.9, 0.5), X_AXIS),
            segment(at(0.5, 0.5), at(0.5, -0.1), Y_AXIS),
            segment(at(0.5, 0.5), at(0.3, 0.7), Z_AXIS),
        ],
        labels: vec![Label {
            anchor_px: at(0.1, 0.25),
            below: false,
            text: "SKU-1".to_owned(),
        }],
        corner_marks_px: vec![at(0.2, 0.3), at(0.8, 0.35), [0.0, 0.0]],
    }
}

fuzz_target!(|bytes: &[u8]| {
    let Ok(jpeg) = Jpeg::parse(bytes) else {
        return;
    };
    let (width_px, height_px) = (jpeg.width_px(), jpeg.height_px());
    if width_px * height_px > LIMITS.max_pixels as usize {
        return;
    }
    let style = Style::for_image(width_px, height_px);
    let mut drawing = jpeg.canvas();
    draw_overlay(
        &mut drawing,
        &overlay(width_px as f64, height_px as f64),
        &style,
    );
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
