//! Encoded image bytes to an RGB raster and back, for drawing the overlay.
//!
//! Decoding: JPEG through zune-jpeg (the detector's decoder, to RGB here), PNG and WebP
//! through the `image` crate. The bytes have already passed the detector's decoder and its
//! limits (docs/service.md, `--max-image-pixels`) when these run, so only a decoder
//! disagreement can fail here. Encoding: JPEG with `jpeg-encoder` (SIMD when the CPU has
//! it; 4:2:0 at [`JPEG_QUALITY`]), PNG with the `image` crate's fast compression.

use super::raster::RgbRaster;
use crate::detect::decode::{ImageFormat, sniff_format};
use image::ImageEncoder;
use std::io::Cursor;
use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

/// Quality of annotated JPEGs (1-100): the overlay's thin coloured strokes stay crisp at 90.
pub const JPEG_QUALITY: u8 = 90;

/// Why an annotated image could not be made.
#[derive(Debug, thiserror::Error)]
pub enum CodecError {
    /// The bytes are not a JPEG, PNG or WebP, or the colour decoder refused what the
    /// detector's grey decoder read.
    #[error("cannot decode the image in colour: {0}")]
    Decode(String),
    /// The image is larger than JPEG allows (65535 px a side) or the encoder failed.
    #[error("cannot encode the annotated image: {0}")]
    Encode(String),
}

/// Decodes JPEG, PNG or WebP bytes to RGB.
///
/// # Errors
/// [`CodecError::Decode`] for bytes that are not a decodable image.
pub fn decode_rgb(bytes: &[u8]) -> Result<RgbRaster, CodecError> {
    match sniff_format(bytes) {
        Some(ImageFormat::Jpeg) => decode_jpeg_rgb(bytes),
        Some(format @ (ImageFormat::Png | ImageFormat::Webp)) => decode_with_image(bytes, format),
        None => Err(CodecError::Decode("not a JPEG, PNG or WebP".to_owned())),
    }
}

fn decode_jpeg_rgb(bytes: &[u8]) -> Result<RgbRaster, CodecError> {
    let options = DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::RGB)
        .set_max_width(usize::from(u16::MAX))
        .set_max_height(usize::from(u16::MAX))
        .set_strict_mode(false);
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    let pixels = decoder
        .decode()
        .map_err(|e| CodecError::Decode(format!("{e:?}")))?;
    let (width_px, height_px) = decoder
        .dimensions()
        .ok_or_else(|| CodecError::Decode("no frame header".to_owned()))?;
    RgbRaster::new(width_px, height_px, pixels)
        .ok_or_else(|| CodecError::Decode("decoded size mismatch".to_owned()))
}

fn decode_with_image(bytes: &[u8], format: ImageFormat) -> Result<RgbRaster, CodecError> {
    let image_format = match format {
        ImageFormat::Webp => image::ImageFormat::WebP,
        ImageFormat::Png | ImageFormat::Jpeg => image::ImageFormat::Png,
    };
    let image = image::ImageReader::with_format(Cursor::new(bytes), image_format)
        .decode()
        .map_err(|e| CodecError::Decode(e.to_string()))?
        .into_rgb8();
    let (width_px, height_px) = (image.width() as usize, image.height() as usize);
    RgbRaster::new(width_px, height_px, image.into_raw())
        .ok_or_else(|| CodecError::Decode("decoded size mismatch".to_owned()))
}

/// The raster as a baseline JPEG, 4:2:0, quality [`JPEG_QUALITY`].
///
/// # Errors
/// [`CodecError::Encode`] for a side over 65535 px.
pub fn encode_jpeg(raster: &RgbRaster) -> Result<Vec<u8>, CodecError> {
    let side = |n: usize| u16::try_from(n).map_err(|_| CodecError::Encode(format!("{n} px")));
    let (width, height) = (side(raster.width_px())?, side(raster.height_px())?);
    let mut out = Vec::with_capacity(raster.pixels().len() / 8);
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, JPEG_QUALITY);
    encoder.set_sampling_factor(jpeg_encoder::SamplingFactor::F_2_2);
    encoder
        .encode(raster.pixels(), width, height, jpeg_encoder::ColorType::Rgb)
        .map_err(|e| CodecError::Encode(e.to_string()))?;
    Ok(out)
}

/// The raster as an 8-bit RGB PNG (fast compression: a photo barely compresses anyway).
///
/// # Errors
/// [`CodecError::Encode`] when the encoder fails.
pub fn encode_png(raster: &RgbRaster) -> Result<Vec<u8>, CodecError> {
    let side = |n: usize| u32::try_from(n).map_err(|_| CodecError::Encode(format!("{n} px")));
    let (width, height) = (side(raster.width_px())?, side(raster.height_px())?);
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(
        raster.pixels(),
        width,
        height,
        image::ExtendedColorType::Rgb8,
    )
    .map_err(|e| CodecError::Encode(e.to_string()))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(width_px: usize, height_px: usize) -> RgbRaster {
        let pixels = (0..width_px * height_px)
            .flat_map(|i| {
                let v = u8::try_from(i % 251).expect("below 256");
                [v, 255 - v, v / 2]
            })
            .collect();
        RgbRaster::new(width_px, height_px, pixels).expect("sized")
    }

    #[test]
    fn png_round_trips_exactly() {
        let raster = gradient(33, 17);
        let png = encode_png(&raster).expect("encodes");
        assert_eq!(decode_rgb(&png).expect("decodes"), raster);
    }

    #[test]
    fn jpeg_round_trips_its_size() {
        let raster = gradient(33, 17);
        let jpeg = encode_jpeg(&raster).expect("encodes");
        let back = decode_rgb(&jpeg).expect("decodes");
        assert_eq!((back.width_px(), back.height_px()), (33, 17));
    }

    #[test]
    fn other_bytes_are_refused() {
        assert!(matches!(decode_rgb(b"GIF89a"), Err(CodecError::Decode(_))));
    }
}
