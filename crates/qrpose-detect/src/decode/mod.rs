//! Encoded image bytes to an 8-bit grayscale raster, with size limits checked first.
//!
//! Formats: JPEG (module `jpeg`: zune-jpeg decodes luma directly, no RGB round trip), PNG
//! (module `png`: row by row to luma, so the only frame-sized buffer is the 1-byte-a-pixel
//! result) and WebP (through the `image` crate, whole frame in colour, then converted to
//! luma: 5 bytes a pixel at its peak, the one format above 1). The format
//! is sniffed from the magic bytes, never taken from a file name or a content type.
//!
//! Order of checks, so that no request can make the service allocate what it was not
//! allowed to: encoded length against [`DecodeLimits::max_encoded_bytes`]; then the
//! dimensions *declared in the header* against [`DecodeLimits::max_pixels`]; only then the
//! decode. Every decoder runs inside [`crate::contain::contain`], so a decoder bug on
//! hostile input is a [`DecodeError::Corrupt`], not a crash.
//!
//! The raster type, [`GrayImage`], lives in [`crate::raster`] (re-exported here).

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

mod jpeg;
mod png;

pub use crate::raster::GrayImage;

use crate::contain::contain;
use image::ImageDecoder;
use std::io::Cursor;
use thiserror::Error;

/// Default limit on the encoded size, bytes (20 MB).
pub const DEFAULT_MAX_ENCODED_BYTES: usize = 20_000_000;
/// Default limit on the declared pixel count (50 MP).
pub const DEFAULT_MAX_PIXELS: u64 = 50_000_000;

/// What an image may cost before it is decoded. The HTTP layer fills this from its config.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DecodeLimits {
    /// Largest accepted encoded size, bytes.
    pub max_encoded_bytes: usize,
    /// Largest accepted width × height, as declared in the header, pixels.
    pub max_pixels: u64,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        Self {
            max_encoded_bytes: DEFAULT_MAX_ENCODED_BYTES,
            max_pixels: DEFAULT_MAX_PIXELS,
        }
    }
}

/// The encodings the service reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// JPEG (baseline or progressive).
    Jpeg,
    /// PNG.
    Png,
    /// WebP (lossy or lossless).
    Webp,
}

impl ImageFormat {
    /// The lower-case name: "jpeg", "png", "webp".
    pub fn as_str(self) -> &'static str {
        match self {
            ImageFormat::Jpeg => "jpeg",
            ImageFormat::Png => "png",
            ImageFormat::Webp => "webp",
        }
    }
}

/// Why bytes did not become an image.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DecodeError {
    /// No bytes at all.
    #[error("the image is empty (0 bytes)")]
    Empty,
    /// More encoded bytes than [`DecodeLimits::max_encoded_bytes`]: refused unread.
    #[error("the encoded image has {bytes} bytes, more than the limit of {max_bytes}")]
    EncodedTooLarge {
        /// Bytes received.
        bytes: usize,
        /// The limit, bytes.
        max_bytes: usize,
    },
    /// The header declares more pixels than [`DecodeLimits::max_pixels`]: refused before
    /// any pixel buffer is allocated.
    #[error(
        "the image declares {width_px} × {height_px} pixels, more than the limit of {max_pixels}"
    )]
    TooManyPixels {
        /// Declared width, px.
        width_px: u64,
        /// Declared height, px.
        height_px: u64,
        /// The limit, px.
        max_pixels: u64,
    },
    /// The header declares a zero width or height.
    #[error("the image declares a zero size ({width_px} × {height_px})")]
    ZeroSize {
        /// Declared width, px.
        width_px: u64,
        /// Declared height, px.
        height_px: u64,
    },
    /// The magic bytes are not JPEG, PNG or WebP.
    #[error("unsupported image format: expected JPEG, PNG or WebP")]
    UnsupportedFormat,
    /// The data is truncated or corrupt.
    #[error("corrupt or truncated {format} data: {reason}")]
    Corrupt {
        /// The sniffed format ("jpeg", "png", "webp").
        format: &'static str,
        /// What the decoder said.
        reason: String,
    },
}

/// The format from the magic bytes, if it is one this module reads.
pub fn sniff_format(bytes: &[u8]) -> Option<ImageFormat> {
    if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some(ImageFormat::Jpeg)
    } else if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some(ImageFormat::Png)
    } else if bytes.len() >= 12 && &bytes[0..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        Some(ImageFormat::Webp)
    } else {
        None
    }
}

fn corrupt(format: ImageFormat, reason: impl ToString) -> DecodeError {
    DecodeError::Corrupt {
        format: format.as_str(),
        reason: reason.to_string(),
    }
}

/// Refuses declared sizes that are zero or over the pixel limit.
fn check_dimensions(
    width_px: u64,
    height_px: u64,
    limits: &DecodeLimits,
) -> Result<(), DecodeError> {
    if width_px == 0 || height_px == 0 {
        return Err(DecodeError::ZeroSize {
            width_px,
            height_px,
        });
    }
    if width_px.saturating_mul(height_px) > limits.max_pixels {
        return Err(DecodeError::TooManyPixels {
            width_px,
            height_px,
            max_pixels: limits.max_pixels,
        });
    }
    Ok(())
}

/// Runs a decoder, turning a panic inside it into [`DecodeError::Corrupt`].
fn contained<T>(
    format: ImageFormat,
    f: impl FnOnce() -> Result<T, DecodeError>,
) -> Result<T, DecodeError> {
    contain(f).unwrap_or_else(|_| Err(corrupt(format, "the decoder failed on this data")))
}

/// The dimensions the header declares, (width, height) px, without decoding pixels.
///
/// # Errors
/// [`DecodeError::UnsupportedFormat`] or [`DecodeError::Corrupt`] when no header can be read.
pub fn declared_dimensions(bytes: &[u8]) -> Result<(u64, u64), DecodeError> {
    let format = sniff_format(bytes).ok_or(DecodeError::UnsupportedFormat)?;
    contained(format, || match format {
        ImageFormat::Jpeg => jpeg::declared_dimensions(bytes),
        ImageFormat::Png => png_dimensions(bytes),
        ImageFormat::Webp => {
            let reader = image_reader(bytes, format);
            let (w, h) = reader.into_dimensions().map_err(|e| corrupt(format, e))?;
            Ok((u64::from(w), u64::from(h)))
        }
    })
}

/// Width and height from a PNG's IHDR chunk, which the format requires to come first.
fn png_dimensions(bytes: &[u8]) -> Result<(u64, u64), DecodeError> {
    let header = bytes
        .get(8..24)
        .ok_or_else(|| corrupt(ImageFormat::Png, "truncated before the IHDR chunk"))?;
    if &header[4..8] != b"IHDR" {
        return Err(corrupt(ImageFormat::Png, "the first chunk is not IHDR"));
    }
    let be = |b: &[u8]| u64::from(u32::from_be_bytes([b[0], b[1], b[2], b[3]]));
    Ok((be(&header[8..12]), be(&header[12..16])))
}

/// What decoding `bytes` and detecting in them weigh against a memory budget counted in
/// pixels: the declared width × height (at most `max_pixels`, which decoding enforces),
/// twice that for WebP, whose decoder holds the whole frame in colour (4 bytes a pixel)
/// besides the luma; 0 for bytes whose size cannot be read (they fail before any frame is
/// allocated).
#[must_use]
pub fn admission_pixels(bytes: &[u8], max_pixels: u64) -> u64 {
    let Ok((width_px, height_px)) = declared_dimensions(bytes) else {
        return 0;
    };
    let pixels = width_px.saturating_mul(height_px).min(max_pixels);
    match sniff_format(bytes) {
        Some(ImageFormat::Webp) => pixels.saturating_mul(2),
        _ => pixels,
    }
}

fn image_reader(bytes: &[u8], format: ImageFormat) -> image::ImageReader<Cursor<&[u8]>> {
    let image_format = match format {
        ImageFormat::Png => image::ImageFormat::Png,
        ImageFormat::Webp => image::ImageFormat::WebP,
        ImageFormat::Jpeg => image::ImageFormat::Jpeg,
    };
    image::ImageReader::with_format(Cursor::new(bytes), image_format)
}

/// Decodes JPEG, PNG or WebP bytes to grayscale, checking `limits` first.
///
/// # Errors
/// Every [`DecodeError`] variant, as its doc says; never panics.
pub fn decode_gray(bytes: &[u8], limits: &DecodeLimits) -> Result<GrayImage, DecodeError> {
    if bytes.is_empty() {
        return Err(DecodeError::Empty);
    }
    if bytes.len() > limits.max_encoded_bytes {
        return Err(DecodeError::EncodedTooLarge {
            bytes: bytes.len(),
            max_bytes: limits.max_encoded_bytes,
        });
    }
    let format = sniff_format(bytes).ok_or(DecodeError::UnsupportedFormat)?;
    let (width_px, height_px) = declared_dimensions(bytes)?;
    check_dimensions(width_px, height_px, limits)?;
    contained(format, || match format {
        ImageFormat::Jpeg => jpeg::decode_luma(bytes),
        ImageFormat::Png => png::decode_luma(bytes).map_err(|e| corrupt(format, e)),
        ImageFormat::Webp => decode_with_image(bytes, format, limits),
    })
}

fn decode_with_image(
    bytes: &[u8],
    format: ImageFormat,
    limits: &DecodeLimits,
) -> Result<GrayImage, DecodeError> {
    let mut reader = image_reader(bytes, format);
    let mut image_limits = image::Limits::default();
    // RGBA8 at the pixel limit, plus the luma copy.
    image_limits.max_alloc = Some(limits.max_pixels.saturating_mul(5));
    reader.limits(image_limits);
    let decoder = reader.into_decoder().map_err(|e| corrupt(format, e))?;
    let (w, h) = decoder.dimensions();
    let image = image::DynamicImage::from_decoder(decoder).map_err(|e| corrupt(format, e))?;
    let luma = image.into_luma8();
    GrayImage::new(w as usize, h as usize, luma.into_raw())
        .ok_or_else(|| corrupt(format, "decoded size mismatch"))
}

#[cfg(test)]
mod tests;
