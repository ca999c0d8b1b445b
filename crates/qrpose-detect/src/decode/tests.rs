//! Tests of image decoding: formats, limits, refusals, CMYK/YCCK.

use super::*;

fn encode_png(width: u32, height: u32) -> Vec<u8> {
    let img = image::GrayImage::from_fn(width, height, |x, y| image::Luma([(x * 7 + y) as u8]));
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), image::ImageFormat::Png)
        .expect("png encodes");
    out
}

fn encode_jpeg(width: u32, height: u32) -> Vec<u8> {
    let img = image::GrayImage::from_fn(width, height, |x, _| {
        image::Luma([if x < width / 2 { 20 } else { 230 }])
    });
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90)
        .encode_image(&img)
        .expect("jpeg encodes");
    out
}

/// A PNG whose IHDR declares `width` × `height` with no pixel data behind it (the CRC is
/// computed so that only the size is wrong).
fn png_header_declaring(width: u32, height: u32) -> Vec<u8> {
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    let crc = crc32(&ihdr);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend_from_slice(&13u32.to_be_bytes());
    out.extend_from_slice(&ihdr);
    out.extend_from_slice(&crc.to_be_bytes());
    out
}

/// The CRC-32 of a PNG chunk (type and data).
pub(super) fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

#[test]
fn decodes_png_and_jpeg_to_the_right_size_and_values() {
    let png = decode_gray(&encode_png(40, 30), &DecodeLimits::default()).expect("png");
    assert_eq!((png.width(), png.height()), (40, 30));
    assert_eq!(png.get(3, 2), 23);
    let jpeg = decode_gray(&encode_jpeg(64, 48), &DecodeLimits::default()).expect("jpeg");
    assert_eq!((jpeg.width(), jpeg.height()), (64, 48));
    assert!(jpeg.get(5, 10) < 40 && jpeg.get(60, 10) > 210);
}

#[test]
fn refuses_a_huge_declared_size_before_allocating() {
    let bytes = png_header_declaring(100_000, 100_000);
    assert_eq!(
        declared_dimensions(&bytes),
        Ok((100_000, 100_000)),
        "the header alone is read"
    );
    let err = decode_gray(&bytes, &DecodeLimits::default()).expect_err("too large");
    assert_eq!(
        err,
        DecodeError::TooManyPixels {
            width_px: 100_000,
            height_px: 100_000,
            max_pixels: DEFAULT_MAX_PIXELS
        }
    );
}

#[test]
fn admission_weighs_the_declared_size_capped_and_webp_twice() {
    assert_eq!(admission_pixels(&encode_png(30, 20), 1_000), 600);
    assert_eq!(admission_pixels(&encode_jpeg(30, 20), 1_000), 600);
    assert_eq!(
        admission_pixels(&png_header_declaring(7000, 7000), 50_000_000),
        49_000_000
    );
    assert_eq!(
        admission_pixels(&png_header_declaring(100_000, 100_000), 50_000_000),
        50_000_000,
        "refused at decode before any allocation: weighs at most the limit"
    );
    let mut webp = Vec::new();
    image::DynamicImage::ImageLuma8(image::GrayImage::new(30, 20))
        .into_rgb8()
        .write_to(&mut Cursor::new(&mut webp), image::ImageFormat::WebP)
        .expect("webp encodes");
    assert_eq!(admission_pixels(&webp, 1_000), 1_200);
    assert_eq!(admission_pixels(b"not an image", 1_000), 0);
}

#[test]
fn applies_configured_limits() {
    let png = encode_png(40, 30);
    let small_bytes = DecodeLimits {
        max_encoded_bytes: 10,
        ..DecodeLimits::default()
    };
    assert!(matches!(
        decode_gray(&png, &small_bytes),
        Err(DecodeError::EncodedTooLarge { max_bytes: 10, .. })
    ));
    let few_pixels = DecodeLimits {
        max_pixels: 1199,
        ..DecodeLimits::default()
    };
    assert!(matches!(
        decode_gray(&png, &few_pixels),
        Err(DecodeError::TooManyPixels {
            max_pixels: 1199,
            ..
        })
    ));
    let exact = DecodeLimits {
        max_pixels: 1200,
        ..DecodeLimits::default()
    };
    assert!(decode_gray(&png, &exact).is_ok(), "the limit is inclusive");
}

#[test]
fn every_bad_input_has_its_error() {
    let limits = DecodeLimits::default();
    assert_eq!(decode_gray(&[], &limits), Err(DecodeError::Empty));
    assert_eq!(
        decode_gray(b"GIF89a not supported", &limits),
        Err(DecodeError::UnsupportedFormat)
    );
    assert_eq!(
        decode_gray(&png_header_declaring(0, 10), &limits),
        Err(DecodeError::ZeroSize {
            width_px: 0,
            height_px: 10
        })
    );
    let jpeg = encode_jpeg(64, 48);
    let png = encode_png(40, 30);
    let cases: [(&str, Vec<u8>, &str); 5] = [
        ("truncated jpeg", jpeg[..jpeg.len() / 3].to_vec(), "jpeg"),
        ("jpeg magic only", vec![0xFF, 0xD8, 0xFF], "jpeg"),
        ("truncated png", png[..png.len() - 30].to_vec(), "png"),
        ("png header only", png_header_declaring(40, 30), "png"),
        ("webp magic only", b"RIFF\0\0\0\0WEBPVP8 ".to_vec(), "webp"),
    ];
    for (name, bytes, format) in cases {
        match decode_gray(&bytes, &limits) {
            Err(DecodeError::Corrupt { format: f, .. }) => assert_eq!(f, format, "{name}"),
            other => panic!("{name}: {other:?}"),
        }
    }
}

/// A textured JPEG (every 8 × 8 block differs, so every part of the scan carries data).
fn textured_jpeg(width: u32, height: u32) -> Vec<u8> {
    let img = image::GrayImage::from_fn(width, height, |x, y| {
        image::Luma([((x * 7 + y * 13 + (x / 8) * (y / 8) * 31) % 251) as u8])
    });
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90)
        .encode_image(&img)
        .expect("jpeg encodes");
    out
}

#[test]
fn a_jpeg_cut_anywhere_in_its_scan_is_corrupt_not_grey() {
    let limits = DecodeLimits::default();
    let jpeg = textured_jpeg(320, 240);
    assert!(decode_gray(&jpeg, &limits).is_ok());
    for share in [0.3, 0.5, 0.8, 0.95, 0.99] {
        let cut = &jpeg[..(jpeg.len() as f64 * share) as usize];
        match decode_gray(cut, &limits) {
            Err(DecodeError::Corrupt { format, reason }) => {
                assert_eq!(format, "jpeg");
                assert!(reason.contains("ends before"), "{share}: {reason}");
            }
            other => panic!("cut at {share}: {other:?}"),
        }
    }
}

/// Ink amounts (c, m, y, k), 0..=255, of the test patches, and the grey each should
/// decode to: 255 × (1 − k) × (0.299 (1 − c) + 0.587 (1 − m) + 0.114 (1 − y)).
const PATCHES: [([u8; 4], u8); 6] = [
    ([0, 0, 0, 0], 255),       // paper
    ([0, 0, 0, 128], 127),     // half black
    ([255, 0, 0, 0], 179),     // cyan
    ([0, 255, 0, 0], 105),     // magenta
    ([0, 0, 255, 0], 226),     // yellow
    ([255, 255, 255, 255], 0), // rich black
];

/// Side of a square patch, px: whole 16 px MCUs, so no patch bleeds into the next.
const PATCH_PX: usize = 16;

/// A row of [`PATCHES`] as interleaved CMYK ink, `invert`ed (255 − ink) if asked.
fn cmyk_patches(invert: bool) -> (Vec<u8>, u16, u16) {
    let (w, h) = (PATCH_PX * PATCHES.len(), PATCH_PX);
    let mut data = Vec::with_capacity(w * h * 4);
    for _ in 0..h {
        for x in 0..w {
            let (ink, _) = PATCHES[x / PATCH_PX];
            data.extend(ink.map(|v| if invert { 255 - v } else { v }));
        }
    }
    (data, w as u16, h as u16)
}

fn encode_4_channels(data: &[u8], w: u16, h: u16, color: jpeg_encoder::ColorType) -> Vec<u8> {
    let mut out = Vec::new();
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, 100);
    encoder.set_sampling_factor(jpeg_encoder::SamplingFactor::F_1_1);
    encoder
        .encode(data, w, h, color)
        .expect("jpeg-encoder writes it");
    out
}

/// The bytes without their Adobe APP14 segment.
fn without_app14(jpeg: &[u8]) -> Vec<u8> {
    let at = (2..jpeg.len() - 1)
        .find(|&i| jpeg[i] == 0xFF && jpeg[i + 1] == 0xEE)
        .expect("an APP14 segment");
    let length = usize::from(u16::from_be_bytes([jpeg[at + 2], jpeg[at + 3]]));
    [&jpeg[..at], &jpeg[at + 2 + length..]].concat()
}

fn assert_patches(name: &str, bytes: &[u8]) {
    let image =
        decode_gray(bytes, &DecodeLimits::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(image.width(), PATCH_PX * PATCHES.len(), "{name}");
    for (i, (ink, grey)) in PATCHES.iter().enumerate() {
        let got = image.get(i * PATCH_PX + PATCH_PX / 2, PATCH_PX / 2);
        assert!(
            got.abs_diff(*grey) <= 4,
            "{name}: ink {ink:?} decoded to {got}, expected {grey}"
        );
    }
}

#[test]
fn cmyk_and_ycck_jpegs_decode_to_the_luma_of_their_colour() {
    use jpeg_encoder::ColorType;
    // jpeg-encoder writes Adobe's convention (255 − ink, with an APP14 marker).
    let (ink, w, h) = cmyk_patches(false);
    let adobe_cmyk = encode_4_channels(&ink, w, h, ColorType::Cmyk);
    assert_eq!(jpeg::adobe_transform(&adobe_cmyk), Some(0));
    let ycck = encode_4_channels(&ink, w, h, ColorType::CmykAsYcck);
    assert_eq!(jpeg::adobe_transform(&ycck), Some(2));
    // Without the marker the stored values are the ink (libjpeg's reading): store 255 −
    // (255 − ink) and drop the marker.
    let (inverted, _, _) = cmyk_patches(true);
    let plain_cmyk = without_app14(&encode_4_channels(&inverted, w, h, ColorType::Cmyk));
    assert_eq!(jpeg::adobe_transform(&plain_cmyk), None);
    for (name, bytes) in [
        ("Adobe CMYK", adobe_cmyk),
        ("YCCK", ycck),
        ("CMYK without an Adobe marker", plain_cmyk),
    ] {
        assert_patches(name, &bytes);
    }
}

#[test]
fn an_adobe_rgb_jpeg_decodes_to_luma() {
    // Adobe transform 0 on three components: RGB stored as is (zune-jpeg has no luma
    // conversion for it either).
    let (w, h) = (32u16, 16u16);
    let rgb: Vec<u8> = (0..usize::from(w) * usize::from(h))
        .flat_map(|i| {
            if i % 32 < 16 {
                [255, 0, 0]
            } else {
                [0, 0, 255]
            }
        })
        .collect();
    let mut out = Vec::new();
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, 100);
    encoder
        .add_app_segment(14, b"Adobe\0\x64\0\0\0\0\0".to_vec())
        .expect("an APP14 segment");
    // "Ycbcr" is written as given: the RGB bytes go in untransformed.
    encoder
        .encode(&rgb, w, h, jpeg_encoder::ColorType::Ycbcr)
        .expect("encodes");
    assert_eq!(jpeg::adobe_transform(&out), Some(0));
    let image = decode_gray(&out, &DecodeLimits::default()).expect("decodes");
    // Red: 0.299 × 255 = 76; blue: 0.114 × 255 = 29.
    assert!(image.get(8, 8).abs_diff(76) <= 4, "{}", image.get(8, 8));
    assert!(image.get(24, 8).abs_diff(29) <= 4, "{}", image.get(24, 8));
}

#[test]
fn a_qr_code_printed_in_cmyk_is_still_read() {
    use crate::Detector;
    use crate::test_frames::DrawnCode;
    use jpeg_encoder::ColorType;
    let (scale, quiet) = (6, 4);
    let code = DrawnCode::new("CMYK-1", scale, quiet * scale, quiet * scale);
    let side = (code.modules + 2 * quiet) * scale;
    // Dark modules in rich black on a light cyan tint.
    let mut ink = Vec::with_capacity(side * side * 4);
    for y in 0..side {
        for x in 0..side {
            ink.extend(if code.dark(x, y) {
                [200, 180, 180, 230]
            } else {
                [40, 0, 0, 0]
            });
        }
    }
    for color in [ColorType::Cmyk, ColorType::CmykAsYcck] {
        let bytes = encode_4_channels(&ink, side as u16, side as u16, color);
        let image = decode_gray(&bytes, &DecodeLimits::default()).expect("decodes");
        let found = crate::backends::rqrr::RqrrDetector.detect(&image);
        let texts: Vec<_> = found.iter().filter_map(|c| c.text.clone()).collect();
        assert_eq!(texts, ["CMYK-1"], "{color:?}");
    }
}

#[test]
fn a_jpeg_with_extra_bytes_between_headers_still_decodes() {
    // Strict zune-jpeg rejects garbage between segments; cameras write such files and
    // the lenient retry reads them.
    let jpeg = textured_jpeg(64, 48);
    // After the first segment (SOI, then a marker and its big-endian length).
    let first_end = 4 + usize::from(u16::from_be_bytes([jpeg[4], jpeg[5]]));
    let mut odd = jpeg[..first_end].to_vec();
    odd.extend_from_slice(&[0x00, 0x11, 0x22]);
    odd.extend_from_slice(&jpeg[first_end..]);
    assert!(
        jpeg::decode_with(&odd, true).is_err(),
        "strict mode rejects it"
    );
    let clean = decode_gray(&jpeg, &DecodeLimits::default()).expect("clean decodes");
    match decode_gray(&odd, &DecodeLimits::default()) {
        Ok(decoded) => assert!(decoded.pixels() == clean.pixels(), "pixels differ"),
        Err(e) => panic!("extra bytes: {e:?}"),
    }
}
