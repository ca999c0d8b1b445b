//! The backend registry and the types every backend shares: which libraries there are
//! ([`Backend`], [`DetectorChoice`]), what one reports ([`Candidate`]), the interface each
//! implements ([`Detector`]), and which detector serves a backend ([`detector_for`]; `auto`
//! tries them best first, `auto_order`). The detectors themselves ([`RqrrDetector`],
//! [`RxingDetector`], `ZxingCppDetector` with the `zxing-cpp` feature) live in one module
//! each; rxing's has beside it this crate's bit-for-bit rewrites of rxing's binarisers and
//! finder-pattern search.

pub(crate) mod rqrr;
pub(crate) mod rxing;
#[cfg(feature = "zxing-cpp")]
pub(crate) mod zxing_cpp;

pub use rqrr::RqrrDetector;
pub use rxing::RxingDetector;
#[cfg(feature = "zxing-cpp")]
pub use zxing_cpp::ZxingCppDetector;

use crate::raster::GrayImage;
use qrpose_core::geometry::frames::PixelPoint;
use thiserror::Error;

/// A detector library.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Backend {
    /// rqrr (pure Rust).
    Rqrr,
    /// rxing (pure Rust port of ZXing).
    Rxing,
    /// zxing-cpp (C++, cargo feature `zxing-cpp`).
    ZxingCpp,
}

impl Backend {
    /// The wire name: "rqrr", "rxing", "zxing-cpp".
    pub fn as_str(self) -> &'static str {
        match self {
            Backend::Rqrr => "rqrr",
            Backend::Rxing => "rxing",
            Backend::ZxingCpp => "zxing-cpp",
        }
    }

    /// Whether this build contains the backend.
    pub fn is_built(self) -> bool {
        match self {
            Backend::Rqrr | Backend::Rxing => true,
            Backend::ZxingCpp => cfg!(feature = "zxing-cpp"),
        }
    }
}

/// What the caller asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DetectorChoice {
    /// The best backend built, with fallbacks (see the module doc).
    #[default]
    Auto,
    /// Exactly this backend, one pass.
    Only(Backend),
}

/// A symbol as a backend reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Corners in qr order, px, as the backend gives them (whole pixels), corrected for
    /// known backend offsets.
    pub corners_px: [PixelPoint; 4],
    /// The symbol's content bytes; `None` when found but not decodable.
    pub payload: Option<Vec<u8>>,
    /// The content as text, as the backend interprets it (ECI / character set), if it is text.
    pub text: Option<String>,
    /// Modules per side (21 + 4 per version above 1), when the backend knows it.
    pub module_count: Option<usize>,
    /// Who found it.
    pub backend: Backend,
}

/// One QR detector library.
pub trait Detector {
    /// Which library this is.
    fn backend(&self) -> Backend;
    /// Every QR symbol the library finds. A failure inside the library (including a panic)
    /// counts as finding nothing.
    fn detect(&self, image: &GrayImage) -> Vec<Candidate>;
}

/// Why detection could not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum DetectError {
    /// The requested backend is not in this build (zxing-cpp needs the cargo feature).
    #[error("the {} detector is not built into this binary", backend.as_str())]
    BackendNotBuilt {
        /// The backend asked for.
        backend: Backend,
    },
}

/// The detector for a backend.
///
/// # Errors
/// [`DetectError::BackendNotBuilt`] for zxing-cpp in a build without the feature.
pub fn detector_for(backend: Backend) -> Result<Box<dyn Detector>, DetectError> {
    match backend {
        Backend::Rqrr => Ok(Box::new(rqrr::RqrrDetector)),
        Backend::Rxing => Ok(Box::new(rxing::RxingDetector::hybrid())),
        #[cfg(feature = "zxing-cpp")]
        Backend::ZxingCpp => Ok(Box::new(zxing_cpp::ZxingCppDetector::thorough())),
        #[cfg(not(feature = "zxing-cpp"))]
        Backend::ZxingCpp => Err(DetectError::BackendNotBuilt { backend }),
    }
}

/// The backends `auto` tries, best first.
pub(crate) fn auto_order() -> Vec<Backend> {
    [Backend::ZxingCpp, Backend::Rxing, Backend::Rqrr]
        .into_iter()
        .filter(|b| b.is_built())
        .collect()
}
