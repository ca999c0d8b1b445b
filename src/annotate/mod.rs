//! Annotated images: the photo with what qrpose found drawn on it, for
//! `POST /v1/pose/image/annotated` and `qrpose estimate --image … --annotate OUT`.
//!
//! [`overlay`] turns the application's answer for a photo and its camera into pixel primitives (outlines,
//! corner marks, payload labels, the projected axes of each pose); [`raster`] draws them.
//! A JPEG photo asked for as JPEG is spliced by the `jpeg-overlay` crate
//! (crates/jpeg-overlay): only the 8×8 blocks the overlay touches are re-encoded, the rest
//! keeps the client's bytes. Otherwise, and whenever the splice cannot be exact, [`codec`]
//! decodes the whole photo in colour and encodes the result as JPEG or PNG. Colours and
//! what is drawn are listed in docs/service.md, The annotated image. The pose crates know
//! nothing of this: drawing is a concern of the service and the CLI; the splice only
//! records and encodes the pixels it is given.

pub mod codec;
pub mod overlay;
pub mod raster;

use crate::app::ImageAnswer;
use crate::detect::decode::{ImageFormat, sniff_format};
use crate::geometry::camera::Camera;
pub use codec::CodecError;
use jpeg_overlay::{CannotSplice, Jpeg};
use overlay::Overlay;
use raster::{RgbRaster, Style};

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

/// The photo `bytes` with the overlay of `answer` drawn on it, encoded as `format`.
/// `camera` must be the one the poses of `answer` were computed with (it projects their
/// axes). CPU-bound: a JPEG asked for as JPEG is spliced (only the blocks drawn into are
/// re-encoded); anything else, or a JPEG the splice refuses, is decoded, drawn and
/// encoded whole.
///
/// # Errors
/// [`CodecError`] when the photo cannot be decoded in colour or the result encoded.
pub fn annotated_image(
    bytes: &[u8],
    answer: &ImageAnswer,
    camera: &Camera,
    format: OutputFormat,
) -> Result<Vec<u8>, CodecError> {
    let size_px = (answer.width_px, answer.height_px);
    annotated_with(bytes, format, size_px, |label_height_px| {
        overlay::overlay_of(answer, camera, label_height_px)
    })
}

/// [`annotated_image`] for the overlay `overlay_for(label height, px)` on a photo that
/// decoded to `size_px` (width, height).
pub(crate) fn annotated_with(
    bytes: &[u8],
    format: OutputFormat,
    size_px: (usize, usize),
    overlay_for: impl Fn(f64) -> Overlay,
) -> Result<Vec<u8>, CodecError> {
    if format == OutputFormat::Jpeg && sniff_format(bytes) == Some(ImageFormat::Jpeg) {
        match spliced(bytes, size_px, &overlay_for) {
            Ok(jpeg) => return Ok(jpeg),
            Err(reason) => {
                tracing::debug!(%reason, "annotated JPEG: re-encoding the whole frame");
            }
        }
    }
    redrawn(bytes, format, &overlay_for)
}

/// The JPEG `bytes` with the overlay spliced in. Only when the frame header declares the
/// size the photo decoded to (`size_px`, within the service's pixel limit): the overlay's
/// coordinates are of that image, and the canvas is sized from the header.
fn spliced(
    bytes: &[u8],
    size_px: (usize, usize),
    overlay_for: &impl Fn(f64) -> Overlay,
) -> Result<Vec<u8>, CannotSplice> {
    let jpeg = Jpeg::parse(bytes)?;
    if (jpeg.width_px(), jpeg.height_px()) != size_px {
        return Err(CannotSplice::SizeMismatch);
    }
    let style = Style::for_image(jpeg.width_px(), jpeg.height_px());
    let mut drawing = jpeg.canvas();
    raster::draw_overlay(&mut drawing, &overlay_for(style.label_height_px()), &style);
    Ok(jpeg.splice(&drawing)?.bytes)
}

/// The photo decoded whole, drawn on and encoded as `format`.
pub(crate) fn redrawn(
    bytes: &[u8],
    format: OutputFormat,
    overlay_for: &impl Fn(f64) -> Overlay,
) -> Result<Vec<u8>, CodecError> {
    let mut raster: RgbRaster = codec::decode_rgb(bytes)?;
    let style = Style::for_image(raster.width_px(), raster.height_px());
    raster::draw_overlay(&mut raster, &overlay_for(style.label_height_px()), &style);
    match format {
        OutputFormat::Jpeg => codec::encode_jpeg(&raster),
        OutputFormat::Png => codec::encode_png(&raster),
    }
}

#[cfg(test)]
mod tests;
