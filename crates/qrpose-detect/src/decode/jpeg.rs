//! The JPEG path of [`super::decode_gray`]: zune-jpeg reads the header and decodes luma
//! directly (no RGB round trip), strict first and leniently when strict mode rejects
//! anything but a truncation.

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
/// mismatch) come back as [`JpegDecodeError::Format`].
pub(super) fn decode_with(bytes: &[u8], strict: bool) -> Result<GrayImage, JpegDecodeError> {
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), jpeg_options(strict));
    decoder.decode_headers()?;
    let (w, h) = decoder
        .dimensions()
        .ok_or(JpegDecodeError::FormatStatic("no frame header"))?;
    let size = decoder
        .output_buffer_size()
        .ok_or(JpegDecodeError::FormatStatic("size overflows"))?;
    let mut pixels = vec![0u8; size];
    decoder.decode_into(&mut pixels)?;
    GrayImage::new(w, h, pixels).ok_or(JpegDecodeError::FormatStatic("decoded size mismatch"))
}
