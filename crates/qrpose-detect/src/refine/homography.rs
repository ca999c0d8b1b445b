//! Plane-to-image homographies between the symbol's module grid and the image.
//!
//! Module coordinates (u, v) run right and down from the symbol's top-left corner, in
//! modules: the symbol of N modules covers [0, N]²; module (i, j) (column i, row j) covers
//! [i, i + 1] × [j, j + 1]. Image coordinates are pixels with integer pixel centres
//! (docs/conventions.md).

use nalgebra::{Matrix3, Point2, Vector3};
use qrpose_core::geometry::frames::PixelPoint;
use qrpose_core::geometry::homography::{fit_homography_dlt, with_unit_h33};

/// A point in module coordinates (modules, right and down from the top-left corner).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModulePoint {
    /// Column direction, modules.
    pub u: f64,
    /// Row direction, modules.
    pub v: f64,
}

impl ModulePoint {
    /// A point from its coordinates.
    pub fn new(u: f64, v: f64) -> Self {
        Self { u, v }
    }
}

/// x_image ~ H · (u, v, 1)ᵀ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Homography {
    h: Matrix3<f64>,
    inv: Matrix3<f64>,
}

impl Homography {
    /// From a matrix; `None` when it is singular or not finite.
    pub(crate) fn from_matrix(h: Matrix3<f64>) -> Option<Self> {
        let inv = h.try_inverse()?;
        (h.iter().all(|x| x.is_finite()) && inv.iter().all(|x| x.is_finite()))
            .then_some(Self { h, inv })
    }

    /// The matrix.
    pub(crate) fn matrix(&self) -> &Matrix3<f64> {
        &self.h
    }

    /// The homography taking the symbol's corners (0, 0), (n, 0), (n, n), (0, n) onto four
    /// image corners in qr order (TL, TR, BR, BL), by qrpose-core's normalised DLT, scaled
    /// to H33 = 1; `None` when the corners are degenerate.
    pub(crate) fn from_corners(corners_qr: &[PixelPoint; 4], n_modules: f64) -> Option<Self> {
        let from = symbol_corners(n_modules).map(|m| Point2::new(m.u, m.v));
        let h = fit_homography_dlt(&from, &corners_qr.map(|p| p.0)).ok()?;
        Self::from_matrix(with_unit_h33(&h)?)
    }

    /// The image of the symbol's corners (0, 0), (n, 0), (n, n), (0, n), qr order: the
    /// inverse of [`Homography::from_corners`].
    pub(crate) fn corners(&self, n_modules: f64) -> [PixelPoint; 4] {
        symbol_corners(n_modules).map(|m| self.map(m))
    }

    /// Maps a module point into the image.
    pub(crate) fn map(&self, p: ModulePoint) -> PixelPoint {
        let x = self.h * Vector3::new(p.u, p.v, 1.0);
        PixelPoint::new(x.x / x.z, x.y / x.z)
    }

    /// Maps an image point back to module coordinates.
    #[cfg(test)]
    pub(crate) fn unmap(&self, p: PixelPoint) -> ModulePoint {
        let x = self.inv * Vector3::new(p.u(), p.v(), 1.0);
        ModulePoint::new(x.x / x.z, x.y / x.z)
    }

    /// Local scale at a module point: image pixels per module along u and along v.
    pub(crate) fn px_per_module(&self, p: ModulePoint) -> (f64, f64) {
        let a = self.map(p);
        let du = self.map(ModulePoint::new(p.u + 1e-3, p.v));
        let dv = self.map(ModulePoint::new(p.u, p.v + 1e-3));
        ((du.0 - a.0).norm() / 1e-3, (dv.0 - a.0).norm() / 1e-3)
    }
}

/// The corners of an n-module symbol in module coordinates, qr order (TL, TR, BR, BL).
fn symbol_corners(n_modules: f64) -> [ModulePoint; 4] {
    [
        ModulePoint::new(0.0, 0.0),
        ModulePoint::new(n_modules, 0.0),
        ModulePoint::new(n_modules, n_modules),
        ModulePoint::new(0.0, n_modules),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_and_inverts_a_perspective_quad() {
        let corners = [
            PixelPoint::new(100.3, 120.1),
            PixelPoint::new(230.8, 110.4),
            PixelPoint::new(250.2, 260.9),
            PixelPoint::new(90.5, 240.0),
        ];
        let h = Homography::from_corners(&corners, 21.0).expect("a quad");
        for (mapped, given) in h.corners(21.0).iter().zip(&corners) {
            assert!((mapped.0 - given.0).norm() < 1e-9);
        }
        let back = h.unmap(PixelPoint::new(170.0, 180.0));
        let again = h.map(back);
        assert!((again.0 - PixelPoint::new(170.0, 180.0).0).norm() < 1e-9);
    }
}
