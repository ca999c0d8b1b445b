//! The zxing-cpp backend (C++, bundled and built by the `zxing-cpp` cargo feature).
//! Reads every QR symbol, also inverted ones, and returns found-but-undecodable symbols too
//! (`ReturnErrors`), whose payload is then `None`. Corners are whole pixels; the module
//! count comes from the symbol's version.

use super::decode::GrayImage;
use super::{Backend, Candidate, Detector};
use crate::geometry::frames::PixelPoint;

/// zxing-cpp behind the [`Detector`] interface.
#[derive(Debug, Clone, Copy, Default)]
pub struct ZxingCppDetector;

fn point(p: zxingcpp::PointI) -> PixelPoint {
    PixelPoint::new(f64::from(p.x), f64::from(p.y))
}

fn detect_unguarded(image: &GrayImage) -> Vec<Candidate> {
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
        .try_invert(true)
        .try_rotate(true)
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
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| detect_unguarded(image)))
            .unwrap_or_default()
    }
}
