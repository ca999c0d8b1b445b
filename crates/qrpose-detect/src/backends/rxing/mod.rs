//! The rxing backend: rxing's port of zxing-cpp's QR reader (`qrcode::cpp_port::QrReader`),
//! multi-symbol, try-harder, on rxing's hybrid (local) binariser, or on its global-histogram
//! one ([`RxingDetector::global_histogram`], for `auto`'s second passes). Corners are whole
//! pixels. The reader's steps are taken one by one (`read`) to keep the module count,
//! which rxing's results drop. rxing lists the corners as TL, TR, BL, BR (checked on
//! rendered ground truth); they are reordered here.
//!
//! rxing's own parts rewritten for speed, each giving rxing's result bit for bit (a test
//! beside each compares them with rxing's): the hybrid binariser ([`hybrid_binarizer`]),
//! the global-histogram binariser ([`global_binarizer`](mod@global_binarizer)), both
//! building their bit matrix at once ([`binarizer`]), and the finder-pattern search (module
//! `finder_scan`). They lean on rxing's internals, which is why the workspace pins rxing's
//! exact version.

mod binarizer;
mod finder_scan;
mod global_binarizer;
mod hybrid_binarizer;

use crate::backends::{Backend, Candidate, Detector};
use crate::contain::contain;
use crate::raster::GrayImage;
use crate::search::pairs::FinderPattern;
use crate::search::region::{Region, inside_quad};
use finder_scan::find_finder_patterns;
use global_binarizer::global_binarizer;
pub(crate) use hybrid_binarizer::LOCAL_WINDOW_PX;
use hybrid_binarizer::local_binarizer;
use qrpose_core::geometry::frames::PixelPoint;
use rxing::common::DetectorRXingResult;
use rxing::common::cpp_essentials::concentric_finder::ConcentricPattern;
use rxing::qrcode::cpp_port::decoder::Decode;
use rxing::qrcode::cpp_port::detector::{FinderPatternSet, GenerateFinderPatternSets, SampleQR};
use rxing::qrcode::detector::QRCodeDetectorResult;
use rxing::{BarcodeFormat, Binarizer, Luma8Source, Point, RXingResult};

/// rxing behind the [`Detector`] interface.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RxingDetector {
    /// The global-histogram binariser instead of the hybrid one.
    global_histogram: bool,
    /// Triples whose grid was sampled but did not decode come back as undecoded candidates
    /// (their sampled corners and module count), for the re-read through the refined grid.
    located: bool,
}

impl RxingDetector {
    /// On the hybrid (local block) binariser, rxing's default for 2-D codes.
    pub fn hybrid() -> Self {
        Self::default()
    }
    /// The hybrid binariser, returning also the symbols whose grid was sampled but did not
    /// decode (payload `None`): `auto`'s crop reads of small candidates hand them to the
    /// re-read through the refined grid ([`crate::search::reread()`]).
    pub fn located() -> Self {
        Self {
            located: true,
            ..Self::default()
        }
    }
    /// On the global-histogram binariser (one threshold per row from the histogram).
    pub fn global_histogram() -> Self {
        Self {
            global_histogram: true,
            ..Self::default()
        }
    }
}

/// What one read found: the symbols it decoded, the regions of finder-pattern triples it
/// could not read, and the finder patterns that no decoded symbol used.
type Read = (Vec<Candidate>, Vec<Region>, Vec<FinderPattern>);

fn detect_unguarded(image: &GrayImage, detector: RxingDetector, read_codes: &[Quad]) -> Read {
    let (Ok(w), Ok(h)) = (u32::try_from(image.width()), u32::try_from(image.height())) else {
        return Read::default();
    };
    let Ok(source) = Luma8Source::new_with_slice(image.pixels(), w, h) else {
        return Read::default();
    };
    if detector.global_histogram {
        read(&global_binarizer(source), detector.located, read_codes)
    } else {
        read(&local_binarizer(source), detector.located, read_codes)
    }
}

/// rxing's multi-symbol QR read (`QrReader::decode_multiple_with_hints` with try-harder,
/// QR codes only), step by step through rxing's public parts so that the sampled grid's
/// size, the module count, is kept: the reader's own results drop it. Triples that do not
/// sample or decode are returned as [`Region`]s, where `auto` may look again, and so are
/// the finder patterns that no decoded symbol used (see [`crate::search::pairs`]).
///
/// A triple whose three finder patterns each lie inside one of `read_codes` (codes an
/// earlier pass decoded, in this image's pixels) is skipped unsampled: a finder pattern
/// belongs to one code, so the triple can only be those codes again. Its patterns count as
/// used.
fn read<B: Binarizer>(binarizer: &B, located: bool, read_codes: &[Quad]) -> Read {
    let Ok(binary) = binarizer.get_black_matrix() else {
        return Read::default();
    };
    let mut patterns = find_finder_patterns(binary);
    let mut used: Vec<ConcentricPattern> = Vec::new();
    let mut found = Vec::new();
    let mut unread = Vec::new();
    for set in GenerateFinderPatternSets(&mut patterns) {
        if [set.bl, set.tl, set.tr].iter().any(|p| used.contains(p)) {
            continue;
        }
        if of_read_codes(&set, read_codes) {
            used.extend([set.bl, set.tl, set.tr]);
            continue;
        }
        let sampled = SampleQR(binary, &set).ok();
        let decoded = sampled
            .as_ref()
            .and_then(|sampled| Decode(sampled.getBits()).ok().filter(|d| d.isValid()));
        let (Some(sampled), Some(decoded)) = (sampled.as_ref(), decoded) else {
            unread.extend(region_of(&set));
            if located {
                found.extend(sampled.as_ref().and_then(undecoded));
            }
            continue;
        };
        used.extend([set.bl, set.tl, set.tr]);
        let module_count = usize::try_from(sampled.getBits().getWidth()).ok();
        let result =
            RXingResult::with_decoder_result(decoded, sampled.getPoints(), BarcodeFormat::QR_CODE);
        let Some(corners_px) = qr_corners(result.getPoints()) else {
            continue;
        };
        found.push(Candidate {
            corners_px,
            payload: Some(result.getRawBytes().to_vec()),
            text: Some(result.getText().to_owned()),
            module_count,
            backend: Backend::Rxing,
        });
    }
    let lone = patterns
        .iter()
        .filter(|p| !used.contains(p))
        .map(|p| FinderPattern {
            centre: centre_of(p),
            size_px: f64::from(p.size),
        })
        .collect();
    (found, unread, lone)
}

/// A symbol whose grid was sampled but did not decode: its sampled corners (qr order) and
/// module count, no payload.
fn undecoded(sampled: &QRCodeDetectorResult) -> Option<Candidate> {
    Some(Candidate {
        corners_px: qr_corners(sampled.getPoints())?,
        payload: None,
        text: None,
        module_count: usize::try_from(sampled.getBits().getWidth()).ok(),
        backend: Backend::Rxing,
    })
}

/// The corners of a quadrilateral as rxing lists them (top-left, top-right, bottom-left,
/// bottom-right, for decoded and sampled symbols alike) in qr order; `None` when fewer than
/// four.
fn qr_corners(points: &[Point]) -> Option<[PixelPoint; 4]> {
    let corner = |i: usize| {
        points
            .get(i)
            .map(|p| PixelPoint::new(f64::from(p.x), f64::from(p.y)))
    };
    Some([corner(0)?, corner(1)?, corner(3)?, corner(2)?])
}

/// A code's corners, px.
type Quad = [PixelPoint; 4];

/// Whether each of the triple's finder-pattern centres lies inside one of `read_codes`.
fn of_read_codes(set: &FinderPatternSet, read_codes: &[Quad]) -> bool {
    !read_codes.is_empty()
        && [&set.tl, &set.tr, &set.bl]
            .iter()
            .all(|p| read_codes.iter().any(|q| inside_quad(q, &centre_of(p))))
}

/// The region of an unread finder-pattern triple.
fn region_of(set: &FinderPatternSet) -> Option<Region> {
    let finder_px = f64::from(set.tl.size.max(set.tr.size).max(set.bl.size));
    Region::from_finder_centres(
        centre_of(&set.tl),
        centre_of(&set.tr),
        centre_of(&set.bl),
        finder_px,
    )
}

/// A finder pattern's centre, px.
fn centre_of(p: &ConcentricPattern) -> PixelPoint {
    PixelPoint::new(f64::from(p.p.x), f64::from(p.p.y))
}

impl Detector for RxingDetector {
    fn backend(&self) -> Backend {
        Backend::Rxing
    }

    fn detect(&self, image: &GrayImage) -> Vec<Candidate> {
        self.detect_with_regions(image).0
    }
}

impl RxingDetector {
    /// The symbols read in `image`, and the regions of the finder-pattern triples that
    /// could not be read (for `auto`'s further passes).
    #[must_use]
    pub(crate) fn detect_with_regions(&self, image: &GrayImage) -> (Vec<Candidate>, Vec<Region>) {
        self.detect_skipping(image, &[])
    }

    /// [`Self::detect_with_regions`] without sampling the finder-pattern triples of codes
    /// already read (`read_codes`, corners in `image`'s pixels): a reduced copy's read of a
    /// frame whose full-resolution read decoded them spends nothing on them again.
    #[must_use]
    pub(crate) fn detect_skipping(
        &self,
        image: &GrayImage,
        read_codes: &[Quad],
    ) -> (Vec<Candidate>, Vec<Region>) {
        let (found, regions, _) =
            contain(|| detect_unguarded(image, *self, read_codes)).unwrap_or_default();
        (found, regions)
    }

    /// [`Self::detect_with_regions`], and the finder patterns that no decoded symbol used.
    #[must_use]
    pub(crate) fn detect_with_patterns(
        &self,
        image: &GrayImage,
    ) -> (Vec<Candidate>, Vec<Region>, Vec<FinderPattern>) {
        contain(|| detect_unguarded(image, *self, &[])).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_frames::DrawnCode;

    /// A reduced copy's read skips the triple of a code read already, and only that one: it
    /// neither decodes it again nor makes it a region, while a code elsewhere is read.
    #[test]
    fn a_read_skips_the_triples_of_codes_read_already() {
        let image = DrawnCode::new("READ-BEFORE", 5, 100, 80).frame(640, 480, 40, 200);
        let (found, regions) = RxingDetector::hybrid().detect_with_regions(&image);
        let texts: Vec<_> = found.iter().filter_map(|c| c.text.as_deref()).collect();
        assert_eq!(texts, ["READ-BEFORE"]);
        assert!(regions.is_empty());
        let read_before = found.first().expect("one code").corners_px;

        let (again, regions) = RxingDetector::hybrid().detect_skipping(&image, &[read_before]);
        assert!(again.is_empty(), "{again:?}");
        assert!(regions.is_empty(), "{regions:?}");

        let elsewhere = read_before.map(|p| PixelPoint::new(p.u() + 300.0, p.v()));
        let (found, _) = RxingDetector::hybrid().detect_skipping(&image, &[elsewhere]);
        let texts: Vec<_> = found.iter().filter_map(|c| c.text.as_deref()).collect();
        assert_eq!(texts, ["READ-BEFORE"]);
    }
}
