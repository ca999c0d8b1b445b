//! The module grid seen through a lens. The printed symbol is a plane, so its
//! module grid maps to the image by one homography only in *undistorted* coordinates; a
//! distorting lens (a fisheye most of all) bows its straight lines in the photo. The
//! refinement therefore keeps its homography H from module coordinates to **ideal
//! pixels**, the pixels of a distortion-free camera with the same intrinsics, and looks
//! at the photo through the lens:
//!
//! ```text
//! ideal:  x_ideal = H · m                                   (m in modules, homogeneous)
//! photo:  x_n = ((u_ideal − cx)/fx, (v_ideal − cy)/fy),   x_px = K · distort(x_n)
//! ```
//!
//! Every sample of the photo is taken at x_px, every edge point found is kept in ideal
//! pixels, where the fits (homography, finder-side lines) are straight-line fits again, and
//! the corners are reported in the photo's pixels. Without distortion x_px = x_ideal and
//! [`Grid`] calls the homography alone, so the refinement is the same, bit for bit, as
//! without a camera. Frames and the pixel convention: docs/conventions.md.

use crate::refine::homography::{Homography, ModulePoint};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::{NormalizedPoint, PixelPoint};

/// Step of the finite differences of [`Grid::px_per_module`], modules (as
/// [`Homography::px_per_module`]).
const SCALE_STEP_MODULES: f64 = 1e-3;

/// A camera whose lens distorts: ideal pixels to the photo's pixels and back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Lens {
    camera: Camera,
}

impl Lens {
    /// The lens of `camera`; `None` when it does not distort (every coefficient 0), and
    /// the photo's pixels are then the ideal ones.
    pub(crate) fn of(camera: &Camera) -> Option<Self> {
        (!camera.distortion().is_none()).then_some(Self { camera: *camera })
    }

    /// Where the photo shows the ideal pixel `ideal`: through K⁻¹ to the ideal normalised
    /// point, through the distortion, and back through K.
    pub(crate) fn distort(&self, ideal: PixelPoint) -> PixelPoint {
        let c = &self.camera;
        let xy_norm =
            NormalizedPoint::new((ideal.u() - c.cx()) / c.fx(), (ideal.v() - c.cy()) / c.fy());
        c.pixel_from_normalized(&xy_norm)
    }

    /// The ideal pixel of the photo's pixel `uv_px`; `None` where the lens cannot be
    /// undistorted (see `Camera::normalize`; a fisheye pixel 90° or more off the axis).
    pub(crate) fn undistort(&self, uv_px: PixelPoint) -> Option<PixelPoint> {
        let xy_norm = self.camera.normalize(&uv_px).ok()?;
        Some(self.camera.ideal_from_normalized(&xy_norm))
    }
}

/// The module grid's image: the homography to ideal pixels, seen through the lens if any.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Grid {
    h: Homography,
    lens: Option<Lens>,
}

impl Grid {
    /// The grid whose symbol corners (0, 0), (n, 0), (n, n), (0, n) fall on `corners_px`
    /// (the photo's pixels, qr order). `None` when the corners are degenerate or one of them
    /// cannot be undistorted.
    pub(super) fn from_corners(
        corners_px: &[PixelPoint; 4],
        n_modules: f64,
        lens: Option<Lens>,
    ) -> Option<Self> {
        let h = match &lens {
            None => Homography::from_corners(corners_px, n_modules)?,
            Some(l) => {
                let [a, b, c, d] = corners_px.map(|p| l.undistort(p));
                Homography::from_corners(&[a?, b?, c?, d?], n_modules)?
            }
        };
        Some(Self { h, lens })
    }

    /// The same lens with another homography (module → ideal pixels).
    pub(super) fn with_homography(&self, h: Homography) -> Self {
        Self { h, lens: self.lens }
    }

    /// The homography, module → ideal pixels.
    pub(super) fn homography(&self) -> &Homography {
        &self.h
    }

    /// A module point in ideal pixels (where the straight-line fits work).
    pub(super) fn ideal(&self, m: ModulePoint) -> PixelPoint {
        self.h.map(m)
    }

    /// An ideal pixel in the photo.
    pub(super) fn photo_from_ideal(&self, ideal: PixelPoint) -> PixelPoint {
        match &self.lens {
            None => ideal,
            Some(l) => l.distort(ideal),
        }
    }

    /// A module point in the photo, px.
    pub(super) fn map(&self, m: ModulePoint) -> PixelPoint {
        self.photo_from_ideal(self.h.map(m))
    }

    /// The symbol's corners (0, 0), (n, 0), (n, n), (0, n) in the photo, px, qr order.
    pub(super) fn corners(&self, n_modules: f64) -> [PixelPoint; 4] {
        match &self.lens {
            None => self.h.corners(n_modules),
            Some(l) => self.h.corners(n_modules).map(|p| l.distort(p)),
        }
    }

    /// The photo's local scale at a module point: pixels per module along u and along v.
    pub(super) fn px_per_module(&self, m: ModulePoint) -> (f64, f64) {
        if self.lens.is_none() {
            return self.h.px_per_module(m);
        }
        let a = self.map(m);
        let du = self.map(ModulePoint::new(m.u + SCALE_STEP_MODULES, m.v));
        let dv = self.map(ModulePoint::new(m.u, m.v + SCALE_STEP_MODULES));
        (
            (du.0 - a.0).norm() / SCALE_STEP_MODULES,
            (dv.0 - a.0).norm() / SCALE_STEP_MODULES,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use qrpose_core::geometry::camera::{Distortion, Equidistant};

    fn fisheye() -> Camera {
        Camera::from_pixels(420.0, 420.0, 639.5, 399.5)
            .expect("valid camera")
            .with_distortion(Distortion::from(Equidistant {
                k1: -0.00566,
                k2: 0.04186,
                k3: -0.03869,
                k4: 0.00673,
            }))
    }

    #[test]
    fn a_camera_without_distortion_has_no_lens() {
        let pinhole = Camera::from_pixels(420.0, 420.0, 639.5, 399.5).expect("valid camera");
        assert!(Lens::of(&pinhole).is_none());
        assert!(Lens::of(&fisheye()).is_some());
    }

    #[test]
    fn undistorting_inverts_distorting_across_a_fisheye_frame() {
        let lens = Lens::of(&fisheye()).expect("a lens");
        // Out to near the 90° circle.
        for (u, v) in [
            (639.5, 399.5),
            (200.0, 100.0),
            (1100.0, 700.0),
            (900.0, 300.0),
        ] {
            let px = PixelPoint::new(u, v);
            let ideal = lens.undistort(px).expect("within 90° of the axis");
            let back = lens.distort(ideal);
            assert!((back.0 - px.0).norm() < 1e-6, "({u}, {v}) → {back:?}");
        }
        // The frame's corner is beyond the 90° circle: it sees no ray in front.
        assert!(lens.undistort(PixelPoint::new(0.0, 0.0)).is_none());
    }

    #[test]
    fn a_grid_with_a_corner_the_lens_cannot_undistort_is_refused() {
        let corners = [
            PixelPoint::new(0.0, 0.0),
            PixelPoint::new(60.0, 5.0),
            PixelPoint::new(55.0, 65.0),
            PixelPoint::new(3.0, 60.0),
        ];
        assert!(Grid::from_corners(&corners, 21.0, Lens::of(&fisheye())).is_none());
        assert!(Grid::from_corners(&corners, 21.0, None).is_some());
    }

    #[test]
    fn the_grid_through_a_lens_puts_the_corners_where_they_were_given() {
        let lens = Lens::of(&fisheye());
        let corners = [
            PixelPoint::new(900.0, 300.0),
            PixelPoint::new(1000.0, 320.0),
            PixelPoint::new(990.0, 420.0),
            PixelPoint::new(895.0, 410.0),
        ];
        let grid = Grid::from_corners(&corners, 25.0, lens).expect("a grid");
        for (got, want) in grid.corners(25.0).iter().zip(&corners) {
            assert!((got.0 - want.0).norm() < 1e-6, "{got:?} vs {want:?}");
        }
        // The middle of the top side is off the chord between its ends: the lens bows it.
        let mid = grid.map(ModulePoint::new(12.5, 0.0));
        let chord = (corners[0].0 + corners[1].0.coords) / 2.0;
        assert!((mid.0 - chord).norm() > 0.1, "the side is bowed: {mid:?}");
    }
}
