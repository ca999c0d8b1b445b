//! Reads of the regions a caller names ([`crate::detect_in_regions`]): where a video stream's
//! tracks predict their codes, only crops of those regions are read, at a higher effort
//! there than `auto`'s first read of a whole frame.
//!
//! Each region is cut out of the frame (clipped to it; a region wholly outside is skipped)
//! and read, cheapest first, until a pass decodes the region's code (one whose centre is
//! near the predicted corners, not a neighbour in the margin):
//!
//! 1. rxing at the crop's own scale, keeping the symbols it locates but cannot decode, which
//!    are read again through their refined module grid (module `reread`);
//! 2. (`balanced`, `thorough`) on a crop whose shorter side is at least
//!    [`HALF_SCALE_FIRST_MIN_SIDE_PX`], rxing at half scale (codes close to the camera,
//!    moiré); then `auto`'s crop passes: the global-histogram binariser (plain and
//!    denoised), a contrast-stretched, an inverted and a sharpened copy, a double-scale copy
//!    plain and sharpened; on a crop of at most
//!    [`QUAD_MAX_SIDE_PX`](super::auto::passes::QUAD_MAX_SIDE_PX), a quadruple-scale
//!    sharpened read (codes of 1.5-2 px per module); `thorough` adds rqrr's own search.
//!
//! A code predicted across the frame's edge (leaving the view) is cut there and cannot be
//! decoded: its region gets the first read only (it may still be wholly inside, the
//! prediction being uncertain), not the closer passes.
//!
//! Passes are logged as `track crop K <pass>` (K: the region's index in the caller's list).
//! Before every pass but the very first the budget's deadline and cancel flag are checked
//! ([`PassLog`]), so a spent or cancelled budget stops between regions and between passes.
//! What the crops find is merged by position (a code in two overlapping regions is one
//! code) and returned in the frame's pixels.

use super::auto::HALF_SCALE_FIRST_MIN_SIDE_PX;
use super::auto::passes::{SecondPass, decoded, look_closer, quad_sharpened, read_crop, variants};
use super::merge::{centroid, merge_candidates, reread_undecoded};
use super::region::{Crop, Region};
use crate::backends::{RxingDetector, auto_order, detector_for};
use crate::budget::{Effort, PassLog};
use crate::raster::{GrayImage, downscale_half};
use crate::{Backend, Candidate, Detector};
use qrpose_core::geometry::frames::PixelPoint;
use std::borrow::Cow;

/// A part of the frame where a code is expected, px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SearchRegion {
    /// A code's predicted corners (any order), and a margin added on every side of their
    /// bounding box: the prediction's uncertainty and room for the code's quiet zone (a
    /// few modules; the crop reads fail on a code cut at its edge).
    Quad {
        /// The predicted corners, px.
        corners_px: [PixelPoint; 4],
        /// Added on every side of the corners' box, px (at least 0).
        margin_px: f64,
    },
    /// An axis-aligned rectangle: its top-left and bottom-right pixel positions, px.
    Rect {
        /// Smallest u and v, px.
        min_px: PixelPoint,
        /// Largest u and v, px.
        max_px: PixelPoint,
    },
}

impl SearchRegion {
    /// The region's box; `None` when it is empty, a coordinate is not finite, or the margin
    /// is negative.
    fn bounds(&self) -> Option<Region> {
        let finite = |points: &[PixelPoint]| {
            points
                .iter()
                .all(|p| p.u().is_finite() && p.v().is_finite())
        };
        match *self {
            Self::Quad {
                corners_px,
                margin_px,
            } => (finite(&corners_px) && margin_px >= 0.0)
                .then(|| Region::around(&corners_px, margin_px))
                .flatten(),
            Self::Rect { min_px, max_px } => finite(&[min_px, max_px])
                .then(|| Region::around(&[min_px, max_px], 0.0))
                .flatten(),
        }
    }

    /// Where the region's own code has its centre: the box of the predicted corners widened
    /// by half the margin (the prediction's error), or the rectangle. A crop's read that
    /// decodes only a neighbouring code, partly in the margin, has not read this one.
    fn core(&self) -> Option<Region> {
        match *self {
            Self::Quad {
                corners_px,
                margin_px,
            } => Region::around(&corners_px, 0.5 * margin_px),
            Self::Rect { .. } => self.bounds(),
        }
    }

    /// Whether the region's code can lie wholly in `image`: a quad's predicted corners all
    /// inside it, between its outer pixel edges (−0.5 to width − 0.5: integer coordinates
    /// are pixel centres; a rectangle: always). A code cut by the frame's edge cannot be
    /// decoded, so a code predicted across the edge (leaving the view) gets the first read
    /// only.
    fn code_may_be_whole(&self, image: &GrayImage) -> bool {
        let (width, height) = (image.width() as f64, image.height() as f64);
        match self {
            Self::Quad { corners_px, .. } => {
                corners_px.iter().all(|p| p.inside_image(width, height))
            }
            Self::Rect { .. } => true,
        }
    }

    /// The pixels of the region that lie in `image`, with their offset; `None` when none do.
    fn crop(&self, image: &GrayImage) -> Option<Crop> {
        let r = self.bounds()?;
        let (max_u, max_v) = ((image.width() - 1) as f64, (image.height() - 1) as f64);
        let overlaps = r.hi_u >= 0.0 && r.lo_u <= max_u && r.hi_v >= 0.0 && r.lo_v <= max_v;
        overlaps
            .then(|| Crop::with_margin(image, &r, 0.0))
            .flatten()
    }
}

/// What the crops have found so far.
struct Reads<'a> {
    image: &'a GrayImage,
    found: Vec<Candidate>,
    /// Corners of undecoded candidates already re-read.
    tried: Vec<[PixelPoint; 4]>,
}

impl Reads<'_> {
    /// Re-reads the undecoded of `new` through their module grid and merges them in;
    /// whether one of them is decoded with its centre in `core`.
    fn add(&mut self, mut new: Vec<Candidate>, core: &Region) -> bool {
        reread_undecoded(self.image, &mut new, &mut self.tried);
        let done = new
            .iter()
            .any(|c| c.payload.is_some() && core.contains(&centroid(&c.corners_px)));
        merge_candidates(&mut self.found, new);
        done
    }
}

/// Every candidate that the reads of `regions` find in `image` at `effort`, in the frame's
/// pixels, before the deadline of `log` (see the module doc).
pub(crate) fn find_in_regions(
    image: &GrayImage,
    regions: &[SearchRegion],
    effort: Effort,
    log: &mut PassLog,
) -> Vec<Candidate> {
    let mut reads = Reads {
        image,
        found: Vec::new(),
        tried: Vec::new(),
    };
    let Some(&best) = auto_order().first() else {
        return reads.found;
    };
    let mut first = true;
    for (k, region) in regions.iter().enumerate() {
        if !first && !log.may_continue() {
            break;
        }
        let (Some(crop), Some(core)) = (region.crop(image), region.core()) else {
            continue;
        };
        let Some(pixels) = crop.image.as_ref() else {
            continue;
        };
        first = false;
        let prefix = format!("track crop {k} ");
        let read = log.run(
            format!("{prefix}rxing"),
            |v: &Vec<Candidate>| decoded(v),
            || read_crop(&crop, &RxingDetector::located(), pixels, 1.0),
        );
        if reads.add(read, &core) || effort == Effort::Fast || !region.code_may_be_whole(image) {
            continue;
        }
        for pass in closer_passes(pixels, best, effort) {
            let Some(read) = pass.run(&prefix, log, |d, variant, scale| {
                read_crop(&crop, d, variant, scale)
            }) else {
                return reads.found;
            };
            if reads.add(read, &core) {
                break;
            }
        }
    }
    reads.found
}

/// The passes after the first on a crop whose first read decoded nothing, cheapest first
/// (see the module doc).
fn closer_passes(crop: &GrayImage, best: Backend, effort: Effort) -> Vec<SecondPass<'_>> {
    let mut passes = Vec::new();
    if crop.width().min(crop.height()) >= HALF_SCALE_FIRST_MIN_SIDE_PX {
        passes.extend(SecondPass::new(
            "half",
            detector_for(Backend::Rxing).ok(),
            2.0,
            move || downscale_half(crop).map(Cow::Owned),
        ));
    }
    if effort == Effort::Thorough {
        passes.extend(look_closer(crop, best));
    } else {
        passes.extend(variants(crop, best));
    }
    let located = || -> Option<Box<dyn Detector>> { Some(Box::new(RxingDetector::located())) };
    passes.extend(quad_sharpened(crop, located()));
    passes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: usize, height: usize) -> GrayImage {
        GrayImage::new(width, height, vec![200; width * height]).expect("a size")
    }

    fn quad(lo: f64, hi: f64, margin_px: f64) -> SearchRegion {
        SearchRegion::Quad {
            corners_px: [
                PixelPoint::new(lo, lo),
                PixelPoint::new(hi, lo),
                PixelPoint::new(hi, hi),
                PixelPoint::new(lo, hi),
            ],
            margin_px,
        }
    }

    #[test]
    fn a_region_is_clipped_to_the_frame_and_maps_back_to_it() {
        let frame = image(100, 80);
        let crop = quad(60.0, 90.0, 20.0).crop(&frame).expect("overlaps");
        let pixels = crop.image.as_ref().expect("pixels");
        // 40..=99 across, 40..=79 down.
        assert_eq!((pixels.width(), pixels.height()), (60, 40));
        let back = crop.to_source(Candidate {
            corners_px: [PixelPoint::new(0.0, 0.0); 4],
            payload: None,
            text: None,
            module_count: None,
            backend: Backend::Rxing,
        });
        assert_eq!(back.corners_px[0], PixelPoint::new(40.0, 40.0));
    }

    #[test]
    fn a_region_outside_the_frame_or_degenerate_has_no_crop() {
        let frame = image(100, 80);
        assert!(quad(120.0, 150.0, 10.0).crop(&frame).is_none());
        assert!(quad(-60.0, -20.0, 10.0).crop(&frame).is_none());
        assert!(quad(10.0, 20.0, -1.0).crop(&frame).is_none());
        assert!(quad(10.0, f64::NAN, 1.0).crop(&frame).is_none());
        let flat = SearchRegion::Rect {
            min_px: PixelPoint::new(10.0, 10.0),
            max_px: PixelPoint::new(10.0, 50.0),
        };
        assert!(flat.crop(&frame).is_none());
        let rect = SearchRegion::Rect {
            min_px: PixelPoint::new(-5.0, 70.0),
            max_px: PixelPoint::new(10.0, 95.0),
        };
        let pixels = rect.crop(&frame).expect("overlaps").image.expect("pixels");
        assert_eq!((pixels.width(), pixels.height()), (11, 10));
    }

    #[test]
    fn a_regions_own_code_is_centred_near_its_corners_not_in_its_outer_margin() {
        let core = quad(100.0, 200.0, 40.0).core().expect("a core");
        // The corners' box widened by half the margin: 80..220.
        assert!(core.contains(&PixelPoint::new(150.0, 150.0)));
        assert!(core.contains(&PixelPoint::new(215.0, 85.0)));
        assert!(!core.contains(&PixelPoint::new(230.0, 150.0)));
    }

    #[test]
    fn a_blank_region_reads_nothing_and_logs_its_passes() {
        let frame = image(300, 200);
        let mut log = PassLog::new(std::time::Duration::from_secs(60));
        let found = find_in_regions(
            &frame,
            &[quad(50.0, 150.0, 10.0)],
            Effort::Balanced,
            &mut log,
        );
        assert!(found.is_empty());
        assert_eq!(
            log.passes.first().map(|p| p.name.as_str()),
            Some("track crop 0 rxing")
        );
        assert!(log.passes.len() > 1, "{:?}", log.passes);
        assert!(
            log.passes
                .iter()
                .all(|p| p.name.starts_with("track crop 0 "))
        );
        let mut fast = PassLog::new(std::time::Duration::from_secs(60));
        find_in_regions(&frame, &[quad(50.0, 150.0, 10.0)], Effort::Fast, &mut fast);
        assert_eq!(fast.passes.len(), 1);
    }

    #[test]
    fn a_code_predicted_across_the_frames_edge_gets_the_first_read_only() {
        let frame = image(300, 200);
        let mut log = PassLog::new(std::time::Duration::from_secs(60));
        // Corners 180..260 down a 200-row frame: the code would be cut by the bottom edge.
        find_in_regions(
            &frame,
            &[quad(180.0, 260.0, 10.0)],
            Effort::Balanced,
            &mut log,
        );
        let names: Vec<&str> = log.passes.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["track crop 0 rxing"]);
        // Corners up to 199.4, inside the last row's pixels (it ends at 199.5): every pass.
        let mut inside = PassLog::new(std::time::Duration::from_secs(60));
        find_in_regions(
            &frame,
            &[quad(100.0, 199.4, 10.0)],
            Effort::Balanced,
            &mut inside,
        );
        assert!(inside.passes.len() > 1, "{:?}", inside.passes);
        // A rectangle names no code: every pass runs on it.
        let mut rect = PassLog::new(std::time::Duration::from_secs(60));
        let whole = SearchRegion::Rect {
            min_px: PixelPoint::new(180.0, 100.0),
            max_px: PixelPoint::new(299.0, 199.0),
        };
        find_in_regions(&frame, &[whole], Effort::Balanced, &mut rect);
        assert!(rect.passes.len() > 1, "{:?}", rect.passes);
    }
}
