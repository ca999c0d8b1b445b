//! Merging what several passes found: two candidates are the same symbol when their
//! centres are closer than half the shorter side; a decoded duplicate replaces an undecoded
//! one ([`merge_candidates`]). Candidates found but not decoded are read again through
//! their refined module grid first ([`reread_undecoded`]).

use crate::Candidate;
use crate::raster::GrayImage;
use crate::refine::corners::{RefineStatus, refine_corners};
use crate::search::reread;
use qrpose_core::geometry::frames::PixelPoint;

/// Centroid of four corners.
pub(crate) fn centroid(c: &[PixelPoint; 4]) -> PixelPoint {
    PixelPoint::new(
        c.iter().map(PixelPoint::u).sum::<f64>() / 4.0,
        c.iter().map(PixelPoint::v).sum::<f64>() / 4.0,
    )
}

/// The shortest side of a quadrilateral, px.
pub(crate) fn shortest_side_px(c: &[PixelPoint; 4]) -> f64 {
    (0..4)
        .map(|i| (c[i].0 - c[(i + 1) % 4].0).norm())
        .fold(f64::INFINITY, f64::min)
}

/// True when two candidates are the same symbol (centres closer than half a side).
pub(crate) fn same_symbol(a: &Candidate, b: &Candidate) -> bool {
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

/// Whether any candidate was decoded.
pub(crate) fn any_decoded(found: &[Candidate]) -> bool {
    found.iter().any(|c| c.payload.is_some())
}

/// Reads every undecoded candidate again through its refined module grid
/// ([`reread::reread`]); `tried` holds the corners of candidates already tried, so that
/// each is refined once however often `auto` calls this.
pub(crate) fn reread_undecoded(
    image: &GrayImage,
    found: &mut [Candidate],
    tried: &mut Vec<[PixelPoint; 4]>,
) {
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
