//! The rxing backend: rxing's port of zxing-cpp's QR reader (`qrcode::cpp_port::QrReader`),
//! multi-symbol, try-harder, on rxing's hybrid (local) binariser, or on its global-histogram
//! one ([`RxingDetector::global_histogram`], for `auto`'s second passes). Corners are whole pixels; the
//! module count is not reported and is measured by [`super::corners`]. rxing lists the
//! corners as TL, TR, BL, BR (checked on rendered ground truth); they are reordered here.

use super::decode::GrayImage;
use super::{Backend, Candidate, Detector};
use crate::geometry::frames::PixelPoint;
use rxing::common::{GlobalHistogramBinarizer, HybridBinarizer};
use rxing::multi::MultipleBarcodeReader;
use rxing::qrcode::cpp_port::QrReader;
use rxing::{BarcodeFormat, Binarizer, BinaryBitmap, DecodeHints, Luma8Source};
use std::collections::HashSet;

/// rxing behind the [`Detector`] interface.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RxingDetector {
    /// The global-histogram binariser instead of the hybrid one.
    global_histogram: bool,
}

impl RxingDetector {
    /// On the hybrid (local block) binariser, rxing's default for 2-D codes.
    pub fn hybrid() -> Self {
        Self {
            global_histogram: false,
        }
    }
    /// On the global-histogram binariser (one threshold per row from the histogram).
    pub fn global_histogram() -> Self {
        Self {
            global_histogram: true,
        }
    }
}

fn detect_unguarded(image: &GrayImage, global_histogram: bool) -> Vec<Candidate> {
    let (Ok(w), Ok(h)) = (u32::try_from(image.width()), u32::try_from(image.height())) else {
        return Vec::new();
    };
    let Ok(source) = Luma8Source::new_with_slice(image.pixels(), w, h) else {
        return Vec::new();
    };
    if global_histogram {
        read(BinaryBitmap::new(GlobalHistogramBinarizer::new(source)))
    } else {
        read(BinaryBitmap::new(HybridBinarizer::new(source)))
    }
}

fn read<B: Binarizer>(mut bitmap: BinaryBitmap<B>) -> Vec<Candidate> {
    let hints = DecodeHints {
        TryHarder: Some(true),
        PossibleFormats: Some(HashSet::from([BarcodeFormat::QR_CODE])),
        ..DecodeHints::default()
    };
    let Ok(results) = QrReader.decode_multiple_with_hints(&mut bitmap, &hints) else {
        return Vec::new();
    };
    results
        .iter()
        .filter(|r| *r.getBarcodeFormat() == BarcodeFormat::QR_CODE)
        .filter_map(|r| {
            let points = r.getPoints();
            let corner = |i: usize| {
                points
                    .get(i)
                    .map(|p| PixelPoint::new(f64::from(p.x), f64::from(p.y)))
            };
            // rxing lists the quadrilateral as top-left, top-right, bottom-left, bottom-right.
            let corners_px = [corner(0)?, corner(1)?, corner(3)?, corner(2)?];
            Some(Candidate {
                corners_px,
                payload: Some(r.getRawBytes().to_vec()),
                text: Some(r.getText().to_owned()),
                module_count: None,
                backend: Backend::Rxing,
            })
        })
        .collect()
}

impl Detector for RxingDetector {
    fn backend(&self) -> Backend {
        Backend::Rxing
    }

    fn detect(&self, image: &GrayImage) -> Vec<Candidate> {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            detect_unguarded(image, self.global_histogram)
        }))
        .unwrap_or_default()
    }
}
