//! The twelve finder-pattern corners for `points = "finders"`: where they lie on the
//! symbol (module coordinates) and on the marker (mm).
//!
//! Each finder pattern is a 7 × 7-module square whose outer corners are known exactly on
//! the printed symbol; [`super::corners`] measures each of its four sides in the image and
//! intersects them. Order: top-left finder (its TL, TR, BR, BL), top-right finder, then
//! bottom-left finder, each in qr order.

use super::homography::ModulePoint;
use nalgebra::Point3;
use qrpose_core::geometry::{frames::MarkerPoint, marker::Marker};

/// Side of a finder pattern, modules.
pub(crate) const FINDER_MODULES: f64 = 7.0;

/// The twelve finder corners in module coordinates of an `n`-module symbol.
pub fn finder_model_points(n: usize) -> [ModulePoint; 12] {
    let n = n as f64;
    let origins = [
        (0.0, 0.0),
        (n - FINDER_MODULES, 0.0),
        (0.0, n - FINDER_MODULES),
    ];
    let square = [
        (0.0, 0.0),
        (FINDER_MODULES, 0.0),
        (FINDER_MODULES, FINDER_MODULES),
        (0.0, FINDER_MODULES),
    ];
    let mut out = [ModulePoint::new(0.0, 0.0); 12];
    for (f, (u0, v0)) in origins.iter().enumerate() {
        for (k, (du, dv)) in square.iter().enumerate() {
            out[4 * f + k] = ModulePoint::new(u0 + du, v0 + dv);
        }
    }
    out
}

/// The marker-frame point (mm) of module coordinate (u, v) on an `n`-module symbol: the
/// symbol's top-left corner is P3 = (−l, 0, 0), u runs along +x, v along +y
/// (docs/conventions.md).
pub fn marker_point_of_module(p: ModulePoint, marker: &Marker, n: usize) -> MarkerPoint {
    let l = marker.size_mm();
    let n = n as f64;
    MarkerPoint(Point3::new(-l + p.u / n * l, p.v / n * l, 0.0))
}

/// The twelve finder corners in the marker frame, mm, in [`finder_model_points`] order.
pub fn finder_marker_points(marker: &Marker, n: usize) -> Vec<MarkerPoint> {
    finder_model_points(n)
        .iter()
        .map(|p| marker_point_of_module(*p, marker, n))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outer_finder_corners_are_the_symbol_corners_p3_p2_p4() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let p = finder_marker_points(&marker, 25);
        let [p1, p2, p3, p4] = marker.object_points();
        assert_eq!(p[0], p3, "TL finder's TL is P3");
        assert_eq!(p[5], p2, "TR finder's TR is P2");
        assert_eq!(p[11], p4, "BL finder's BL is P4");
        assert!(p.iter().all(|q| q != &p1), "no finder at P1");
        // 7 modules of 2 mm.
        assert!((p[1].0.x - p[0].0.x - 14.0).abs() < 1e-12);
    }
}
