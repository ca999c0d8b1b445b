//! Finder-pattern pairs: where a small code may be when a read saw only two of its three
//! finder patterns.
//!
//! Under blur a small code (2-3 px per module) often shows the binariser two finder patterns
//! and not the third, so no triple forms and no [`Region`] is made. Two lone patterns of
//! about the same size, as far apart as two finder patterns of one small code, fix where
//! that code can be: the third finder lies on either side of the line through them
//! (adjacent finders) or the two are opposite corners (diagonal finders). [`pair_regions`]
//! gives one region per such pair that covers every case, for `auto` to read once more on
//! a crop, so that the extra work lands where a code may be and nowhere else.

use crate::Candidate;
use crate::search::region::Region;
use qrpose_core::geometry::frames::PixelPoint;

/// A finder pattern that a read found but used in no decoded symbol.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FinderPattern {
    /// Its centre, px.
    pub(crate) centre: PixelPoint,
    /// Its width across, px (7 modules).
    pub(crate) size_px: f64,
}

/// Two finder patterns of one small code differ in size by at most this factor (tilt, and a
/// binariser that erodes one more than the other).
pub(crate) const PAIR_MAX_SIZE_RATIO: f64 = 1.25;
/// Closest pair, in finder-pattern widths: adjacent finders of a version 1 code are 2 widths
/// apart (14 modules), and tilt shortens that.
pub(crate) const PAIR_MIN_SPACING: f64 = 1.5;
/// Farthest pair, in finder-pattern widths: adjacent finders of a version 4 code (33
/// modules) are 26 / 7 ≈ 3.7 widths apart, diagonal ones of a version 2 code 18 √2 / 7 ≈
/// 3.6. The codes this is for are small and low-version (a code that loses its finder rings
/// to the blur has 2-3 px per module, so a higher version would be a large code); on the
/// sharpened noise of frames without a code, spurious pairs are mostly farther apart
/// (measured on the BoofCV no-code crops, docs/detection.md).
pub(crate) const PAIR_MAX_SPACING: f64 = 4.0;
/// Farthest pair, px: the pair read is for small codes (2-3 px per module, versions 1-4:
/// adjacent finders 34-78 px apart), whose crops are cheap; a region is about three times
/// this long.
pub(crate) const PAIR_MAX_DISTANCE_PX: f64 = 80.0;

/// Whether `a` and `b` could be two finder patterns of one small code.
fn plausible_pair(a: &FinderPattern, b: &FinderPattern) -> bool {
    let (small, large) = (a.size_px.min(b.size_px), a.size_px.max(b.size_px));
    let distance = (a.centre.u() - b.centre.u()).hypot(a.centre.v() - b.centre.v());
    let size = 0.5 * (small + large);
    small > 0.0
        && large <= PAIR_MAX_SIZE_RATIO * small
        && distance >= PAIR_MIN_SPACING * size
        && distance <= PAIR_MAX_SPACING * size
        && distance <= PAIR_MAX_DISTANCE_PX
}

/// The region of a pair: the box of both centres moved by their distance to either side of
/// the line through them (where the third finder and the fourth corner are when the two are
/// adjacent; diagonal ones have the other two in between), widened by one finder pattern.
fn pair_region(a: &FinderPattern, b: &FinderPattern) -> Option<Region> {
    let (du, dv) = (b.centre.u() - a.centre.u(), b.centre.v() - a.centre.v());
    // The normal to the line, as long as the pair's distance.
    let (nu, nv) = (-dv, du);
    let points: Vec<PixelPoint> = [a.centre, b.centre]
        .iter()
        .flat_map(|p| [1.0, -1.0].map(|side| PixelPoint::new(p.u() + side * nu, p.v() + side * nv)))
        .collect();
    Region::around(&points, a.size_px.max(b.size_px))
}

/// Whether `p` lies inside the box of a decoded symbol of `found` (a finder pattern of a
/// code already read).
fn on_read_symbol(p: &PixelPoint, found: &[Candidate]) -> bool {
    found
        .iter()
        .filter(|c| c.payload.is_some())
        .filter_map(|c| Region::around(&c.corners_px, 0.0))
        .any(|r| r.contains(p))
}

/// The regions of every plausible pair among `patterns` whose patterns are on no symbol of
/// `found` already read, in the order of the patterns.
#[must_use]
pub(crate) fn pair_regions(patterns: &[FinderPattern], found: &[Candidate]) -> Vec<Region> {
    let lone: Vec<&FinderPattern> = patterns
        .iter()
        .filter(|p| !on_read_symbol(&p.centre, found))
        .collect();
    let mut regions = Vec::new();
    for (k, a) in lone.iter().enumerate() {
        for b in lone.iter().skip(k + 1) {
            if plausible_pair(a, b) {
                regions.extend(pair_region(a, b));
            }
        }
    }
    regions
}

/// Lone finder patterns up to this wide get a crop of their own (`auto`'s lone-pattern
/// reads), px: 7 modules of 2.5 px, the codes whose other finder patterns blur away.
pub(crate) const LONE_MAX_SIZE_PX: f64 = 18.0;
/// Reach of a lone pattern's region from its centre, in finder widths: the far corner of a
/// version 2 code (25 modules) is 21.5 modules (3.07 widths) from a finder's centre along
/// each axis, whichever of its three finders the pattern is.
pub(crate) const LONE_REACH: f64 = 3.1;

/// The regions of the small patterns of `patterns` (at most [`LONE_MAX_SIZE_PX`] wide) that
/// lie on no symbol of `found` already read: each covers a code of versions 1-2 of which
/// the pattern is any one finder, in the order of the patterns.
#[must_use]
pub(crate) fn lone_regions(patterns: &[FinderPattern], found: &[Candidate]) -> Vec<Region> {
    patterns
        .iter()
        .filter(|p| p.size_px > 0.0 && p.size_px <= LONE_MAX_SIZE_PX)
        .filter(|p| !on_read_symbol(&p.centre, found))
        .filter_map(|p| Region::around(&[p.centre], LONE_REACH * p.size_px))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Backend;

    fn pattern(u: f64, v: f64, size_px: f64) -> FinderPattern {
        FinderPattern {
            centre: PixelPoint::new(u, v),
            size_px,
        }
    }

    fn contains(r: &Region, u: f64, v: f64) -> bool {
        r.contains(&PixelPoint::new(u, v))
    }

    #[test]
    fn a_pair_region_covers_the_code_on_either_side_and_between_diagonal_finders() {
        // A 25-module code of 2.4 px modules: finders 18 modules (43 px) apart, 17 px wide.
        let (a, b) = (pattern(200.0, 100.0, 17.0), pattern(243.0, 100.0, 17.0));
        let regions = pair_regions(&[a, b], &[]);
        assert_eq!(regions.len(), 1);
        let r = &regions[0];
        // The symbol below (third finder at (200, 143)) or above (at (200, 57)), corners
        // 3.5 modules (8.4 px) beyond the finder centres.
        for (u, v) in [(191.6, 151.4), (251.4, 151.4), (191.6, 48.6), (251.4, 48.6)] {
            assert!(contains(r, u, v), "({u}, {v}) outside {r:?}");
        }
        // Diagonal finders: the other two between them.
        let diagonal = pair_regions(&[a, pattern(243.0, 143.0, 17.0)], &[]);
        assert!(contains(&diagonal[0], 243.0, 100.0) && contains(&diagonal[0], 200.0, 143.0));
    }

    #[test]
    fn implausible_pairs_make_no_region() {
        let a = pattern(200.0, 100.0, 17.0);
        for (a, b) in [
            (a, pattern(243.0, 100.0, 23.0)), // sizes too different
            (a, pattern(210.0, 100.0, 17.0)), // overlapping
            (a, pattern(280.0, 100.0, 17.0)), // too many modules apart for a small code
            (pattern(200.0, 100.0, 24.0), pattern(290.0, 100.0, 24.0)), // too far, px
            (a, pattern(243.0, 100.0, 0.0)),  // no size
        ] {
            assert!(pair_regions(&[a, b], &[]).is_empty(), "{a:?} {b:?}");
        }
    }

    #[test]
    fn a_lone_region_covers_a_small_code_whichever_finder_the_pattern_is() {
        // A 25-module code of 1.7 px modules: finder 12 px wide, far corner 21.5 modules
        // (36.6 px) from its centre along each axis.
        let lone = lone_regions(&[pattern(200.0, 100.0, 12.0)], &[]);
        assert_eq!(lone.len(), 1);
        for (u, v) in [(163.4, 63.4), (236.6, 63.4), (163.4, 136.6), (236.6, 136.6)] {
            assert!(contains(&lone[0], u, v), "({u}, {v}) outside {:?}", lone[0]);
        }
        // Large patterns belong to codes the first reads see; they get no crop.
        assert!(lone_regions(&[pattern(200.0, 100.0, 30.0)], &[]).is_empty());
    }

    #[test]
    fn patterns_on_a_read_symbol_pair_with_nothing() {
        let read = Candidate {
            corners_px: [
                PixelPoint::new(180.0, 80.0),
                PixelPoint::new(220.0, 80.0),
                PixelPoint::new(220.0, 120.0),
                PixelPoint::new(180.0, 120.0),
            ],
            payload: Some(b"x".to_vec()),
            text: Some("x".to_owned()),
            module_count: Some(21),
            backend: Backend::Rxing,
        };
        let (a, b) = (pattern(200.0, 100.0, 17.0), pattern(243.0, 100.0, 17.0));
        assert!(pair_regions(&[a, b], std::slice::from_ref(&read)).is_empty());
        assert!(lone_regions(&[a], &[read]).is_empty());
    }
}
