//! What the splice refuses, and why. Broken data is refused without a panic. (The qrpose
//! service's tests check that what is refused is drawn on the decoded frame instead.)

use super::*;
use jpeg_encoder::{ColorType, Encoder};

/// Checks that `jpeg` decodes (both decoders, at its size) and that the splice refuses it
/// with `reason`.
fn check_fallback(jpeg: &[u8], reason: CannotSplice) {
    for decoded in decode_both(jpeg) {
        assert_eq!(
            (decoded.width_px, decoded.height_px),
            (usize::from(WIDTH), usize::from(HEIGHT))
        );
    }
    let refused = Jpeg::parse(jpeg).and_then(|j| j.splice(&drawing(&j, &writes())));
    assert_eq!(refused.err(), Some(reason));
}

/// `jpeg` with `segment` (marker included) inserted after SOI.
fn with_segment(jpeg: &[u8], segment: &[u8]) -> Vec<u8> {
    [&jpeg[..2], segment, &jpeg[2..]].concat()
}

#[test]
fn a_grey_jpeg_with_restart_markers_falls_back() {
    let jpeg = encode(
        Options {
            grey: true,
            restart: Some(5),
            ..COLOUR_420
        },
        |_| {},
    );
    check_fallback(&jpeg, CannotSplice::GreyWithRestarts);
}

#[test]
fn a_progressive_jpeg_falls_back() {
    let jpeg = encode(COLOUR_420, |e| e.set_progressive(true));
    check_fallback(&jpeg, CannotSplice::Progressive);
}

#[test]
fn an_adobe_rgb_jpeg_falls_back() {
    let jpeg = encode(COLOUR_420, |_| {});
    // APP14 "Adobe", version 100, flags 0, 0, transform 0 (RGB).
    let adobe = [
        0xFF, 0xEE, 0, 14, b'A', b'd', b'o', b'b', b'e', 0, 100, 0, 0, 0, 0, 0,
    ];
    let rgb = with_segment(&jpeg, &adobe);
    assert_eq!(Jpeg::parse(&rgb).err(), Some(CannotSplice::NotYcbcr));
    // Transform 1 (YCbCr) is spliced.
    let mut ycc = adobe;
    ycc[15] = 1;
    assert!(Jpeg::parse(&with_segment(&jpeg, &ycc)).is_ok());
}

#[test]
fn a_jpeg_with_rgb_component_ids_falls_back() {
    let mut jpeg = encode(COLOUR_420, |_| {});
    let headers = Jpeg::parse(&jpeg).expect("parses").headers;
    // SOF: marker, length, precision, height, width, count, then id, factors, table each.
    for (k, id) in [b'R', b'G', b'B'].into_iter().enumerate() {
        jpeg[headers.sof.start + 10 + 3 * k] = id;
        jpeg[headers.sos.start + 5 + 2 * k] = id;
    }
    check_fallback(&jpeg, CannotSplice::NotYcbcr);
}

#[test]
fn a_cmyk_jpeg_falls_back() {
    let cmyk: Vec<u8> = photo(WIDTH, HEIGHT)
        .chunks_exact(3)
        .flat_map(|p| [255 - p[0], 255 - p[1], 255 - p[2], 30])
        .collect();
    let mut jpeg = Vec::new();
    Encoder::new(&mut jpeg, 90)
        .encode(&cmyk, WIDTH, HEIGHT, ColorType::Cmyk)
        .expect("encodes");
    check_fallback(&jpeg, CannotSplice::Components(4));
}

#[test]
fn optimized_tables_lacking_a_needed_code_fall_back() {
    // A flat frame needs few codes; strokes across it need more than its tables have.
    let flat = vec![128_u8; usize::from(WIDTH) * usize::from(HEIGHT)];
    let mut jpeg = Vec::new();
    let mut encoder = Encoder::new(&mut jpeg, 90);
    encoder.set_optimized_huffman_tables(true);
    encoder
        .encode(&flat, WIDTH, HEIGHT, ColorType::Luma)
        .expect("encodes");
    check_fallback(&jpeg, CannotSplice::MissingCode);
}

#[test]
fn one_scan_per_component_falls_back() {
    // jpeg-encoder writes optimized colour JPEGs as three sequential scans.
    let jpeg = encode(COLOUR_420, |e| e.set_optimized_huffman_tables(true));
    check_fallback(&jpeg, CannotSplice::MultipleScans);
}

#[test]
fn other_coding_processes_and_precisions_are_refused() {
    let jpeg = encode(COLOUR_420, |_| {});
    let sof = Jpeg::parse(&jpeg).expect("parses").headers.sof.start;
    let patched = |at: usize, value: u8| {
        let mut copy = jpeg.clone();
        copy[at] = value;
        Jpeg::parse(&copy).err()
    };
    assert_eq!(patched(sof + 1, 0xC9), Some(CannotSplice::Arithmetic));
    assert_eq!(patched(sof + 1, 0xC3), Some(CannotSplice::Process(3)));
    assert_eq!(patched(sof + 4, 12), Some(CannotSplice::Precision(12)));
    let mut dnl = jpeg.clone();
    dnl[sof + 5] = 0;
    dnl[sof + 6] = 0;
    assert_eq!(Jpeg::parse(&dnl).err(), Some(CannotSplice::Dnl));
    assert_eq!(patched(sof + 11, 0x31), Some(CannotSplice::Sampling));
}

#[test]
fn a_second_scan_is_refused() {
    let jpeg = encode(COLOUR_420, |_| {});
    let sos = Jpeg::parse(&jpeg).expect("parses").headers.sos;
    // A copy of the SOS and a byte of data before EOI.
    let mut two = jpeg[..jpeg.len() - 2].to_vec();
    two.extend_from_slice(&jpeg[sos.clone()]);
    two.extend_from_slice(&[0x00, 0xFF, 0xD9]);
    let refused = Jpeg::parse(&two).and_then(|j| j.splice(&drawing(&j, &writes())));
    assert_eq!(refused.err(), Some(CannotSplice::MultipleScans));
}

/// A small deterministic generator for the corruption test.
fn next(state: &mut u64) -> u64 {
    *state = state
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    *state >> 33
}

/// A number below `n` from the generator.
fn below(state: &mut u64, n: usize) -> usize {
    usize::try_from(next(state) % u64::try_from(n).expect("fits")).expect("below n")
}

#[test]
fn garbled_or_truncated_data_never_panics() {
    let writes = writes();
    let mut state = 7_u64;
    for options in [
        COLOUR_420,
        Options {
            grey: true,
            ..COLOUR_420
        },
        Options {
            restart: Some(4),
            ..COLOUR_420
        },
        Options {
            restart: Some(4),
            sampling: SamplingFactor::F_1_1,
            ..COLOUR_420
        },
    ] {
        let jpeg = encode(options, |_| {});
        let start = scan_start(&jpeg);
        for _ in 0..150 {
            let mut broken = jpeg.clone();
            for _ in 0..1 + next(&mut state) % 4 {
                let at = start + below(&mut state, jpeg.len() - start);
                broken[at] ^= 1 << below(&mut state, 8);
            }
            if let Ok(parsed) = Jpeg::parse(&broken) {
                let _ = parsed.splice(&drawing(&parsed, &writes));
            }
        }
        for cut in (0..jpeg.len()).step_by(97) {
            if let Ok(parsed) = Jpeg::parse(&jpeg[..cut]) {
                let _ = parsed.splice(&drawing(&parsed, &writes));
            }
        }
        // Garbled headers too.
        for _ in 0..150 {
            let mut broken = jpeg.clone();
            let at = below(&mut state, start);
            broken[at] = next(&mut state).to_le_bytes()[0];
            if let Ok(parsed) = Jpeg::parse(&broken) {
                let _ = parsed.splice(&drawing(&parsed, &writes));
            }
        }
    }
}

#[test]
fn the_chrominance_tables_are_complete() {
    let dc = huffman::chroma_dc();
    let ac = huffman::chroma_ac();
    assert_eq!(dc.values.len(), 12);
    assert_eq!(ac.values.len(), 162);
    let (dc, ac) = (
        huffman::Encoder::new(&dc).expect("a prefix code"),
        huffman::Encoder::new(&ac).expect("a prefix code"),
    );
    assert!((0..=11).all(|s| dc.code(s).is_ok()));
    for run in 0..16_u8 {
        assert!((1..=10).all(|size| ac.code(run << 4 | size).is_ok()));
    }
    assert!(ac.code(0x00).is_ok() && ac.code(0xF0).is_ok());
}

/// `jpeg` spliced with one pixel drawn at (`x`, `y`).
fn splice_one_pixel(jpeg: &[u8], x: i64, y: i64) -> Result<Spliced, CannotSplice> {
    let parsed = Jpeg::parse(jpeg)?;
    let mut drawing = parsed.canvas();
    drawing.put(x, y, OUTLINE);
    parsed.splice(&drawing)
}

/// Found by `cargo fuzz` (fuzz/fuzz_targets/splice.rs; the file is kept as a seed): a 4:2:0
/// JPEG whose scan is followed by fill bytes and an APP1 segment longer than the rest of
/// the file. zune-jpeg decodes it, but once spliced (the overlay's blocks re-encoded, the
/// scan's last code ending a bit before that marker) it did not, and the qrpose service
/// would have answered with a JPEG it cannot read. Such a trailer is refused.
#[test]
fn a_segment_running_past_the_end_after_the_scan_falls_back() {
    let jpeg: &[u8] =
        include_bytes!("../../../../fuzz/seeds/splice/crash_truncated_app1_after_scan.jpg");
    assert_eq!(
        splice_one_pixel(jpeg, 0, 0).err(),
        Some(CannotSplice::Malformed(
            "a segment after the scan runs past the end"
        ))
    );
}

/// Found by `cargo fuzz` (kept as a seed): a grey JPEG followed, after its scan, by a DHT
/// segment whose counts exceed its length. zune-jpeg stops after a one-scan file's scan and
/// never reads it; the spliced version of a grey frame has three scans, after which it does
/// and refuses the file. Tables after the scan are refused.
#[test]
fn tables_after_the_scan_fall_back() {
    let jpeg: &[u8] =
        include_bytes!("../../../../fuzz/seeds/splice/crash_grey_bad_dht_after_scan.jpg");
    assert_eq!(
        splice_one_pixel(jpeg, 0, 0).err(),
        Some(CannotSplice::Malformed("tables after the scan"))
    );
    // A table after the scan of an otherwise clean file is refused the same way.
    let clean = encode(COLOUR_420, |_| {});
    let eoi = clean.len() - 2;
    let dqt: Vec<u8> = [&[0xFF, 0xDB, 0, 67, 0][..], &[1; 64]].concat();
    let with_table = [&clean[..eoi], &dqt, &clean[eoi..]].concat();
    let refused = Jpeg::parse(&with_table).and_then(|j| j.splice(&drawing(&j, &writes())));
    assert_eq!(
        refused.err(),
        Some(CannotSplice::Malformed("tables after the scan"))
    );
}

/// Found by `cargo fuzz` (kept as a seed): a grey JPEG that stops after its scan, with no
/// EOI. zune-jpeg accepts that of a one-scan file, but in strict mode not of the three
/// scans of its spliced version. The splice adds the EOI; every decoder then reads it.
#[test]
fn a_grey_jpeg_without_eoi_gets_one_and_decodes_once_spliced() {
    let jpeg: &[u8] = include_bytes!("../../../../fuzz/seeds/splice/crash_grey_without_eoi.jpg");
    assert_ne!(jpeg.get(jpeg.len() - 2..), Some(&[0xFF, 0xD9][..]));
    let spliced = splice_one_pixel(jpeg, 3, 3).expect("spliced");
    assert_eq!(
        spliced.bytes.get(spliced.bytes.len() - 2..),
        Some(&[0xFF, 0xD9][..])
    );
    let decoded = decode_zune(&spliced.bytes, ColorSpace::Luma, true).expect("decodes");
    assert_eq!((decoded.width_px, decoded.height_px), (11, 49));
}
