//! Image to QR codes: decode the bytes, find every symbol with one or more backends, read
//! it, and refine its corners to a fraction of a pixel. No async, no HTTP.
//!
//! - [`decode`]: bytes → [`decode::GrayImage`], with [`decode::DecodeLimits`].
//! - Backends behind [`Detector`]: [`rqrr`] and [`rxing`] always; `zxing_cpp` with the
//!   `zxing-cpp` cargo feature. [`DetectorChoice::Auto`] makes a quick pass first
//!   (zxing-cpp's single read when built, else rxing on a half-scale copy of a large
//!   image), then runs each backend at full resolution, best first, then second passes of
//!   the best one on a contrast-stretched, inverted or double-scale copy, stopping as soon
//!   as a code is read; results are merged by position. Symbols found but not read are
//!   read again through their refined module grid ([`reread`]).
//! - [`corners`]: sub-pixel corners and the twelve finder-pattern corners, whatever the
//!   backend ([`profile`] measures single edges, [`homography`] maps the module grid).
//!
//! Conventions: corners in `"qr"` order (top-left, top-right, bottom-right, bottom-left of
//! the symbol), pixels with integer pixel centres (SPEC section 1).

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

pub mod corners;
pub mod decode;
pub mod finders;
pub mod homography;
pub mod profile;
pub mod reread;
pub mod rqrr;
pub mod rxing;
#[cfg(feature = "zxing-cpp")]
pub mod zxing_cpp;

use crate::geometry::frames::PixelPoint;
use corners::{RefineStatus, refine_corners};
use decode::GrayImage;
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
pub fn auto_order() -> Vec<Backend> {
    [Backend::ZxingCpp, Backend::Rxing, Backend::Rqrr]
        .into_iter()
        .filter(|b| b.is_built())
        .collect()
}

/// One detected symbol with refined corners.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedCode {
    /// What the backend reported.
    pub candidate: Candidate,
    /// Refined corners and finder corners.
    pub refinement: corners::Refinement,
}

impl DetectedCode {
    /// The corners to use, px, qr order: refined when refinement succeeded.
    pub fn corners_px(&self) -> &[PixelPoint; 4] {
        &self.refinement.corners_px
    }
    /// Whether the corners are refined.
    pub fn is_refined(&self) -> bool {
        self.refinement.status == RefineStatus::Refined
    }
}

/// Centroid of four corners.
fn centroid(c: &[PixelPoint; 4]) -> PixelPoint {
    PixelPoint::new(
        c.iter().map(PixelPoint::u).sum::<f64>() / 4.0,
        c.iter().map(PixelPoint::v).sum::<f64>() / 4.0,
    )
}

fn shortest_side_px(c: &[PixelPoint; 4]) -> f64 {
    (0..4)
        .map(|i| (c[i].0 - c[(i + 1) % 4].0).norm())
        .fold(f64::INFINITY, f64::min)
}

/// True when two candidates are the same symbol (centres closer than half a side).
fn same_symbol(a: &Candidate, b: &Candidate) -> bool {
    let d = (centroid(&a.corners_px).0 - centroid(&b.corners_px).0).norm();
    d < 0.5 * shortest_side_px(&a.corners_px).min(shortest_side_px(&b.corners_px))
}

/// Adds `new` candidates to `into`, replacing an undecoded one by a decoded duplicate.
pub fn merge_candidates(into: &mut Vec<Candidate>, new: Vec<Candidate>) {
    for c in new {
        match into.iter_mut().find(|e| same_symbol(e, &c)) {
            Some(existing) => {
                if existing.payload.is_none() && c.payload.is_some() {
                    *existing = c;
                }
            }
            None => into.push(c),
        }
    }
}

/// Images up to this many px on their longer side get a double-scale second pass (the last
/// one: four times the pixels). Codes of 2-3 px per module under heavy blur, which every
/// backend misses at their own size, are found there.
pub const UPSCALE_MAX_SIDE_PX: usize = 1920;

/// One second pass of `auto`: a detector on a variant of the image, and the scale that maps
/// the variant's pixels back (source px per variant px).
struct SecondPass {
    detector: Box<dyn Detector>,
    image: GrayImage,
    scale: f64,
}

/// Blur of the blurred global-histogram pass, px: it smooths halftone and sensor noise of
/// small photos before the single threshold.
pub const DENOISE_SIGMA_PX: f64 = 1.0;

/// The second passes of `auto`, cheapest first, each built only when reached:
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
fn second_passes(image: &GrayImage, best: Backend) -> impl Iterator<Item = SecondPass> + '_ {
    type Make<'a> = Box<dyn Fn() -> Option<SecondPass> + 'a>;
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
    let pass = |detector: Option<Box<dyn Detector>>, image: Option<GrayImage>, scale: f64| {
        Some(SecondPass {
            detector: detector?,
            image: image?,
            scale,
        })
    };
    let small = image.width().max(image.height()) <= UPSCALE_MAX_SIDE_PX;
    let makers: Vec<Make<'_>> = vec![
        Box::new(move || pass(global(), Some(image.clone()), 1.0)),
        Box::new(move || pass(global(), sharpen(image, DENOISE_SIGMA_PX, -1.0), 1.0)),
        Box::new(move || pass(local(), stretch_contrast(image), 1.0)),
        Box::new(move || {
            (best != Backend::ZxingCpp)
                .then(|| pass(local(), invert(image), 1.0))
                .flatten()
        }),
        Box::new(move || {
            pass(
                local(),
                sharpen(image, SHARPEN_SIGMA_PX, SHARPEN_AMOUNT),
                1.0,
            )
        }),
        Box::new(move || {
            small
                .then(|| pass(local(), upscale_double(image), 0.5))
                .flatten()
        }),
        Box::new(move || {
            let double = small.then(|| upscale_double(image)).flatten()?;
            let sharp = sharpen(
                &double,
                2.0 * SHARPEN_DOUBLE_SIGMA_PX,
                SHARPEN_DOUBLE_AMOUNT,
            );
            pass(local(), sharp, 0.5)
        }),
    ];
    makers.into_iter().filter_map(|make| make())
}

/// Unsharp mask of the sharpened second pass: Gaussian σ, source px.
pub const SHARPEN_SIGMA_PX: f64 = 1.5;
/// Unsharp mask of the sharpened second pass: amount (1 doubles the detail).
pub const SHARPEN_AMOUNT: f64 = 2.0;
/// Unsharp mask of the sharpened double-scale pass: Gaussian σ, source px.
pub const SHARPEN_DOUBLE_SIGMA_PX: f64 = 1.0;
/// Unsharp mask of the sharpened double-scale pass: amount.
pub const SHARPEN_DOUBLE_AMOUNT: f64 = 3.0;

/// Unsharp mask: `image + amount · (image − Gaussian(image, σ))`, clamped to 0-255
/// (`amount` = −1 is the Gaussian blur itself).
/// Blur of σ ≈ 0.5 module leaves a module-wide pattern a sixth of its contrast; this gives
/// the binarisers of the backends some of it back (measured on the rendered set, see
/// docs/detection.md).
pub fn sharpen(image: &GrayImage, sigma_px: f64, amount: f64) -> Option<GrayImage> {
    let (w, h) = (image.width(), image.height());
    let radius = (3.0 * sigma_px).ceil().max(1.0) as usize;
    let kernel: Vec<f32> = {
        let raw: Vec<f64> = (0..=2 * radius)
            .map(|k| {
                let x = k as f64 - radius as f64;
                (-0.5 * x * x / (sigma_px * sigma_px)).exp()
            })
            .collect();
        let sum: f64 = raw.iter().sum();
        raw.iter().map(|k| (k / sum) as f32).collect()
    };
    let src: Vec<f32> = image.pixels().iter().map(|&p| f32::from(p)).collect();
    // Horizontal pass on an edge-padded copy of each row, then the vertical pass a whole
    // row at a time (both loops vectorise).
    let mut tmp = vec![0.0f32; w * h];
    let mut padded = vec![0.0f32; w + 2 * radius];
    for (row, out) in src.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
        let (first, last) = (row[0], row[w - 1]);
        padded[..radius].fill(first);
        padded[radius..radius + w].copy_from_slice(row);
        padded[radius + w..].fill(last);
        for (o, window) in out.iter_mut().zip(padded.windows(2 * radius + 1)) {
            *o = kernel.iter().zip(window).map(|(k, p)| k * p).sum();
        }
    }
    let amount = amount as f32;
    let mut blurred = vec![0.0f32; w];
    let mut pixels = Vec::with_capacity(w * h);
    for (y, row) in src.chunks_exact(w).enumerate() {
        blurred.fill(0.0);
        for (k, &kv) in kernel.iter().enumerate() {
            let yy = (y + k).saturating_sub(radius).min(h - 1);
            for (b, &t) in blurred.iter_mut().zip(&tmp[yy * w..(yy + 1) * w]) {
                *b += kv * t;
            }
        }
        pixels.extend(
            row.iter()
                .zip(&blurred)
                .map(|(&v, &b)| (v + amount * (v - b)).round().clamp(0.0, 255.0) as u8),
        );
    }
    GrayImage::new(w, h, pixels)
}

/// The photographic negative, for light-on-dark codes.
pub fn invert(image: &GrayImage) -> Option<GrayImage> {
    let pixels = image.pixels().iter().map(|p| 255 - p).collect();
    GrayImage::new(image.width(), image.height(), pixels)
}

/// Doubles the image by bilinear interpolation (pixel centres kept: copy pixel (x, y)
/// samples the source at ((x + 0.5) / 2 − 0.5, (y + 0.5) / 2 − 0.5)).
pub fn upscale_double(image: &GrayImage) -> Option<GrayImage> {
    let (w, h) = (image.width() * 2, image.height() * 2);
    let max_u = (image.width() - 1) as f64;
    let max_v = (image.height() - 1) as f64;
    let mut pixels = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let u = ((x as f64 + 0.5) / 2.0 - 0.5).clamp(0.0, max_u);
            let v = ((y as f64 + 0.5) / 2.0 - 0.5).clamp(0.0, max_v);
            pixels.push(image.sample(u, v).unwrap_or(0.0).round().clamp(0.0, 255.0) as u8);
        }
    }
    GrayImage::new(w, h, pixels)
}

/// Stretches the 1st-99th percentile range to 0-255; `None` when it is already full.
pub fn stretch_contrast(image: &GrayImage) -> Option<GrayImage> {
    let mut hist = [0usize; 256];
    for &p in image.pixels() {
        hist[usize::from(p)] += 1;
    }
    let total = image.pixels().len();
    let pct = |q: f64| {
        let target = (q * total as f64) as usize;
        let mut acc = 0;
        for (value, count) in hist.iter().enumerate() {
            acc += count;
            if acc > target {
                return value;
            }
        }
        255
    };
    let (lo, hi) = (pct(0.01), pct(0.99));
    if hi <= lo || (lo < 10 && hi > 245) {
        return None;
    }
    let scale = 255.0 / (hi - lo) as f64;
    let pixels = image
        .pixels()
        .iter()
        .map(|&p| (((f64::from(p) - lo as f64) * scale).clamp(0.0, 255.0)).round() as u8)
        .collect();
    GrayImage::new(image.width(), image.height(), pixels)
}

/// Halves the image by 2 × 2 box averaging (rounded); an odd last row or column is dropped.
pub fn downscale_half(image: &GrayImage) -> Option<GrayImage> {
    let (w, h) = (image.width() / 2, image.height() / 2);
    let stride = image.width();
    // Row by row into a zeroed buffer, vertical sums first: both loops vectorise.
    let mut pixels = vec![0u8; w * h];
    let mut sums = vec![0u16; 2 * w];
    for (out, pair) in pixels
        .chunks_exact_mut(w.max(1))
        .zip(image.pixels().chunks_exact(2 * stride))
    {
        let (top, bottom) = pair.split_at(stride);
        for ((s, &t), &b) in sums.iter_mut().zip(top).zip(bottom) {
            *s = u16::from(t) + u16::from(b);
        }
        for (o, s) in out.iter_mut().zip(sums.chunks_exact(2)) {
            // At most (4 · 255 + 2) / 4 = 255.
            *o = ((s[0] + s[1] + 2) >> 2) as u8;
        }
    }
    GrayImage::new(w, h, pixels)
}

/// Maps candidates found on a downscaled copy (`scale` source px per copy px) back to the
/// source: pixel centres scale about −0.5.
fn rescale(mut c: Candidate, scale: f64) -> Candidate {
    if scale != 1.0 {
        c.corners_px = c
            .corners_px
            .map(|p| PixelPoint::new((p.u() + 0.5) * scale - 0.5, (p.v() + 0.5) * scale - 0.5));
        // The module count measured on the copy is still right; whole-pixel corners are not.
    }
    c
}

/// Images whose shorter side has at least this many px are first searched at half scale by
/// the pure-Rust backends (`auto` in a build without zxing-cpp): a quarter of the pixels to
/// binarise and scan. Codes of at least about 4 px per module (2 px at half scale) are read
/// there; smaller ones fall through to the full-resolution pass.
pub const HALF_SCALE_FIRST_MIN_SIDE_PX: usize = 700;

/// Margin around a symbol found at half scale for the full-resolution read of its
/// surroundings: a share of the symbol's bounding box on each side, plus the quiet zone.
const CROP_MARGIN_SHARE: f64 = 0.25;
/// Fixed extra margin of that crop, px.
const CROP_MARGIN_PX: f64 = 8.0;

/// The quick first pass of `auto`: zxing-cpp's one read when it is built, otherwise rxing
/// on a half-scale copy of a large image and then again at full resolution on a crop around
/// each symbol it read (whole-pixel corners at full resolution, for the refinement, at the
/// cost of a few small images); `None` when there is no quick pass for this image.
fn quick_pass(image: &GrayImage, best: Backend) -> Option<Vec<Candidate>> {
    match best {
        #[cfg(feature = "zxing-cpp")]
        Backend::ZxingCpp => Some(zxing_cpp::ZxingCppDetector::fast().detect(image)),
        Backend::Rxing if image.width().min(image.height()) >= HALF_SCALE_FIRST_MIN_SIDE_PX => {
            let half = downscale_half(image)?;
            let mut found = Vec::new();
            for rough in rxing::RxingDetector::hybrid().detect(&half) {
                let rough = rescale(rough, 2.0);
                let Some(crop) = Crop::around(image, &rough.corners_px) else {
                    continue;
                };
                let precise = crop
                    .image
                    .as_ref()
                    .map(|c| rxing::RxingDetector::hybrid().detect(c));
                let precise: Vec<Candidate> = precise
                    .unwrap_or_default()
                    .into_iter()
                    .filter(|c| c.payload.is_some())
                    .map(|c| crop.to_source(c))
                    .collect();
                merge_candidates(&mut found, precise);
            }
            Some(found)
        }
        _ => None,
    }
}

/// A rectangle of an image, copied out, with its offset in the source.
struct Crop {
    image: Option<GrayImage>,
    x0: usize,
    y0: usize,
}

impl Crop {
    /// The bounding box of `corners_px` widened by the crop margins, clamped to the image.
    fn around(image: &GrayImage, corners_px: &[PixelPoint; 4]) -> Option<Self> {
        let (mut lo_u, mut lo_v, mut hi_u, mut hi_v) = (
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        );
        for p in corners_px {
            lo_u = lo_u.min(p.u());
            lo_v = lo_v.min(p.v());
            hi_u = hi_u.max(p.u());
            hi_v = hi_v.max(p.v());
        }
        if !(lo_u.is_finite() && lo_v.is_finite() && hi_u.is_finite() && hi_v.is_finite()) {
            return None;
        }
        let margin = CROP_MARGIN_SHARE * (hi_u - lo_u).max(hi_v - lo_v) + CROP_MARGIN_PX;
        let max_u = (image.width() - 1) as f64;
        let max_v = (image.height() - 1) as f64;
        let x0 = (lo_u - margin).clamp(0.0, max_u).floor() as usize;
        let y0 = (lo_v - margin).clamp(0.0, max_v).floor() as usize;
        let x1 = (hi_u + margin).clamp(0.0, max_u).ceil() as usize;
        let y1 = (hi_v + margin).clamp(0.0, max_v).ceil() as usize;
        let (w, h) = (x1.checked_sub(x0)? + 1, y1.checked_sub(y0)? + 1);
        let mut pixels = Vec::with_capacity(w * h);
        for row in image.pixels().chunks_exact(image.width()).skip(y0).take(h) {
            pixels.extend_from_slice(row.get(x0..x0 + w)?);
        }
        Some(Self {
            image: GrayImage::new(w, h, pixels),
            x0,
            y0,
        })
    }

    /// A candidate found in the crop, in source pixels.
    fn to_source(&self, mut c: Candidate) -> Candidate {
        let (dx, dy) = (self.x0 as f64, self.y0 as f64);
        c.corners_px = c
            .corners_px
            .map(|p| PixelPoint::new(p.u() + dx, p.v() + dy));
        c
    }
}

fn any_decoded(found: &[Candidate]) -> bool {
    found.iter().any(|c| c.payload.is_some())
}

/// Reads every undecoded candidate again through its refined module grid
/// ([`reread::reread`]); `tried` holds the corners of candidates already tried, so that
/// each is refined once however often `auto` calls this.
fn reread_undecoded(image: &GrayImage, found: &mut [Candidate], tried: &mut Vec<[PixelPoint; 4]>) {
    for c in found.iter_mut().filter(|c| c.payload.is_none()) {
        if tried.contains(&c.corners_px) {
            continue;
        }
        tried.push(c.corners_px);
        let refinement = refine_corners(image, &c.corners_px, c.module_count);
        let (RefineStatus::Refined, Some(n)) = (refinement.status, refinement.module_count) else {
            continue;
        };
        if let Some(read) = reread::reread(image, &refinement.corners_px, n) {
            c.payload = Some(read.payload);
            c.text = read.text;
            c.module_count = Some(n);
        }
    }
}

/// Every candidate the choice finds in `image`, before refinement.
///
/// `auto`: a quick pass first ([`HALF_SCALE_FIRST_MIN_SIDE_PX`], zxing-cpp's single read);
/// then each backend in [`auto_order`] at full resolution; then second passes of the best
/// one on front-end variants ([`second_passes`]). It stops after the first step that
/// reads a code; undecoded symbols found on the way are kept. Every choice reads symbols
/// that its backend found but could not decode again through their refined module grid
/// ([`reread`]).
///
/// # Errors
/// [`DetectError::BackendNotBuilt`] when a single backend is asked for that is not built.
pub fn find_candidates(
    image: &GrayImage,
    choice: DetectorChoice,
) -> Result<Vec<Candidate>, DetectError> {
    match choice {
        DetectorChoice::Only(backend) => {
            let mut found = detector_for(backend)?.detect(image);
            reread_undecoded(image, &mut found, &mut Vec::new());
            Ok(found)
        }
        DetectorChoice::Auto => {
            let order = auto_order();
            let mut found: Vec<Candidate> = Vec::new();
            let mut tried = Vec::new();
            let Some(&best) = order.first() else {
                return Ok(found);
            };
            // Each step's candidates are re-read before they are merged, so that an unread
            // duplicate from an earlier step does not shadow a symbol this step can read.
            let mut add = |found: &mut Vec<Candidate>, mut new: Vec<Candidate>| {
                reread_undecoded(image, &mut new, &mut tried);
                merge_candidates(found, new);
                any_decoded(found)
            };
            if let Some(quick) = quick_pass(image, best)
                && add(&mut found, quick)
            {
                return Ok(found);
            }
            for backend in &order {
                if add(&mut found, detector_for(*backend)?.detect(image)) {
                    return Ok(found);
                }
            }
            for pass in second_passes(image, best) {
                let mut more: Vec<Candidate> = pass
                    .detector
                    .detect(&pass.image)
                    .into_iter()
                    .map(|c| rescale(c, pass.scale))
                    .collect();
                if pass.scale < 1.0 && !any_decoded(&more) {
                    // rqrr finds blurred symbols on the enlarged copy that it cannot read;
                    // their refined grids often can be (at full resolution).
                    more.extend(
                        rqrr::RqrrDetector
                            .detect(&pass.image)
                            .into_iter()
                            .map(|c| rescale(c, pass.scale)),
                    );
                }
                if add(&mut found, more) {
                    break;
                }
            }
            Ok(found)
        }
    }
}

/// Finds, reads and refines every QR symbol in `image`.
///
/// # Errors
/// [`DetectError::BackendNotBuilt`] when a single backend is asked for that is not built.
pub fn detect_codes(
    image: &GrayImage,
    choice: DetectorChoice,
) -> Result<Vec<DetectedCode>, DetectError> {
    let candidates = find_candidates(image, choice)?;
    Ok(candidates
        .into_iter()
        .map(|candidate| {
            let refinement = refine_corners(image, &candidate.corners_px, candidate.module_count);
            DetectedCode {
                candidate,
                refinement,
            }
        })
        .collect())
}
