//! The zxing-cpp backend (C++, bundled and built by the `zxing-cpp` cargo feature).
//! Reads every QR symbol and returns found-but-undecodable symbols too (`ReturnErrors`),
//! whose payload is then `None`. Corners are whole pixels; the module count comes from the
//! symbol's version.
//!
//! Settings: [`ZxingCppDetector::thorough`] (the library's defaults: try harder, also
//! inverted, and again on a 2×-downscaled pyramid down to 500 px; zxing-cpp runs *every*
//! layer and both polarities whatever it already found, six reads of a 1280×720 frame),
//! [`ZxingCppDetector::fast`] (one read of the image as it is, normal polarity), which
//! `auto` tries first, and [`ZxingCppDetector::global_histogram`] (one read with the
//! global-histogram binariser instead of the local-average one, for `auto`'s second
//! passes). Text comes in zxing-cpp's `Plain` mode: the content itself, not its
//! human-readable rendering (`<SOH>` for control characters, `(01)` for GS1 fields).

use super::{Backend, Candidate, Detector};
use crate::contain::contain;
use crate::raster::GrayImage;
use qrpose_core::geometry::frames::PixelPoint;

/// zxing-cpp behind the [`Detector`] interface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ZxingCppDetector {
    /// One read at full resolution, normal polarity, instead of the library's pyramid of
    /// scales and both polarities.
    fast: bool,
    /// The global-histogram binariser instead of the local-average one.
    global_histogram: bool,
}

impl ZxingCppDetector {
    /// The library's default search: every pyramid layer, both polarities.
    pub fn thorough() -> Self {
        Self {
            fast: false,
            global_histogram: false,
        }
    }
    /// One read of the image as it is (normal polarity, no downscaled layers).
    pub fn fast() -> Self {
        Self {
            fast: true,
            global_histogram: false,
        }
    }
    /// One read with the global-histogram binariser (one threshold for the whole image).
    pub fn global_histogram() -> Self {
        Self {
            fast: true,
            global_histogram: true,
        }
    }
}

impl Default for ZxingCppDetector {
    fn default() -> Self {
        Self::thorough()
    }
}

fn point(p: zxingcpp::PointI) -> PixelPoint {
    PixelPoint::new(f64::from(p.x), f64::from(p.y))
}

fn detect_unguarded(image: &GrayImage, settings: ZxingCppDetector) -> Vec<Candidate> {
    let Ok(view) = zxingcpp::ImageView::from_slice(
        image.pixels(),
        image.width(),
        image.height(),
        zxingcpp::ImageFormat::Lum,
    ) else {
        return Vec::new();
    };
    let reader = zxingcpp::read()
        .formats([zxingcpp::BarcodeFormat::QRCode])
        .try_harder(true)
        .try_invert(!settings.fast)
        .try_downscale(!settings.fast)
        .try_rotate(true)
        .binarizer(if settings.global_histogram {
            zxingcpp::Binarizer::GlobalHistogram
        } else {
            zxingcpp::Binarizer::LocalAverage
        })
        .text_mode(zxingcpp::TextMode::Plain)
        .return_errors(true);
    let Ok(barcodes) = reader.from(&view) else {
        return Vec::new();
    };
    barcodes
        .iter()
        .map(|b| {
            let pos = b.position();
            let valid = b.is_valid();
            let module_count = b
                .extra_with_key("Version")
                .trim()
                .parse::<usize>()
                .ok()
                .filter(|v| (1..=40).contains(v))
                .map(|v| 17 + 4 * v);
            Candidate {
                corners_px: [
                    point(pos.top_left),
                    point(pos.top_right),
                    point(pos.bottom_right),
                    point(pos.bottom_left),
                ],
                payload: valid.then(|| b.bytes()),
                text: valid.then(|| b.text()),
                module_count,
                backend: Backend::ZxingCpp,
            }
        })
        .collect()
}

impl Detector for ZxingCppDetector {
    fn backend(&self) -> Backend {
        Backend::ZxingCpp
    }

    fn detect(&self, image: &GrayImage) -> Vec<Candidate> {
        contain(|| detect_unguarded(image, *self)).unwrap_or_default()
    }
}
