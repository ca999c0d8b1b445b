//! The output file of a render: [`Encoding`] (JPEG at a quality, or PNG) and [`encode`].

use super::RenderError;
use qrpose_detect::decode::GrayImage;
use serde::{Deserialize, Serialize};

/// How to encode the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Encoding {
    /// JPEG at this quality (1-100).
    Jpeg(u8),
    /// Lossless PNG.
    Png,
}

/// Encodes a grayscale image as JPEG or PNG.
///
/// # Errors
/// [`RenderError::Image`] when the encoder fails.
pub fn encode(image: &GrayImage, encoding: Encoding) -> Result<Vec<u8>, RenderError> {
    let err = |e: image::ImageError| RenderError::Image {
        reason: e.to_string(),
    };
    let (Ok(w), Ok(h)) = (u32::try_from(image.width()), u32::try_from(image.height())) else {
        return Err(RenderError::ImageSize {
            width_px: u32::MAX,
            height_px: u32::MAX,
        });
    };
    let mut out = Vec::new();
    match encoding {
        Encoding::Jpeg(q) => {
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, q)
                .encode(image.pixels(), w, h, image::ExtendedColorType::L8)
                .map_err(err)?;
        }
        Encoding::Png => {
            use image::ImageEncoder;
            image::codecs::png::PngEncoder::new(&mut out)
                .write_image(image.pixels(), w, h, image::ExtendedColorType::L8)
                .map_err(err)?;
        }
    }
    Ok(out)
}
