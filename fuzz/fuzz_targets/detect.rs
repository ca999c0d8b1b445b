//! The detector (every backend and `auto` at every effort) on small arbitrary grey images:
//! never a panic of our own code, every corner finite. The first two bytes give the width
//! and height (1-64 px), the rest the pixels (repeated to fill the frame).
//!
//! rqrr panics on some inputs (a bug upstream); the service contains that, and so
//! does `qrpose_detect`. libFuzzer's panic hook would abort on it even inside
//! `catch_unwind`, so this target replaces it with a silent one: a contained third-party
//! panic is not a finding, while an uncontained panic anywhere still reaches libFuzzer's
//! `catch_unwind` and aborts the process (a crash).
#![no_main]

use libfuzzer_sys::fuzz_target;
use qrpose_detect::budget::{Budget, Effort};
use qrpose_detect::decode::GrayImage;
use qrpose_detect::{Backend, DetectorChoice, detect_within};
use std::time::Duration;

fn image_of(bytes: &[u8]) -> Option<GrayImage> {
    let (&w, rest) = bytes.split_first()?;
    let (&h, pixels) = rest.split_first()?;
    let (w, h) = (usize::from(w % 64) + 1, usize::from(h % 64) + 1);
    if pixels.is_empty() {
        return None;
    }
    let data = pixels.iter().copied().cycle().take(w * h).collect();
    GrayImage::new(w, h, data)
}

fuzz_target!(
    init: {
        // Contained panics of third-party backends are expected; see the module doc.
        std::panic::set_hook(Box::new(|_| {}));
    },
    |bytes: &[u8]| {
        let Some(image) = image_of(bytes) else {
            return;
        };
        let effort = match bytes.len() % 3 {
            0 => Effort::Fast,
            1 => Effort::Balanced,
            _ => Effort::Thorough,
        };
        let budget = Budget::new(effort, Some(Duration::from_secs(5)));
        for choice in [
            DetectorChoice::Auto,
            DetectorChoice::Only(Backend::Rqrr),
            DetectorChoice::Only(Backend::Rxing),
        ] {
            if let Ok(detection) = detect_within(&image, choice, &budget) {
                for code in &detection.codes {
                    for corner in code.corners_px() {
                        assert!(corner.u().is_finite() && corner.v().is_finite());
                    }
                }
            }
        }
    }
);
