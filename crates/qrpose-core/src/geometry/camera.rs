//! Camera intrinsics, lens distortion, and the maps between pixels and rays.
//!
//! A camera is given in one of three forms (docs/conventions.md):
//! - pixels: `fx_px, fy_px, cx_px, cy_px`;
//! - sensor: `focal_length_mm, pixel_size_um, cx_px, cy_px`, so fx = fy = f / pixel size;
//! - the paper's image plane: corners in image-plane millimetres with `focal_length_mm`
//!   (x' = x_n · f, paper Eqs. 4-6), principal point at the origin.
//!
//! Lens distortion, applied to normalised coordinates, is [`Distortion`]: `plumb_bob`,
//! `rational_polynomial` or `equidistant` (fisheye), in its own module, re-exported here.

pub use super::distortion::{
    Distortion, DistortionError, DistortionModel, Equidistant, PlumbBob, RationalPolynomial,
    UNDISTORT_MAX_ITERATIONS, UNDISTORT_TOL,
};
use super::frames::{CameraPoint, NormalizedPoint, PixelPoint};
use thiserror::Error;

/// Which unit image coordinates are in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageUnit {
    /// Pixels (the usual case).
    Pixel,
    /// Image-plane millimetres, the paper's form (no pixel size known).
    ImagePlaneMm,
}

/// One intrinsic parameter, to say which one is at fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraParam {
    /// Horizontal focal length, px.
    FxPx,
    /// Vertical focal length, px.
    FyPx,
    /// Principal point, horizontal, px.
    CxPx,
    /// Principal point, vertical, px.
    CyPx,
    /// Focal length, mm.
    FocalLengthMm,
    /// Pixel pitch, µm.
    PixelSizeUm,
    /// Radial coefficient k1.
    K1,
    /// Radial coefficient k2.
    K2,
    /// Tangential coefficient p1.
    P1,
    /// Tangential coefficient p2.
    P2,
    /// Radial coefficient k3.
    K3,
    /// Coefficient k4: the rational model's denominator r² term, or the fisheye θ⁹ term.
    K4,
    /// Coefficient k5: the rational model's denominator r⁴ term.
    K5,
    /// Coefficient k6: the rational model's denominator r⁶ term.
    K6,
}

impl CameraParam {
    /// The parameter's name as the API spells it (`fx_px`, `k1`, …).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::FxPx => "fx_px",
            Self::FyPx => "fy_px",
            Self::CxPx => "cx_px",
            Self::CyPx => "cy_px",
            Self::FocalLengthMm => "focal_length_mm",
            Self::PixelSizeUm => "pixel_size_um",
            Self::K1 => "k1",
            Self::K2 => "k2",
            Self::P1 => "p1",
            Self::P2 => "p2",
            Self::K3 => "k3",
            Self::K4 => "k4",
            Self::K5 => "k5",
            Self::K6 => "k6",
        }
    }

    /// Whether it is a distortion coefficient (under `distortion` in the API).
    #[must_use]
    pub const fn is_distortion(self) -> bool {
        matches!(
            self,
            Self::K1 | Self::K2 | Self::P1 | Self::P2 | Self::K3 | Self::K4 | Self::K5 | Self::K6
        )
    }
}

impl std::fmt::Display for CameraParam {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a camera was refused, or a pixel could not be turned into a ray.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum CameraError {
    /// A parameter is NaN or infinite: nothing can be computed from it.
    #[error("camera parameter {param} is not a finite number")]
    NonFinite {
        /// The parameter at fault.
        param: CameraParam,
    },
    /// A focal length or pixel size is zero or negative: the pinhole model has no meaning.
    #[error("camera parameter {param} must be positive, got {value}")]
    NonPositive {
        /// The parameter at fault.
        param: CameraParam,
        /// Its value, in the parameter's unit.
        value: f64,
    },
    /// The distortion model cannot be inverted at this point: Newton's method did not reach
    /// [`UNDISTORT_TOL`], or the point lies where the model folds over (its Jacobian is not
    /// positive), so no unique ray exists.
    #[error("cannot undistort the point ({u}, {v}) with these distortion coefficients")]
    UndistortionFailed {
        /// The point's horizontal coordinate, px (or image-plane mm).
        u: f64,
        /// The point's vertical coordinate.
        v: f64,
    },
}

/// Pinhole intrinsics plus distortion. Image coordinates are in [`Camera::unit`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    distortion: Distortion,
    unit: ImageUnit,
}

fn check_positive(value: f64, param: CameraParam) -> Result<f64, CameraError> {
    if !value.is_finite() {
        return Err(CameraError::NonFinite { param });
    }
    if value <= 0.0 {
        return Err(CameraError::NonPositive { param, value });
    }
    Ok(value)
}

fn check_finite(value: f64, param: CameraParam) -> Result<f64, CameraError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(CameraError::NonFinite { param })
    }
}

impl Camera {
    /// A camera from focal lengths and principal point in pixels.
    ///
    /// # Errors
    /// [`CameraError::NonFinite`] or [`CameraError::NonPositive`] naming the bad parameter.
    pub fn from_pixels(
        fx_px: f64,
        fy_px: f64,
        cx_px: f64,
        cy_px: f64,
    ) -> Result<Self, CameraError> {
        Ok(Self {
            fx: check_positive(fx_px, CameraParam::FxPx)?,
            fy: check_positive(fy_px, CameraParam::FyPx)?,
            cx: check_finite(cx_px, CameraParam::CxPx)?,
            cy: check_finite(cy_px, CameraParam::CyPx)?,
            distortion: Distortion::NONE,
            unit: ImageUnit::Pixel,
        })
    }

    /// A camera from the lens focal length and the sensor's pixel pitch: fx = fy = f / pitch.
    ///
    /// # Errors
    /// As [`Camera::from_pixels`].
    pub fn from_focal_length(
        focal_length_mm: f64,
        pixel_size_um: f64,
        cx_px: f64,
        cy_px: f64,
    ) -> Result<Self, CameraError> {
        let f_mm = check_positive(focal_length_mm, CameraParam::FocalLengthMm)?;
        let pitch_mm = check_positive(pixel_size_um, CameraParam::PixelSizeUm)? * 1e-3;
        let f_px = f_mm / pitch_mm;
        if !f_px.is_finite() {
            return Err(CameraError::NonFinite {
                param: CameraParam::PixelSizeUm,
            });
        }
        Self::from_pixels(f_px, f_px, cx_px, cy_px)
    }

    /// The paper's form: image points in image-plane millimetres, x' = x_n · f (Eqs. 4-6).
    ///
    /// # Errors
    /// As [`Camera::from_pixels`], for the focal length.
    pub fn image_plane_mm(focal_length_mm: f64) -> Result<Self, CameraError> {
        let f = check_positive(focal_length_mm, CameraParam::FocalLengthMm)?;
        Ok(Self {
            fx: f,
            fy: f,
            cx: 0.0,
            cy: 0.0,
            distortion: Distortion::NONE,
            unit: ImageUnit::ImagePlaneMm,
        })
    }

    /// The same camera with lens distortion.
    pub fn with_distortion(self, distortion: Distortion) -> Self {
        Self { distortion, ..self }
    }

    /// Horizontal focal length in image units per normalised unit (px, or mm).
    pub fn fx(&self) -> f64 {
        self.fx
    }
    /// Vertical focal length in image units per normalised unit.
    pub fn fy(&self) -> f64 {
        self.fy
    }
    /// Principal point, horizontal, image units.
    pub fn cx(&self) -> f64 {
        self.cx
    }
    /// Principal point, vertical, image units.
    pub fn cy(&self) -> f64 {
        self.cy
    }
    /// The lens distortion.
    pub fn distortion(&self) -> &Distortion {
        &self.distortion
    }
    /// The unit of image coordinates.
    pub fn unit(&self) -> ImageUnit {
        self.unit
    }

    /// Pixel (or image-plane mm) to an undistorted normalised point.
    ///
    /// # Errors
    /// [`CameraError::UndistortionFailed`] when the distortion cannot be inverted there.
    pub fn normalize(&self, p: &PixelPoint) -> Result<NormalizedPoint, CameraError> {
        let distorted =
            NormalizedPoint::new((p.u() - self.cx) / self.fx, (p.v() - self.cy) / self.fy);
        self.distortion
            .undistort(&distorted)
            .ok_or(CameraError::UndistortionFailed { u: p.u(), v: p.v() })
    }

    /// An undistorted normalised point to image coordinates, without distortion.
    pub fn ideal_from_normalized(&self, p: &NormalizedPoint) -> PixelPoint {
        PixelPoint::new(self.fx * p.x() + self.cx, self.fy * p.y() + self.cy)
    }

    /// An undistorted normalised point to where the sensor sees it (distortion applied).
    pub fn pixel_from_normalized(&self, p: &NormalizedPoint) -> PixelPoint {
        self.ideal_from_normalized(&self.distortion.distort(p))
    }

    /// Projects a camera-frame point into the image; `None` at or behind the camera.
    pub fn project(&self, p: &CameraPoint) -> Option<PixelPoint> {
        p.normalized().map(|n| self.pixel_from_normalized(&n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    fn strong_plumb_bob() -> PlumbBob {
        PlumbBob {
            k1: -0.28,
            k2: 0.09,
            p1: 0.0012,
            p2: -0.0009,
            k3: -0.012,
        }
    }

    fn strong_lens() -> Distortion {
        Distortion::from(strong_plumb_bob())
    }

    #[test]
    fn undistortion_inverts_the_forward_model_to_a_micropixel() {
        let camera = Camera::from_pixels(1000.0, 1002.0, 639.5, 359.5)
            .expect("valid camera")
            .with_distortion(strong_lens());
        for i in 0..=16 {
            for j in 0..=9 {
                let ideal =
                    NormalizedPoint::new(-0.6 + 0.075 * f64::from(i), -0.35 + 0.075 * f64::from(j));
                let seen = camera.pixel_from_normalized(&ideal);
                let back = camera
                    .normalize(&seen)
                    .expect("invertible inside the image");
                let err_px = ((back.x() - ideal.x()) * camera.fx())
                    .hypot((back.y() - ideal.y()) * camera.fy());
                assert!(
                    err_px < 1e-6,
                    "point ({}, {}): error {err_px} px",
                    ideal.x(),
                    ideal.y()
                );
            }
        }
    }

    #[test]
    fn forward_model_matches_opencv_formula_at_a_known_point() {
        // x = 0.3, y = -0.2: r² = 0.13; radial = 1 - 0.28·0.13 + 0.09·0.0169 - 0.012·0.002197
        let d = strong_plumb_bob();
        let p = strong_lens().distort(&NormalizedPoint::new(0.3, -0.2));
        let r2: f64 = 0.13;
        let radial = 1.0 + d.k1 * r2 + d.k2 * r2 * r2 + d.k3 * r2 * r2 * r2;
        let xd = 0.3 * radial + 2.0 * d.p1 * 0.3 * -0.2 + d.p2 * (r2 + 2.0 * 0.09);
        let yd = -0.2 * radial + d.p1 * (r2 + 2.0 * 0.04) + 2.0 * d.p2 * 0.3 * -0.2;
        assert!((p.x() - xd).abs() < 1e-15 && (p.y() - yd).abs() < 1e-15);
    }

    #[test]
    fn undistortion_refuses_points_where_the_model_folds_over() {
        let camera = Camera::from_pixels(1000.0, 1000.0, 0.0, 0.0)
            .expect("valid camera")
            .with_distortion(Distortion::PlumbBob(PlumbBob {
                k1: -0.5,
                ..PlumbBob::NONE
            }));
        // The radial factor x·(1 - 0.5 x²) peaks at x = 0.816 (0.544): no ray maps further out.
        let err = camera
            .normalize(&PixelPoint::new(700.0, 0.0))
            .expect_err("beyond the fold");
        assert!(matches!(err, CameraError::UndistortionFailed { .. }));
    }

    #[test]
    fn sensor_form_gives_focal_length_over_pixel_pitch() {
        let camera = Camera::from_focal_length(4.0, 2.0, 640.0, 360.0).expect("valid camera");
        assert!((camera.fx() - 2000.0).abs() < 1e-9 && (camera.fy() - 2000.0).abs() < 1e-9);
    }

    #[test]
    fn rejects_non_positive_and_non_finite_parameters() {
        let cases = [
            (Camera::from_pixels(0.0, 1.0, 0.0, 0.0), CameraParam::FxPx),
            (Camera::from_pixels(1.0, -1.0, 0.0, 0.0), CameraParam::FyPx),
            (
                Camera::from_pixels(1.0, 1.0, f64::NAN, 0.0),
                CameraParam::CxPx,
            ),
            (
                Camera::from_pixels(1.0, 1.0, 0.0, f64::INFINITY),
                CameraParam::CyPx,
            ),
            (
                Camera::from_focal_length(-2.8, 1.0, 0.0, 0.0),
                CameraParam::FocalLengthMm,
            ),
            (
                Camera::from_focal_length(2.8, 0.0, 0.0, 0.0),
                CameraParam::PixelSizeUm,
            ),
            (Camera::image_plane_mm(0.0), CameraParam::FocalLengthMm),
        ];
        for (result, want) in cases {
            match result {
                Err(CameraError::NonPositive { param, .. } | CameraError::NonFinite { param }) => {
                    assert_eq!(param, want)
                }
                other => panic!("expected an error naming {want:?}, got {other:?}"),
            }
        }
        let err = Distortion::try_new(0.0, 0.0, 0.0, f64::NAN, 0.0).expect_err("NaN p2");
        assert_eq!(
            err,
            CameraError::NonFinite {
                param: CameraParam::P2
            }
        );
    }

    #[test]
    fn projection_and_normalisation_agree() {
        let camera = Camera::from_pixels(900.0, 910.0, 320.0, 240.0).expect("valid camera");
        let px = camera
            .project(&CameraPoint(Point3::new(30.0, -12.0, 600.0)))
            .expect("in front");
        let n = camera.normalize(&px).expect("no distortion");
        assert!((n.x() - 0.05).abs() < 1e-15 && (n.y() + 0.02).abs() < 1e-15);
        assert!(
            camera
                .project(&CameraPoint(Point3::new(0.0, 0.0, -1.0)))
                .is_none()
        );
    }
}
