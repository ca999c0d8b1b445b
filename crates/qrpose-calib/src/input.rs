//! What a calibration is given: views of one planar target, each a list of correspondences
//! (a point of the target, in millimetres in the target's own frame with z = 0, and the
//! pixel where it was measured), the image size, and the options.
//!
//! Pixels follow qrpose's convention (`docs/conventions.md`): u right, v down, integer
//! coordinates at pixel centres, so the image spans [-0.5, w - 0.5] × [-0.5, h - 0.5] and
//! its centre is ((w - 1) / 2, (h - 1) / 2). The target frame is the caller's: the poses
//! reported are `p_cam = R · p_target + t`, mm.

use crate::error::CalibrationError;
use nalgebra::Point2;
use qrpose_core::geometry::camera::DistortionModel;
use qrpose_core::geometry::frames::PixelPoint;

/// Fewest correspondences a view may have: twice the four a homography needs, so that each
/// view's own fit is over-determined and its residuals say something about it.
pub const MIN_POINTS_PER_VIEW: usize = 8;

/// Fewest usable views a calibration is attempted with: Zhang's closed form needs three
/// views in general (Sec. 3.1), and with fewer the intrinsics rest on a single pair of
/// plane orientations. The service asks for 3 to 100 photos for the same reason.
pub const MIN_VIEWS: usize = 3;

/// Levenberg-Marquardt iterations allowed in each robust round by default; a good set
/// converges in 3-15.
pub const DEFAULT_MAX_ITERATIONS: usize = 100;

/// One measured point: where a point of the target was seen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correspondence {
    /// The point in the target's frame, mm (the target is the plane z = 0).
    pub target_mm: Point2<f64>,
    /// Where it was measured in the image, px (distorted, as the sensor saw it).
    pub pixel_px: PixelPoint,
}

impl Correspondence {
    /// A correspondence from the target point (X, Y) in mm and the pixel (u, v) in px.
    #[must_use]
    pub fn new(x_mm: f64, y_mm: f64, u_px: f64, v_px: f64) -> Self {
        Self {
            target_mm: Point2::new(x_mm, y_mm),
            pixel_px: PixelPoint::new(u_px, v_px),
        }
    }
}

/// One photo of the target: its correspondences, in any order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct View {
    /// The measured points.
    pub points: Vec<Correspondence>,
}

/// The size of the calibrated images, px.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ImageSize {
    /// Width, px.
    pub width_px: u32,
    /// Height, px.
    pub height_px: u32,
}

impl ImageSize {
    /// A size of `width_px` × `height_px`.
    #[must_use]
    pub const fn new(width_px: u32, height_px: u32) -> Self {
        Self {
            width_px,
            height_px,
        }
    }

    /// Width, px, as a float.
    #[must_use]
    pub fn width(&self) -> f64 {
        f64::from(self.width_px)
    }

    /// Height, px, as a float.
    #[must_use]
    pub fn height(&self) -> f64 {
        f64::from(self.height_px)
    }

    /// The image centre ((w - 1) / 2, (h - 1) / 2), px: integer coordinates are pixel centres.
    #[must_use]
    pub fn centre_px(&self) -> Point2<f64> {
        Point2::new(0.5 * (self.width() - 1.0), 0.5 * (self.height() - 1.0))
    }
}

/// How to calibrate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Options {
    /// The lens model to fit (`plumb_bob` by default), as qrpose-core implements it.
    pub model: DistortionModel,
    /// Levenberg-Marquardt iterations allowed in each robust round
    /// ([`DEFAULT_MAX_ITERATIONS`]).
    pub max_iterations: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            model: DistortionModel::PlumbBob,
            max_iterations: DEFAULT_MAX_ITERATIONS,
        }
    }
}

/// Checks the input before any arithmetic: a positive image size, finite coordinates,
/// [`MIN_POINTS_PER_VIEW`] points in every view and [`MIN_VIEWS`] views.
///
/// # Errors
/// The first problem found, in that order.
pub(crate) fn validate(views: &[View], image: ImageSize) -> Result<(), CalibrationError> {
    if image.width_px == 0 || image.height_px == 0 {
        return Err(CalibrationError::InvalidImageSize {
            width_px: image.width_px,
            height_px: image.height_px,
        });
    }
    for (view, v) in views.iter().enumerate() {
        let bad = v.points.iter().position(|c| {
            ![c.target_mm.x, c.target_mm.y, c.pixel_px.u(), c.pixel_px.v()]
                .iter()
                .all(|x| x.is_finite())
        });
        if let Some(point) = bad {
            return Err(CalibrationError::NonFinite { view, point });
        }
        if v.points.len() < MIN_POINTS_PER_VIEW {
            return Err(CalibrationError::TooFewPoints {
                view,
                points: v.points.len(),
                required: MIN_POINTS_PER_VIEW,
            });
        }
    }
    if views.len() < MIN_VIEWS {
        return Err(CalibrationError::TooFewViews {
            given: views.len(),
            usable: views.len(),
            required: MIN_VIEWS,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_view() -> View {
        let points = (0..9)
            .map(|i| {
                let (x, y) = (f64::from(i % 3) * 10.0, f64::from(i / 3) * 10.0);
                Correspondence::new(x, y, 100.0 + x, 100.0 + y)
            })
            .collect();
        View { points }
    }

    #[test]
    fn the_image_centre_is_between_the_middle_pixel_centres() {
        let c = ImageSize::new(1280, 720).centre_px();
        assert_eq!((c.x, c.y), (639.5, 359.5));
    }

    #[test]
    fn validation_names_the_first_bad_point_and_the_short_view() {
        let mut views = vec![square_view(), square_view(), square_view()];
        assert_eq!(validate(&views, ImageSize::new(640, 480)), Ok(()));
        views[1].points[4].pixel_px = PixelPoint::new(f64::NAN, 1.0);
        assert_eq!(
            validate(&views, ImageSize::new(640, 480)),
            Err(CalibrationError::NonFinite { view: 1, point: 4 })
        );
        views[1] = square_view();
        views[2].points.truncate(7);
        assert_eq!(
            validate(&views, ImageSize::new(640, 480)),
            Err(CalibrationError::TooFewPoints {
                view: 2,
                points: 7,
                required: MIN_POINTS_PER_VIEW
            })
        );
    }
}
