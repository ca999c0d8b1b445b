//! PNG straight to 8-bit luma, one row at a time.
//!
//! The `image` crate decodes a whole frame in its own colour type first (4 bytes a pixel for
//! RGBA, 8 for 16-bit RGBA) and converts it afterwards; on a 50 MP photo that transient is
//! 200-400 MB per request. Here each decoded row (palette and low bit depths expanded, 16-bit
//! samples cut to their high byte) is turned into luma as it arrives, so the only frame-sized
//! buffer is the 1-byte-a-pixel result. Interlaced (Adam7) rows are placed with the `png`
//! crate's own pass geometry.
//!
//! The luma of a colour pixel has the `image` crate's ITU-R BT.709 weights (2126, 7152, 722
//! over 10 000, rounded) and alpha is ignored, as `DynamicImage::into_luma8` does; that
//! converts in `f32`, so a grey value may differ from it by one level where the weighted sum
//! falls on a half (tested).

use super::GrayImage;
use png::{BitDepth, ColorType, InterlaceInfo, Transformations};
use std::io::Cursor;

/// BT.709 luma weights over [`LUMA_DIV`], as the `image` crate's.
const LUMA_WEIGHTS: [u32; 3] = [2126, 7152, 722];
/// The weights' denominator.
const LUMA_DIV: u32 = 10_000;

/// Why a PNG could not be decoded to luma.
#[derive(Debug, thiserror::Error)]
pub(super) enum PngLumaError {
    /// The `png` crate refused the data.
    #[error("{0}")]
    Png(#[from] png::DecodingError),
    /// The decoder's output was not 8 bits a sample after normalisation.
    #[error("unexpected decoded sample depth {0:?}")]
    Depth(BitDepth),
    /// A decoded row is shorter than its pixel count says, or lies outside the frame.
    #[error("decoded row {line} does not fit the {width_px} × {height_px} frame")]
    Row {
        line: usize,
        width_px: usize,
        height_px: usize,
    },
}

/// The luma of one decoded pixel of `channels` 8-bit samples.
fn luma(pixel: &[u8]) -> u8 {
    match *pixel {
        [r, g, b, ..] => {
            let l = LUMA_WEIGHTS[0] * u32::from(r)
                + LUMA_WEIGHTS[1] * u32::from(g)
                + LUMA_WEIGHTS[2] * u32::from(b);
            u8::try_from((l + LUMA_DIV / 2) / LUMA_DIV).unwrap_or(u8::MAX)
        }
        [grey, ..] => grey,
        [] => 0,
    }
}

/// Samples per pixel of a normalised (expanded, 8-bit) colour type.
fn channels(color: ColorType) -> usize {
    match color {
        ColorType::Grayscale | ColorType::Indexed => 1,
        ColorType::GrayscaleAlpha => 2,
        ColorType::Rgb => 3,
        ColorType::Rgba => 4,
    }
}

/// Writes the luma of the decoded `row` (`channels` samples a pixel) into `out`.
fn row_to_luma(row: &[u8], channels: usize, out: &mut [u8]) {
    for (o, pixel) in out.iter_mut().zip(row.chunks_exact(channels)) {
        *o = luma(pixel);
    }
}

/// Decodes PNG `bytes` to luma (the caller has checked the declared size against its limits).
pub(super) fn decode_luma(bytes: &[u8]) -> Result<GrayImage, PngLumaError> {
    let mut decoder = png::Decoder::new(Cursor::new(bytes));
    decoder.set_transformations(Transformations::normalize_to_color8());
    let mut reader = decoder.read_info()?;
    let (color, depth) = reader.output_color_type();
    if depth != BitDepth::Eight {
        return Err(PngLumaError::Depth(depth));
    }
    let channels = channels(color);
    let info = reader.info();
    let (width_px, height_px) = (info.width as usize, info.height as usize);
    let mut pixels = vec![0u8; width_px * height_px];
    let mut luma_row = vec![0u8; width_px];
    let mut line = 0usize;
    while let Some(row) = reader.next_interlaced_row()? {
        let data = row.data();
        let samples = data.len() / channels;
        let out = luma_row.get_mut(..samples).ok_or(PngLumaError::Row {
            line,
            width_px,
            height_px,
        })?;
        row_to_luma(data, channels, out);
        match row.interlace() {
            InterlaceInfo::Null(_) => {
                let target = pixels
                    .get_mut(line * width_px..(line + 1) * width_px)
                    .filter(|_| samples == width_px)
                    .ok_or(PngLumaError::Row {
                        line,
                        width_px,
                        height_px,
                    })?;
                target.copy_from_slice(out);
            }
            InterlaceInfo::Adam7(pass) => {
                png::expand_interlaced_row(&mut pixels, width_px, out, pass, 8);
            }
        }
        line += 1;
    }
    GrayImage::new(width_px, height_px, pixels).ok_or(PngLumaError::Row {
        line,
        width_px,
        height_px,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode(
        width: u32,
        height: u32,
        color: ColorType,
        depth: BitDepth,
        interlaced: bool,
        data: &[u8],
    ) -> Vec<u8> {
        if interlaced {
            return adam7::encode(width, height, color, data);
        }
        let mut out = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut out, width, height);
            encoder.set_color(color);
            encoder.set_depth(depth);
            let mut writer = encoder.write_header().expect("header");
            writer.write_image_data(data).expect("data");
        }
        out
    }

    /// An Adam7-interlaced 8-bit PNG written by hand (the `png` crate's encoder writes none):
    /// each pass's rows with filter type 0, in stored (uncompressed) deflate blocks.
    mod adam7 {
        use crate::decode::tests::crc32;
        use png::ColorType;

        /// (x0, y0, dx, dy) of the seven passes.
        const PASSES: [(usize, usize, usize, usize); 7] = [
            (0, 0, 8, 8),
            (4, 0, 8, 8),
            (0, 4, 4, 8),
            (2, 0, 4, 4),
            (0, 2, 2, 4),
            (1, 0, 2, 2),
            (0, 1, 1, 2),
        ];

        fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
            out.extend((data.len() as u32).to_be_bytes());
            let start = out.len();
            out.extend(kind);
            out.extend(data);
            let crc = crc32(&out[start..]);
            out.extend(crc.to_be_bytes());
        }

        fn stored_zlib(raw: &[u8]) -> Vec<u8> {
            let mut z = vec![0x78, 0x01];
            let blocks: Vec<&[u8]> = raw.chunks(65_535).collect();
            for (i, block) in blocks.iter().enumerate() {
                z.push(u8::from(i + 1 == blocks.len()));
                let len = block.len() as u16;
                z.extend(len.to_le_bytes());
                z.extend((!len).to_le_bytes());
                z.extend(*block);
            }
            let (mut a, mut b) = (1u32, 0u32);
            for &byte in raw {
                a = (a + u32::from(byte)) % 65_521;
                b = (b + a) % 65_521;
            }
            z.extend(((b << 16) | a).to_be_bytes());
            z
        }

        pub(super) fn encode(width: u32, height: u32, color: ColorType, data: &[u8]) -> Vec<u8> {
            let n = match color {
                ColorType::Grayscale => 1,
                ColorType::GrayscaleAlpha => 2,
                ColorType::Rgb => 3,
                _ => 4,
            };
            let (w, h) = (width as usize, height as usize);
            let mut raw = Vec::new();
            for (x0, y0, dx, dy) in PASSES {
                if x0 >= w || y0 >= h {
                    continue;
                }
                for y in (y0..h).step_by(dy) {
                    raw.push(0);
                    for x in (x0..w).step_by(dx) {
                        raw.extend(&data[(y * w + x) * n..(y * w + x + 1) * n]);
                    }
                }
            }
            let mut ihdr = Vec::new();
            ihdr.extend(width.to_be_bytes());
            ihdr.extend(height.to_be_bytes());
            ihdr.extend([8, color as u8, 0, 0, 1]);
            let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
            chunk(&mut out, b"IHDR", &ihdr);
            chunk(&mut out, b"IDAT", &stored_zlib(&raw));
            chunk(&mut out, b"IEND", &[]);
            out
        }
    }

    /// What `image` makes of the same bytes.
    fn via_image(bytes: &[u8]) -> Vec<u8> {
        image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
            .expect("image decodes")
            .into_luma8()
            .into_raw()
    }

    fn pattern(len: usize) -> Vec<u8> {
        (0..len).map(|k| ((k * 37 + k / 7) % 256) as u8).collect()
    }

    #[test]
    fn every_8_bit_colour_type_gives_the_image_crates_luma() {
        let (w, h) = (13u32, 9u32);
        for (color, n) in [
            (ColorType::Grayscale, 1),
            (ColorType::GrayscaleAlpha, 2),
            (ColorType::Rgb, 3),
            (ColorType::Rgba, 4),
        ] {
            for interlaced in [false, true] {
                // Both layouts of the same pixels decode to the same luma.
                let bytes = encode(
                    w,
                    h,
                    color,
                    BitDepth::Eight,
                    interlaced,
                    &pattern((w * h) as usize * n),
                );
                let ours = decode_luma(&bytes).expect("decodes");
                assert_eq!((ours.width(), ours.height()), (13, 9));
                let theirs = via_image(&bytes);
                let worst = ours
                    .pixels()
                    .iter()
                    .zip(&theirs)
                    .map(|(&a, &b)| a.abs_diff(b))
                    .max();
                assert!(
                    worst <= Some(1),
                    "{color:?} interlaced {interlaced}: {worst:?}"
                );
                let same = ours.pixels().iter().zip(&theirs).filter(|(a, b)| a == b);
                assert!(
                    same.count() * 10 >= theirs.len() * 9,
                    "{color:?}: mostly identical"
                );
            }
        }
    }

    #[test]
    fn low_bit_depth_and_16_bit_grey_expand_to_eight_bits() {
        let (w, h) = (10u32, 4u32);
        // 1-bit: bytes of 8 pixels, rows padded to whole bytes (2 bytes a row).
        let bits = encode(w, h, ColorType::Grayscale, BitDepth::One, false, &[0xA5; 8]);
        let ours = decode_luma(&bits).expect("decodes");
        assert_eq!(ours.pixels(), via_image(&bits).as_slice());
        assert_eq!(ours.get(0, 0), 255);
        assert_eq!(ours.get(1, 0), 0);
        // 16-bit: the high byte.
        let wide: Vec<u8> = (0..w * h).flat_map(|k| [(k * 6) as u8, 0xFF]).collect();
        let ours = decode_luma(&encode(
            w,
            h,
            ColorType::Grayscale,
            BitDepth::Sixteen,
            false,
            &wide,
        ))
        .expect("decodes");
        assert_eq!(ours.get(3, 0), 18);
    }

    #[test]
    fn a_truncated_png_is_an_error_not_a_panic() {
        let bytes = encode(8, 8, ColorType::Rgb, BitDepth::Eight, false, &pattern(192));
        for cut in [20, 40, bytes.len() - 13] {
            assert!(decode_luma(&bytes[..cut]).is_err(), "cut at {cut}");
        }
    }
}
