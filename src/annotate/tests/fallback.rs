//! When the splice is used, and what is drawn when it refuses: JPEGs the `jpeg-overlay`
//! crate cannot splice exactly (its own tests check each refusal's reason) get the
//! whole-frame path's image, decode at the photo's size, and never fail the request.

use super::*;
use crate::annotate::codec;
use crate::annotate::raster::{Style, draw_overlay};
use crate::annotate::{OutputFormat, annotated_with, redrawn};
use jpeg_overlay::Jpeg;

/// Annotating `jpeg` (which decodes to `size_px`) gives a JPEG that decodes to that size.
fn assert_annotated_decodes(jpeg: &[u8], size_px: (usize, usize)) -> Vec<u8> {
    let annotated =
        annotated_with(jpeg, OutputFormat::Jpeg, size_px, |_| overlay()).expect("annotated");
    let decoded = codec::decode_rgb(&annotated).expect("the annotated image decodes");
    assert_eq!((decoded.width_px(), decoded.height_px()), size_px);
    annotated
}

/// Checks that annotating `jpeg` gives the whole-frame path's image, at the photo's size.
fn check_redrawn(jpeg: &[u8], size_px: (usize, usize)) {
    let annotated = assert_annotated_decodes(jpeg, size_px);
    let whole = redrawn(jpeg, OutputFormat::Jpeg, &|_| overlay()).expect("drawn");
    assert_eq!(annotated, whole);
}

#[test]
fn annotating_a_jpeg_splices_it() {
    let jpeg = encode(COLOUR_420, |_| {});
    let annotated = assert_annotated_decodes(&jpeg, SIZE_PX);
    let parsed = Jpeg::parse(&jpeg).expect("spliceable");
    let style = Style::for_image(SIZE_PX.0, SIZE_PX.1);
    let mut drawing = parsed.canvas();
    draw_overlay(&mut drawing, &overlay(), &style);
    assert_eq!(annotated, parsed.splice(&drawing).expect("spliced").bytes);
    // PNG output stays the whole-frame path.
    let png = annotated_with(&jpeg, OutputFormat::Png, SIZE_PX, |_| overlay()).expect("annotated");
    assert_eq!(
        png,
        redrawn(&jpeg, OutputFormat::Png, &|_| overlay()).expect("drawn")
    );
}

#[test]
fn jpegs_the_splice_refuses_are_redrawn_whole() {
    let refused = [
        encode(
            Options {
                grey: true,
                restart: Some(5),
                ..COLOUR_420
            },
            |_| {},
        ),
        encode(COLOUR_420, |e| e.set_progressive(true)),
        // jpeg-encoder writes optimized colour JPEGs as three sequential scans.
        encode(COLOUR_420, |e| e.set_optimized_huffman_tables(true)),
    ];
    for jpeg in &refused {
        assert!(Jpeg::parse(jpeg).is_err());
        check_redrawn(jpeg, SIZE_PX);
    }
    // APP14 "Adobe", version 100, flags 0, 0, transform 0 (RGB).
    let adobe = [
        0xFF, 0xEE, 0, 14, b'A', b'd', b'o', b'b', b'e', 0, 100, 0, 0, 0, 0, 0,
    ];
    let jpeg = encode(COLOUR_420, |_| {});
    check_redrawn(&[&jpeg[..2], &adobe, &jpeg[2..]].concat(), SIZE_PX);
    let cmyk: Vec<u8> = photo(WIDTH, HEIGHT)
        .chunks_exact(3)
        .flat_map(|p| [255 - p[0], 255 - p[1], 255 - p[2], 30])
        .collect();
    let mut jpeg = Vec::new();
    Encoder::new(&mut jpeg, 90)
        .encode(&cmyk, WIDTH, HEIGHT, ColorType::Cmyk)
        .expect("encodes");
    check_redrawn(&jpeg, SIZE_PX);
}

#[test]
fn a_jpeg_whose_splice_fails_part_way_is_redrawn_whole() {
    // Parsed, but the strokes need Huffman codes its optimized tables lack: the splice
    // fails after reading the scan.
    let flat = vec![128_u8; usize::from(WIDTH) * usize::from(HEIGHT)];
    let mut jpeg = Vec::new();
    let mut encoder = Encoder::new(&mut jpeg, 90);
    encoder.set_optimized_huffman_tables(true);
    encoder
        .encode(&flat, WIDTH, HEIGHT, ColorType::Luma)
        .expect("encodes");
    assert!(Jpeg::parse(&jpeg).is_ok());
    check_redrawn(&jpeg, SIZE_PX);
}

#[test]
fn a_jpeg_declaring_another_size_than_the_decoded_one_is_redrawn_whole() {
    // The overlay's coordinates are of the decoded image, and the splice's canvas is sized
    // from the frame header: they must agree, or the whole frame is drawn instead.
    let jpeg = encode(COLOUR_420, |_| {});
    for size_px in [(SIZE_PX.0 + 1, SIZE_PX.1), (SIZE_PX.0, SIZE_PX.1 - 8)] {
        let annotated =
            annotated_with(&jpeg, OutputFormat::Jpeg, size_px, |_| overlay()).expect("annotated");
        let whole = redrawn(&jpeg, OutputFormat::Jpeg, &|_| overlay()).expect("drawn");
        assert_eq!(annotated, whole, "{size_px:?}");
    }
}

/// The files `cargo fuzz` found (fuzz/fuzz_targets/splice.rs, kept as seeds; the
/// `jpeg-overlay` crate's tests say what each is): the service answers each with a JPEG
/// that decodes at the photo's size.
#[test]
fn the_files_the_fuzzer_found_are_annotated_with_jpegs_that_decode() {
    let truncated_app1: &[u8] =
        include_bytes!("../../../fuzz/seeds/splice/crash_truncated_app1_after_scan.jpg");
    check_redrawn(truncated_app1, (80, 48));
    let bad_dht: &[u8] =
        include_bytes!("../../../fuzz/seeds/splice/crash_grey_bad_dht_after_scan.jpg");
    assert_annotated_decodes(bad_dht, (11, 64));
    let without_eoi: &[u8] =
        include_bytes!("../../../fuzz/seeds/splice/crash_grey_without_eoi.jpg");
    assert_annotated_decodes(without_eoi, (11, 49));
}
