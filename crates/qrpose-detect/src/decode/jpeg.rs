//! The JPEG path of [`super::decode_gray`]: zune-jpeg reads the header and decodes luma
//! directly (no RGB round trip), strict first and leniently when strict mode rejects
//! anything but a truncation.
//!
//! Colour spaces: grey and YCbCr JPEGs give their Y channel. zune-jpeg maps nothing else to
//! luma, so the others are decoded to their own channels and converted here, in place:
//! RGB (an Adobe APP14 marker with transform 0 on three components) with Rec. 601 weights;
//! CMYK and YCCK (print workflows) through the naive ink model, no ICC profile:
//! R = (1 − c)(1 − k) and so on for G and B, then the same weights. Ink amounts follow the
//! Adobe convention when an Adobe APP14 marker is present (Photoshop stores 255 − ink, and
//! YCCK is always Adobe: its YCbCr decodes to c, m, y and its K channel holds 255 − k), and
//! libjpeg's otherwise (the stored value is the ink amount). Peak memory for such a JPEG is
//! 4 bytes per pixel (3 for RGB), released to 1 after the conversion.

use super::{DecodeError, GrayImage, ImageFormat, corrupt};
use zune_jpeg::JpegDecoder;
use zune_jpeg::errors::DecodeErrors as JpegDecodeError;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

/// The dimensions the JPEG header declares, (width, height) px, without decoding pixels.
pub(super) fn declared_dimensions(bytes: &[u8]) -> Result<(u64, u64), DecodeError> {
    let format = ImageFormat::Jpeg;
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), jpeg_options(false));
    decoder
        .decode_headers()
        .map_err(|e| corrupt(format, format!("{e:?}")))?;
    let (w, h) = decoder
        .dimensions()
        .ok_or_else(|| corrupt(format, "no frame header"))?;
    Ok((w as u64, h as u64))
}

/// zune-jpeg options: luma out, and its own size guard opened to the JPEG maximum so that
/// [`super::DecodeLimits`] alone decides.
fn jpeg_options(strict: bool) -> DecoderOptions {
    DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::Luma)
        .set_max_width(usize::from(u16::MAX))
        .set_max_height(usize::from(u16::MAX))
        .set_strict_mode(strict)
}

/// Luma straight from zune-jpeg. Strict mode first: lenient zune-jpeg fills the rows of a
/// truncated scan with grey and reports success, and a code cut in half must not come back
/// as a pose. Data that strict mode rejects for anything but running out (extra bytes
/// between headers, a stray marker: common in camera files) is decoded again leniently.
pub(super) fn decode_luma(bytes: &[u8]) -> Result<GrayImage, DecodeError> {
    match decode_with(bytes, true) {
        Err(e) if is_truncation(&e) => Err(corrupt(
            ImageFormat::Jpeg,
            format!("the data ends before the image does ({e})"),
        )),
        Err(_) => decode_with(bytes, false).map_err(|e| corrupt(ImageFormat::Jpeg, e)),
        Ok(image) => Ok(image),
    }
}

/// Whether zune-jpeg ran out of data, as opposed to rejecting some other part of the file.
fn is_truncation(e: &JpegDecodeError) -> bool {
    match e {
        JpegDecodeError::ExhaustedData => true,
        JpegDecodeError::FormatStatic(msg) => msg.to_ascii_lowercase().contains("premature"),
        _ => false,
    }
}

/// Decodes with zune-jpeg, strict or lenient; errors other than zune-jpeg's own (size
/// mismatch, a colour space without a luma conversion) come back as
/// [`JpegDecodeError::Format`].
pub(super) fn decode_with(bytes: &[u8], strict: bool) -> Result<GrayImage, JpegDecodeError> {
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), jpeg_options(strict));
    decoder.decode_headers()?;
    let mut input = decoder
        .input_colorspace()
        .ok_or(JpegDecodeError::FormatStatic("no frame header"))?;
    let components = decoder.info().map_or(0, |info| info.components);
    if input == ColorSpace::CMYK && components == 3 {
        // Adobe transform 0 on three components is RGB (zune-jpeg decides so only later).
        input = ColorSpace::RGB;
    }
    let conversion = match input {
        ColorSpace::Luma | ColorSpace::YCbCr => return decode_raw(decoder)?.into_gray(),
        ColorSpace::RGB => ToLuma::Rgb,
        ColorSpace::CMYK => ToLuma::Cmyk {
            adobe: adobe_transform(bytes).is_some(),
        },
        ColorSpace::YCCK => ToLuma::Ycck,
        other => {
            return Err(JpegDecodeError::Format(format!(
                "no conversion from the {other:?} colour space to grey"
            )));
        }
    };
    // The image's own channels out (zune-jpeg copies them), converted to luma here.
    let options = jpeg_options(strict).jpeg_set_out_colorspace(input);
    let decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    decode_raw(decoder)?.convert(conversion)
}

/// Decodes into the decoder's output colour space.
fn decode_raw(mut decoder: JpegDecoder<ZCursor<&[u8]>>) -> Result<RawImage, JpegDecodeError> {
    decoder.decode_headers()?;
    let (w, h) = decoder
        .dimensions()
        .ok_or(JpegDecodeError::FormatStatic("no frame header"))?;
    let size = decoder
        .output_buffer_size()
        .ok_or(JpegDecodeError::FormatStatic("size overflows"))?;
    let mut pixels = vec![0u8; size];
    decoder.decode_into(&mut pixels)?;
    Ok(RawImage { w, h, pixels })
}

/// Decoded pixels, channels interleaved.
struct RawImage {
    w: usize,
    h: usize,
    pixels: Vec<u8>,
}

const SIZE_MISMATCH: JpegDecodeError = JpegDecodeError::FormatStatic("decoded size mismatch");

impl RawImage {
    /// A one-channel image as it is.
    fn into_gray(self) -> Result<GrayImage, JpegDecodeError> {
        GrayImage::new(self.w, self.h, self.pixels).ok_or(SIZE_MISMATCH)
    }

    /// Converts to luma, in place: pixel i is written at i after being read from
    /// channels × i ≥ i.
    fn convert(self, conversion: ToLuma) -> Result<GrayImage, JpegDecodeError> {
        let Self { w, h, mut pixels } = self;
        let channels = conversion.channels();
        let n = w.checked_mul(h).ok_or(SIZE_MISMATCH)?;
        if pixels.len() != n * channels {
            return Err(SIZE_MISMATCH);
        }
        for i in 0..n {
            let at = i * channels;
            pixels[i] = conversion.pixel(&pixels[at..at + channels]);
        }
        pixels.truncate(n);
        pixels.shrink_to_fit();
        GrayImage::new(w, h, pixels).ok_or(SIZE_MISMATCH)
    }
}

/// How interleaved channels become luma.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ToLuma {
    /// R, G, B.
    Rgb,
    /// C, M, Y, K as stored; `adobe`: the stored values are 255 − ink.
    Cmyk { adobe: bool },
    /// Y, Cb, Cr, K of Adobe's YCCK.
    Ycck,
}

/// Rec. 601 luma weights of R, G and B.
const LUMA_WEIGHTS: [f32; 3] = [0.299, 0.587, 0.114];

fn luma_of(r: f32, g: f32, b: f32) -> u8 {
    let [wr, wg, wb] = LUMA_WEIGHTS;
    (wr * r + wg * g + wb * b).round().clamp(0.0, 255.0) as u8
}

/// JFIF's YCbCr to R, G, B, clamped to 0..=255.
fn ycbcr_to_rgb(y: f32, cb: f32, cr: f32) -> [f32; 3] {
    let (cb, cr) = (cb - 128.0, cr - 128.0);
    [
        y + 1.402 * cr,
        y - 0.344_136 * cb - 0.714_136 * cr,
        y + 1.772 * cb,
    ]
    .map(|v| v.clamp(0.0, 255.0))
}

impl ToLuma {
    fn channels(self) -> usize {
        match self {
            ToLuma::Rgb => 3,
            ToLuma::Cmyk { .. } | ToLuma::Ycck => 4,
        }
    }

    /// The luma of one pixel's channels.
    fn pixel(self, p: &[u8]) -> u8 {
        let f = |i: usize| f32::from(p[i]);
        // How much light each ink lets through, as 0..=255.
        let (through, k_through) = match self {
            ToLuma::Rgb => return luma_of(f(0), f(1), f(2)),
            ToLuma::Cmyk { adobe: true } => ([f(0), f(1), f(2)], f(3)),
            ToLuma::Cmyk { adobe: false } => {
                ([255.0 - f(0), 255.0 - f(1), 255.0 - f(2)], 255.0 - f(3))
            }
            // YCbCr decodes to the ink amounts c, m, y; K holds 255 − k.
            ToLuma::Ycck => (ycbcr_to_rgb(f(0), f(1), f(2)).map(|ink| 255.0 - ink), f(3)),
        };
        let k = k_through / 255.0;
        luma_of(through[0] * k, through[1] * k, through[2] * k)
    }
}

/// The colour transform of an Adobe APP14 segment before the first scan (0: none / CMYK or
/// RGB, 1: YCbCr, 2: YCCK), or `None` without one. Stops at the first malformed segment.
pub(super) fn adobe_transform(bytes: &[u8]) -> Option<u8> {
    let mut at = 2; // after SOI
    loop {
        if *bytes.get(at)? != 0xFF {
            return None;
        }
        // Fill bytes: any number of 0xFF before the marker code.
        while *bytes.get(at + 1)? == 0xFF {
            at += 1;
        }
        let marker = *bytes.get(at + 1)?;
        at += 2;
        match marker {
            // Start of scan, end of image: no more headers.
            0xDA | 0xD9 => return None,
            // Standalone markers (TEM, RSTn) carry no length.
            0x01 | 0xD0..=0xD7 => continue,
            _ => {}
        }
        let length = usize::from(u16::from_be_bytes([*bytes.get(at)?, *bytes.get(at + 1)?]));
        let data = bytes.get(at + 2..at + length.max(2))?;
        if marker == 0xEE && data.len() >= 12 && data.starts_with(b"Adobe") {
            return Some(data[11]);
        }
        at += length;
    }
}
