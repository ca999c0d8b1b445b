//! Annotated images: the photo with what qrpose found drawn on it, for
//! `POST /v1/pose/image/annotated` and `qrpose estimate --image … --annotate OUT`.
//!
//! [`overlay`] turns an image response and its camera into pixel primitives (outlines,
//! corner marks, payload labels, the projected axes of each pose); [`raster`] draws them;
//! [`codec`] decodes the photo in colour and encodes the result as JPEG or PNG. Colours and
//! what is drawn are listed in docs/service.md, The annotated image. The library crates
//! know nothing of this: drawing is a concern of the service and the CLI.

pub mod codec;
pub mod overlay;
pub mod raster;

use crate::api::image::ImageResponse;
use crate::geometry::camera::Camera;
pub use codec::CodecError;

/// The encoding of an annotated image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OutputFormat {
    /// JPEG (the default).
    #[default]
    Jpeg,
    /// PNG: lossless, so every drawn pixel keeps its exact colour.
    Png,
}

impl OutputFormat {
    /// The media type.
    pub fn media_type(self) -> &'static str {
        match self {
            Self::Jpeg => "image/jpeg",
            Self::Png => "image/png",
        }
    }

    /// The format a file name asks for: `.png` (any case) is PNG, anything else JPEG.
    pub fn from_file_name(name: &std::path::Path) -> Self {
        match name.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("png") => Self::Png,
            _ => Self::Jpeg,
        }
    }
}

/// The photo `bytes` with the overlay of `response` drawn on it, encoded as `format`.
/// `camera` must be the one the poses of `response` were computed with (it projects their
/// axes). CPU-bound: decode, draw, encode.
///
/// # Errors
/// [`CodecError`] when the photo cannot be decoded in colour or the result encoded.
pub fn annotated_image(
    bytes: &[u8],
    response: &ImageResponse,
    camera: &Camera,
    format: OutputFormat,
) -> Result<Vec<u8>, CodecError> {
    let mut raster = codec::decode_rgb(bytes)?;
    let style = raster::Style::for_image(raster.width_px(), raster.height_px());
    let overlay = overlay::overlay_of(response, camera, style.label_height_px());
    raster::draw_overlay(&mut raster, &overlay, &style);
    match format {
        OutputFormat::Jpeg => codec::encode_jpeg(&raster),
        OutputFormat::Png => codec::encode_png(&raster),
    }
}
