//! The second passes of `auto`: a detector on an image variant (global histogram,
//! denoised, stretched, inverted, sharpened, double scale), each variant built only when its
//! pass runs, and the mapping of what they find back to the source pixels.

use crate::backends::detector_for;
#[cfg(feature = "zxing-cpp")]
use crate::backends::zxing_cpp;
use crate::backends::{rqrr, rxing};
use crate::budget::PassLog;
use crate::raster::GrayImage;
use crate::raster::{invert, sharpen, stretch_contrast, upscale_double};
use crate::search::region::Crop;
use crate::{Backend, Candidate, Detector};
use qrpose_core::geometry::frames::PixelPoint;
use std::borrow::Cow;
use std::time::Instant;

use super::UPSCALE_MAX_SIDE_PX;

/// One second pass of `auto`: a detector on a variant of the image, built only when the
/// pass runs (inside its timed [`PassLog`] entry, after the deadline was checked), and the
/// scale that maps the variant's pixels back (source px per variant px).
pub(in crate::search) struct SecondPass<'a> {
    pub(super) name: &'static str,
    /// The backend named in the log before `name`, where two read the same variant.
    pub(super) backend: Option<Backend>,
    detector: Box<dyn Detector>,
    /// The variant; `None` when it would not differ from what was read (e.g. a contrast
    /// stretch of an image that spans 0-255 already): the pass is then skipped.
    variant: Box<dyn FnOnce() -> Option<Cow<'a, GrayImage>> + 'a>,
    scale: f64,
}

impl<'a> SecondPass<'a> {
    pub(in crate::search) fn new(
        name: &'static str,
        detector: Option<Box<dyn Detector>>,
        scale: f64,
        variant: impl FnOnce() -> Option<Cow<'a, GrayImage>> + 'a,
    ) -> Option<Self> {
        Some(Self {
            name,
            backend: None,
            detector: detector?,
            variant: Box::new(variant),
            scale,
        })
    }

    /// This pass, logged with `backend`'s name before its own (`zxing-cpp stretched`): for
    /// a variant that another backend also reads in the same step.
    fn by(mut self, backend: Backend) -> Self {
        self.backend = Some(backend);
        self
    }

    /// Runs the pass, logged as `prefix` + its name, when the deadline allows and its
    /// variant exists; `read` turns the detector's candidates on the variant into the
    /// caller's. `None` when the deadline has passed (nothing was built).
    pub(in crate::search) fn run(
        self,
        prefix: &str,
        log: &mut PassLog,
        read: impl FnOnce(&dyn Detector, &GrayImage, f64) -> Vec<Candidate>,
    ) -> Option<Vec<Candidate>> {
        if !log.may_continue() {
            return None;
        }
        let started = Instant::now();
        let Some(variant) = (self.variant)() else {
            return Some(Vec::new());
        };
        Some(log.run_since(
            started,
            match self.backend {
                Some(backend) => format!("{prefix}{} {}", backend.as_str(), self.name),
                None => format!("{prefix}{}", self.name),
            },
            |v: &Vec<Candidate>| decoded(v),
            || read(self.detector.as_ref(), &variant, self.scale),
        ))
    }
}

/// The double-scale pass of `detector` on `image`; `None` without a detector.
pub(super) fn double(
    image: &GrayImage,
    detector: Option<Box<dyn Detector>>,
) -> Option<SecondPass<'_>> {
    SecondPass::new("double", detector, 0.5, move || {
        upscale_double(image).map(Cow::Owned)
    })
}

/// The double-scale sharpened pass of `detector` on `image` (the last of
/// [`second_passes`]); `None` without a detector.
pub(super) fn double_sharpened(
    image: &GrayImage,
    detector: Option<Box<dyn Detector>>,
) -> Option<SecondPass<'_>> {
    SecondPass::new("double sharpened", detector, 0.5, move || {
        let double = upscale_double(image)?;
        sharpen(
            &double,
            2.0 * SHARPEN_DOUBLE_SIGMA_PX,
            SHARPEN_DOUBLE_AMOUNT,
        )
        .map(Cow::Owned)
    })
}

/// The quadruple-scale sharpened pass of `detector` on a small crop (`None` without a
/// detector or when `image` is longer than [`QUAD_MAX_SIDE_PX`]): two double-scale steps,
/// then an unsharp mask of [`SHARPEN_QUAD_SIGMA_PX`] source px and [`SHARPEN_QUAD_AMOUNT`].
/// Codes of 1.5-2 px per module under blur form a triple at double scale whose sampled grid
/// still does not decode; at four times the pixels rxing's finder-centred sampling does.
pub(in crate::search) fn quad_sharpened(
    image: &GrayImage,
    detector: Option<Box<dyn Detector>>,
) -> Option<SecondPass<'_>> {
    if image.width().max(image.height()) > QUAD_MAX_SIDE_PX {
        return None;
    }
    SecondPass::new("quad sharpened", detector, 0.25, move || {
        // Sharpened at double scale, where a quarter of the pixels make the same mask.
        let double = upscale_double(image)?;
        let sharp = sharpen(&double, 2.0 * SHARPEN_QUAD_SIGMA_PX, SHARPEN_QUAD_AMOUNT)?;
        upscale_double(&sharp).map(Cow::Owned)
    })
}

/// Longest side of a crop that gets [`quad_sharpened`], px: the pass is for codes of about
/// 30-45 px, and sixteen times the pixels of a larger crop would cost more than the frame's
/// own reads.
pub(crate) const QUAD_MAX_SIDE_PX: usize = 160;
/// Unsharp mask of the quadruple-scale pass: Gaussian σ, source px.
pub(crate) const SHARPEN_QUAD_SIGMA_PX: f64 = 0.75;
/// Unsharp mask of the quadruple-scale pass: amount.
pub(crate) const SHARPEN_QUAD_AMOUNT: f64 = 2.0;

/// What a pass on a crop found, in the source's pixels: `detector` on `variant` (`scale`
/// crop px per variant px), mapped back through `crop`.
pub(in crate::search) fn read_crop(
    crop: &Crop,
    detector: &dyn Detector,
    variant: &GrayImage,
    scale: f64,
) -> Vec<Candidate> {
    detector
        .detect(variant)
        .into_iter()
        .map(|c| crop.to_source(rescale(c, scale)))
        .collect()
}

/// Blur of the blurred global-histogram pass, px: it smooths halftone and sensor noise of
/// small photos before the single threshold.
pub(crate) const DENOISE_SIGMA_PX: f64 = 1.0;

/// The second passes of `auto`, cheapest first, each variant built only when its pass runs:
/// 1. the best backend with the global-histogram binariser, on the image and on a copy
///    blurred by [`DENOISE_SIGMA_PX`] (small noisy photos that the local binariser breaks
///    up);
/// 2. the best backend on a contrast-stretched, an inverted (unless zxing-cpp, which reads
///    the negative itself, is the best) and a sharpened ([`sharpen`]) copy;
/// 3. on a double-scale copy, plain and sharpened (images of at most
///    [`UPSCALE_MAX_SIDE_PX`]).
///
/// zxing-cpp runs its single-read settings here: its thorough one would read each variant
/// again downscaled and inverted, which its own full pass has covered.
pub(super) fn second_passes(image: &GrayImage, best: Backend) -> Vec<SecondPass<'_>> {
    let local = move || -> Option<Box<dyn Detector>> {
        match best {
            #[cfg(feature = "zxing-cpp")]
            Backend::ZxingCpp => Some(Box::new(zxing_cpp::ZxingCppDetector::fast())),
            other => detector_for(other).ok(),
        }
    };
    let global = move || -> Option<Box<dyn Detector>> {
        match best {
            #[cfg(feature = "zxing-cpp")]
            Backend::ZxingCpp => Some(Box::new(zxing_cpp::ZxingCppDetector::global_histogram())),
            Backend::Rqrr => None,
            _ => Some(Box::new(rxing::RxingDetector::global_histogram())),
        }
    };
    let owned = |variant: Option<GrayImage>| variant.map(Cow::Owned);
    let small = image.width().max(image.height()) <= UPSCALE_MAX_SIDE_PX;
    let mut passes = vec![
        SecondPass::new("global-histogram", global(), 1.0, move || {
            Some(Cow::Borrowed(image))
        }),
        SecondPass::new("denoised", global(), 1.0, move || {
            owned(sharpen(image, DENOISE_SIGMA_PX, -1.0))
        }),
        SecondPass::new("stretched", local(), 1.0, move || {
            owned(stretch_contrast(image))
        }),
    ];
    if best != Backend::ZxingCpp {
        passes.push(SecondPass::new("inverted", local(), 1.0, move || {
            owned(invert(image))
        }));
    }
    passes.push(SecondPass::new("sharpened", local(), 1.0, move || {
        owned(sharpen(image, SHARPEN_SIGMA_PX, SHARPEN_AMOUNT))
    }));
    if small {
        passes.push(double(image, local()));
        passes.push(double_sharpened(image, local()));
    }
    passes.into_iter().flatten().collect()
}

/// Unsharp mask of the sharpened second pass: Gaussian σ, source px.
pub(crate) const SHARPEN_SIGMA_PX: f64 = 1.5;
/// Unsharp mask of the sharpened second pass: amount (1 doubles the detail).
pub(crate) const SHARPEN_AMOUNT: f64 = 2.0;
/// Unsharp mask of the sharpened double-scale pass: Gaussian σ, source px.
pub(crate) const SHARPEN_DOUBLE_SIGMA_PX: f64 = 1.0;
/// Unsharp mask of the sharpened double-scale pass: amount.
pub(crate) const SHARPEN_DOUBLE_AMOUNT: f64 = 3.0;

/// Maps candidates found on a downscaled copy (`scale` source px per copy px) back to the
/// source: pixel centres scale about −0.5.
pub(super) fn rescale(mut c: Candidate, scale: f64) -> Candidate {
    if scale != 1.0 {
        c.corners_px = c
            .corners_px
            .map(|p| PixelPoint::new((p.u() + 0.5) * scale - 0.5, (p.v() + 0.5) * scale - 0.5));
        // The module count measured on the copy is still right; whole-pixel corners are not.
    }
    c
}

/// Decoded symbols in a pass's result.
pub(in crate::search) fn decoded(found: &[Candidate]) -> usize {
    found.iter().filter(|c| c.payload.is_some()).count()
}

/// The backend whose variants the default build reads where `best` is the best built: a
/// zxing-cpp build runs the default build's passes too, and zxing-cpp's after them, so
/// that it reads every code the default build reads (with zxing-cpp's variants in place of
/// rxing's it read fewer codes of the BoofCV `nominal` and `damaged` photos).
fn default_for(best: Backend) -> Backend {
    if best == Backend::ZxingCpp {
        Backend::Rxing
    } else {
        best
    }
}

/// A zxing-cpp build's own variants (none in the default build), logged under its name.
fn zxing_cpp_variants(image: &GrayImage, best: Backend) -> Vec<SecondPass<'_>> {
    if best == default_for(best) {
        return Vec::new();
    }
    second_passes(image, best)
        .into_iter()
        .map(|p| p.by(best))
        .collect()
}

/// Step 3's variants of the whole frame: the default build's [`second_passes`], then a
/// zxing-cpp build's.
pub(in crate::search) fn variants(image: &GrayImage, best: Backend) -> Vec<SecondPass<'_>> {
    let mut passes = second_passes(image, default_for(best));
    passes.extend(zxing_cpp_variants(image, best));
    passes
}

/// The passes of step 2 on one crop, cheapest first: the default build's variants of
/// [`second_passes`], then rqrr (its own finder search; the slowest, 20-30 ms even on a
/// small crop), then a zxing-cpp build's variants.
pub(in crate::search) fn look_closer(crop: &GrayImage, best: Backend) -> Vec<SecondPass<'_>> {
    let mut passes = second_passes(crop, default_for(best));
    passes.extend(SecondPass::new(
        "rqrr",
        Some(Box::new(rqrr::RqrrDetector)),
        1.0,
        move || Some(Cow::Borrowed(crop)),
    ));
    passes.extend(zxing_cpp_variants(crop, best));
    passes
}
