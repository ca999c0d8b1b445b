//! Where a symbol may be: [`Region`]s, the places of finder-pattern triples that a pass found
//! but could not read, and [`Crop`]s, the small images that `auto` spends further effort on
//! instead of the whole frame.
//!
//! A region is the bounding box of a triple's three finder-pattern centres and the fourth
//! corner of their parallelogram, widened by one finder pattern (7 modules) on each side so
//! that the whole symbol is inside. Regions that overlap a symbol already read, or another
//! region, are dropped ([`unread_regions`]), and so are triples whose three finder patterns
//! each lie inside a symbol already read: a finder pattern belongs to one symbol, so such a
//! triple is made of the patterns of codes read (neighbouring codes on a sheet of many). A
//! triple whose patterns are farther apart, in modules of their size, than a version 40
//! symbol's makes no region at all ([`Region::from_finder_centres`]).

// Pixel indices are floats clamped into the image before the cast.
#![allow(clippy::cast_possible_truncation)]

use crate::Candidate;
use crate::raster::GrayImage;
use crate::search::pairs::FinderPattern;
use qrpose_core::geometry::frames::PixelPoint;

/// An axis-aligned box of the image where a symbol may be, px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Region {
    /// Left edge, px.
    pub(crate) lo_u: f64,
    /// Top edge, px.
    pub(crate) lo_v: f64,
    /// Right edge, px.
    pub(crate) hi_u: f64,
    /// Bottom edge, px.
    pub(crate) hi_v: f64,
    /// Width of the finder patterns that made it (7 modules), px; 0 when unknown.
    pub(crate) finder_px: f64,
    /// Centres of the triple's three finder patterns, px; `None` for a box that no triple
    /// made.
    pub(crate) finders: Option<[PixelPoint; 3]>,
}

/// At most this many unread regions get further effort in one image: clutter can produce
/// dozens of finder-like triples, and each costs a few crop passes.
pub(crate) const MAX_REGIONS: usize = 16;

/// The most modules across a QR symbol (version 40, ISO/IEC 18004 Table 1).
const MAX_MODULES: f64 = 177.0;

impl Region {
    /// The region of a finder-pattern triple: centres `tl`, `tr`, `bl` (px) and the finder
    /// patterns' size `finder_px` (7 modules, the largest of the three). `None` when the
    /// triple spans more modules than any symbol has: finder centres are 3.5 modules in
    /// from the symbol's edges, so a symbol of N modules has them N − 7 modules apart, and
    /// a triple whose mean side is more than [`MAX_MODULES`] − 7 modules of the largest
    /// pattern's size (which gives the fewest modules) is clutter or patterns of different
    /// codes, not a symbol.
    #[must_use]
    pub(crate) fn from_finder_centres(
        tl: PixelPoint,
        tr: PixelPoint,
        bl: PixelPoint,
        finder_px: f64,
    ) -> Option<Self> {
        let module_px = finder_px / 7.0;
        let mean_side_px =
            0.5 * (nalgebra::distance(&tl.0, &tr.0) + nalgebra::distance(&tl.0, &bl.0));
        if module_px > 0.0 && mean_side_px / module_px > MAX_MODULES - 7.0 {
            return None;
        }
        let br = PixelPoint::new(tr.u() + bl.u() - tl.u(), tr.v() + bl.v() - tl.v());
        Self::around(&[tl, tr, br, bl], finder_px).map(|r| Self {
            finder_px,
            finders: Some([tl, tr, bl]),
            ..r
        })
    }

    /// The bounding box of `points` widened by `margin_px` on every side.
    #[must_use]
    pub(crate) fn around(points: &[PixelPoint], margin_px: f64) -> Option<Self> {
        let mut r = Self {
            lo_u: f64::INFINITY,
            lo_v: f64::INFINITY,
            hi_u: f64::NEG_INFINITY,
            hi_v: f64::NEG_INFINITY,
            finder_px: 0.0,
            finders: None,
        };
        for p in points {
            r.lo_u = r.lo_u.min(p.u() - margin_px);
            r.lo_v = r.lo_v.min(p.v() - margin_px);
            r.hi_u = r.hi_u.max(p.u() + margin_px);
            r.hi_v = r.hi_v.max(p.v() + margin_px);
        }
        let finite = [r.lo_u, r.lo_v, r.hi_u, r.hi_v]
            .iter()
            .all(|x| x.is_finite());
        (finite && r.hi_u > r.lo_u && r.hi_v > r.lo_v).then_some(r)
    }

    /// The same region in the source image of a copy scaled by `scale` source px per copy px
    /// (pixel centres scale about −0.5).
    #[must_use]
    pub(crate) fn rescaled(self, scale: f64) -> Self {
        let s = |x: f64| (x + 0.5) * scale - 0.5;
        Self {
            lo_u: s(self.lo_u),
            lo_v: s(self.lo_v),
            hi_u: s(self.hi_u),
            hi_v: s(self.hi_v),
            finder_px: self.finder_px * scale,
            finders: self
                .finders
                .map(|f| f.map(|p| PixelPoint::new(s(p.u()), s(p.v())))),
        }
    }

    fn area(&self) -> f64 {
        (self.hi_u - self.lo_u) * (self.hi_v - self.lo_v)
    }

    /// Area of the intersection over the area of the smaller box, in [0, 1].
    fn overlap(&self, other: &Self) -> f64 {
        let w = self.hi_u.min(other.hi_u) - self.lo_u.max(other.lo_u);
        let h = self.hi_v.min(other.hi_v) - self.lo_v.max(other.lo_v);
        if w <= 0.0 || h <= 0.0 {
            return 0.0;
        }
        w * h / self.area().min(other.area())
    }

    /// Whether `p` lies in the region (edges included).
    pub(crate) fn contains(&self, p: &PixelPoint) -> bool {
        (self.lo_u..=self.hi_u).contains(&p.u()) && (self.lo_v..=self.hi_v).contains(&p.v())
    }
}

/// Two regions (or a region and a read symbol) overlapping by more than this share of the
/// smaller are the same place.
const SAME_PLACE_OVERLAP: f64 = 0.5;

/// Whether two regions are the same place (overlapping by more than half of the smaller).
#[must_use]
pub(crate) fn same_place(a: &Region, b: &Region) -> bool {
    a.overlap(b) > SAME_PLACE_OVERLAP
}

/// Whether `p` lies inside the quadrilateral `quad` (corners in order around it, either
/// way round; a self-intersecting one contains nothing).
pub(crate) fn inside_quad(quad: &[PixelPoint; 4], p: &PixelPoint) -> bool {
    let side = |a: &PixelPoint, b: &PixelPoint| {
        (b.u() - a.u()) * (p.v() - a.v()) - (b.v() - a.v()) * (p.u() - a.u())
    };
    let sides: Vec<f64> = (0..4).map(|i| side(&quad[i], &quad[(i + 1) % 4])).collect();
    sides.iter().all(|&s| s > 0.0) || sides.iter().all(|&s| s < 0.0)
}

/// The regions worth more effort: not on a symbol already read (`found`, decoded ones), not
/// a triple whose three finder patterns each lie inside one (they are the read symbols'),
/// and one per place, largest first, at most [`MAX_REGIONS`].
#[must_use]
pub(crate) fn unread_regions(mut regions: Vec<Region>, found: &[Candidate]) -> Vec<Region> {
    regions.sort_by(|a, b| b.area().total_cmp(&a.area()));
    let decoded: Vec<&Candidate> = found.iter().filter(|c| c.payload.is_some()).collect();
    let read: Vec<Region> = decoded
        .iter()
        .filter_map(|c| Region::around(&c.corners_px, 0.0))
        .collect();
    let mut kept: Vec<Region> = Vec::new();
    for r in regions {
        let centre = PixelPoint::new(0.5 * (r.lo_u + r.hi_u), 0.5 * (r.lo_v + r.hi_v));
        let of_read_finders = r.finders.is_some_and(|finders| {
            finders
                .iter()
                .all(|f| decoded.iter().any(|c| inside_quad(&c.corners_px, f)))
        });
        let on_read = of_read_finders
            || read
                .iter()
                .any(|s| s.contains(&centre) || s.overlap(&r) > SAME_PLACE_OVERLAP);
        let seen = kept.iter().any(|k| k.overlap(&r) > SAME_PLACE_OVERLAP);
        if !on_read && !seen {
            kept.push(r);
            if kept.len() == MAX_REGIONS {
                break;
            }
        }
    }
    kept
}

/// A share of a box's longer side added on each side of a crop, for the quiet zone and the
/// error of a rough position.
const CROP_MARGIN_SHARE: f64 = 0.25;
/// Fixed extra margin of a crop, px.
const CROP_MARGIN_PX: f64 = 8.0;

/// A rectangle of an image, copied out, with its offset in the source.
pub(crate) struct Crop {
    /// The pixels; `None` when the rectangle is empty.
    pub(crate) image: Option<GrayImage>,
    x0: usize,
    y0: usize,
}

impl Crop {
    /// The bounding box of `corners_px` widened by the crop margins, clamped to the image.
    #[must_use]
    pub(crate) fn around(image: &GrayImage, corners_px: &[PixelPoint; 4]) -> Option<Self> {
        Self::of_region(image, &Region::around(corners_px, 0.0)?)
    }

    /// `region` widened by the crop margins, clamped to the image.
    #[must_use]
    pub(crate) fn of_region(image: &GrayImage, region: &Region) -> Option<Self> {
        let margin = CROP_MARGIN_SHARE * (region.hi_u - region.lo_u).max(region.hi_v - region.lo_v)
            + CROP_MARGIN_PX;
        Self::with_margin(image, region, margin)
    }

    /// `region` widened by `margin` px on every side, clamped to the image.
    #[must_use]
    pub(crate) fn with_margin(image: &GrayImage, region: &Region, margin: f64) -> Option<Self> {
        let max_u = (image.width() - 1) as f64;
        let max_v = (image.height() - 1) as f64;
        let x0 = (region.lo_u - margin).clamp(0.0, max_u).floor() as usize;
        let y0 = (region.lo_v - margin).clamp(0.0, max_v).floor() as usize;
        let x1 = (region.hi_u + margin).clamp(0.0, max_u).ceil() as usize;
        let y1 = (region.hi_v + margin).clamp(0.0, max_v).ceil() as usize;
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

    /// A source pixel position in the crop's pixels.
    #[must_use]
    pub(crate) fn to_crop(&self, p: &PixelPoint) -> PixelPoint {
        PixelPoint::new(p.u() - self.x0 as f64, p.v() - self.y0 as f64)
    }

    /// A region found in the crop, in source pixels.
    #[must_use]
    pub(crate) fn region_to_source(&self, r: Region) -> Region {
        let (dx, dy) = (self.x0 as f64, self.y0 as f64);
        Region {
            lo_u: r.lo_u + dx,
            lo_v: r.lo_v + dy,
            hi_u: r.hi_u + dx,
            hi_v: r.hi_v + dy,
            finder_px: r.finder_px,
            finders: r
                .finders
                .map(|f| f.map(|p| PixelPoint::new(p.u() + dx, p.v() + dy))),
        }
    }

    /// A finder pattern found in the crop, in source pixels.
    #[must_use]
    pub(crate) fn pattern_to_source(&self, p: FinderPattern) -> FinderPattern {
        FinderPattern {
            centre: PixelPoint::new(p.centre.u() + self.x0 as f64, p.centre.v() + self.y0 as f64),
            ..p
        }
    }

    /// A candidate found in the crop, in source pixels.
    #[must_use]
    pub(crate) fn to_source(&self, mut c: Candidate) -> Candidate {
        let (dx, dy) = (self.x0 as f64, self.y0 as f64);
        c.corners_px = c
            .corners_px
            .map(|p| PixelPoint::new(p.u() + dx, p.v() + dy));
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Backend;

    fn decoded_at(lo: f64, hi: f64) -> Candidate {
        Candidate {
            corners_px: [
                PixelPoint::new(lo, lo),
                PixelPoint::new(hi, lo),
                PixelPoint::new(hi, hi),
                PixelPoint::new(lo, hi),
            ],
            payload: Some(b"x".to_vec()),
            text: Some("x".to_owned()),
            module_count: Some(21),
            backend: Backend::Rxing,
        }
    }

    #[test]
    fn a_triple_region_covers_the_whole_symbol() {
        // Finder centres 3.5 modules in from the corners of a 21-module symbol of 4 px
        // modules at (100, 100): the symbol spans 100..184.
        let (m, o) = (4.0, 100.0);
        let c = |col: f64, row: f64| PixelPoint::new(o + col * m, o + row * m);
        let r = Region::from_finder_centres(c(3.5, 3.5), c(17.5, 3.5), c(3.5, 17.5), 7.0 * m)
            .expect("a region");
        assert!(r.lo_u <= o && r.lo_v <= o && r.hi_u >= o + 84.0 && r.hi_v >= o + 84.0);
    }

    #[test]
    fn a_triple_wider_than_a_version_40_symbol_makes_no_region() {
        // 4 px modules: a version 40 symbol (177 modules) has its finder centres 170
        // modules = 680 px apart.
        let p = |u: f64, v: f64| PixelPoint::new(u, v);
        assert!(
            Region::from_finder_centres(p(0.0, 0.0), p(680.0, 0.0), p(0.0, 680.0), 28.0).is_some()
        );
        assert!(
            Region::from_finder_centres(p(0.0, 0.0), p(700.0, 0.0), p(0.0, 700.0), 28.0).is_none()
        );
        // Unequal sides: their mean counts (1000 and 300 px: 162.5 modules).
        assert!(
            Region::from_finder_centres(p(0.0, 0.0), p(1000.0, 0.0), p(0.0, 300.0), 28.0).is_some()
        );
        // A 2 px finder pattern 400 px from its partners: 1400 modules, clutter.
        assert!(
            Region::from_finder_centres(p(0.0, 0.0), p(400.0, 0.0), p(0.0, 400.0), 14.0).is_none()
        );
    }

    #[test]
    fn regions_on_read_symbols_and_duplicates_are_dropped() {
        let region = |lo: f64, hi: f64| Region {
            lo_u: lo,
            lo_v: lo,
            hi_u: hi,
            hi_v: hi,
            finder_px: 0.0,
            finders: None,
        };
        let regions = vec![
            region(0.0, 100.0),   // on the read symbol
            region(300.0, 400.0), // unread
            region(310.0, 405.0), // the same place again
            region(600.0, 650.0), // unread, smaller
        ];
        let kept = unread_regions(regions, &[decoded_at(10.0, 90.0)]);
        assert_eq!(kept, vec![region(300.0, 400.0), region(600.0, 650.0)]);
    }

    fn decoded_box(u0: f64, v0: f64, u1: f64, v1: f64) -> Candidate {
        Candidate {
            corners_px: [
                PixelPoint::new(u0, v0),
                PixelPoint::new(u1, v0),
                PixelPoint::new(u1, v1),
                PixelPoint::new(u0, v1),
            ],
            ..decoded_at(0.0, 1.0)
        }
    }

    #[test]
    fn a_triple_of_read_symbols_finder_patterns_is_dropped() {
        // Three read 80 px codes of a sheet around a gap; a triple of one finder pattern of
        // each (12 px inside the code's corner nearest the gap) is no code of its own,
        // though its box covers a fifth of each read code and its centre none of them.
        // A triple with a pattern outside every read code may be an unread code's: kept.
        let read = [
            decoded_box(-68.0, -68.0, 12.0, 12.0),
            decoded_box(100.0, -68.0, 180.0, 12.0),
            decoded_box(-68.0, 100.0, 12.0, 180.0),
        ];
        let p = |u: f64, v: f64| PixelPoint::new(u, v);
        let across = Region::from_finder_centres(p(0.0, 0.0), p(112.0, 0.0), p(0.0, 112.0), 24.0)
            .expect("a region");
        // The same triple away from the codes stays.
        let beside =
            Region::from_finder_centres(p(400.0, 0.0), p(512.0, 0.0), p(400.0, 112.0), 24.0)
                .expect("a region");
        assert_eq!(unread_regions(vec![across, beside], &read), vec![beside]);
        let partly = Region::from_finder_centres(p(0.0, 0.0), p(112.0, 0.0), p(60.0, 300.0), 24.0)
            .expect("a region");
        assert_eq!(unread_regions(vec![partly], &read), vec![partly]);
    }

    #[test]
    fn at_most_max_regions_are_kept() {
        let regions = (0..40)
            .map(|k| {
                let lo = f64::from(k) * 100.0;
                Region {
                    lo_u: lo,
                    lo_v: 0.0,
                    hi_u: lo + 50.0,
                    hi_v: 50.0,
                    finder_px: 0.0,
                    finders: None,
                }
            })
            .collect();
        assert_eq!(unread_regions(regions, &[]).len(), MAX_REGIONS);
    }

    #[test]
    fn a_crop_maps_its_finds_back_to_the_source() {
        let image = GrayImage::new(200, 100, vec![128; 200 * 100]).expect("an image");
        let crop = Crop::of_region(
            &image,
            &Region {
                lo_u: 50.0,
                lo_v: 40.0,
                hi_u: 90.0,
                hi_v: 60.0,
                finder_px: 0.0,
                finders: None,
            },
        )
        .expect("inside");
        let small = crop.image.as_ref().expect("pixels");
        assert!(small.width() < 200 && small.height() <= 100);
        let found = crop.to_source(decoded_at(0.0, 10.0));
        assert!(found.corners_px[0].u() >= 0.0 && found.corners_px[0].u() <= 50.0);
    }
}
