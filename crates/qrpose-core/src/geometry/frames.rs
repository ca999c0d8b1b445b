//! Points and poses, one newtype per frame, and the axis conventions they obey.
//!
//! These conventions are written once, here, exactly as `docs/conventions.md` fixes them.
//!
//! ```text
//!   camera frame (mm)                 image (px)                marker frame (mm), paper Eq. 18
//!                                      (0,0)──► u                 P3 (-l,0,0) ◄─── P2 (0,0,0) origin
//!        z (forward, into scene)        │                          │ top-left       top-right │
//!       ╱                               ▼ v                        │                          ▼ y
//!      O──► x (right)                                              P4 (-l,l,0)      P1 (0,l,0)
//!      │                                                           bottom-left      bottom-right
//!      ▼ y (down)                                                  x points from P3 to P2; z = x × y
//! ```
//!
//! - **Camera frame**: origin at the optical centre; x right, y down, z forward (OpenCV's).
//! - **Pixels**: (u, v), u right, v down; integer coordinates are pixel *centres*, so the
//!   top-left pixel covers [-0.5, 0.5]².
//! - **Normalised coordinates**: x_n = (u − cx) / fx, y_n = (v − cy) / fy after undistortion:
//!   the point (x_n, y_n, 1) lies on the ray through the pixel.
//! - **Marker frame** (paper Eq. 18): origin at corner P2, side l;
//!   P1 = (0, l, 0), P2 = (0, 0, 0), P3 = (−l, 0, 0), P4 = (−l, l, 0). At identity rotation the
//!   marker faces the camera squarely and upright, so in the image P3 is the symbol's
//!   top-left corner, P2 top-right, P1 bottom-right and P4 bottom-left (the symbol's finder
//!   patterns sit at top-left, top-right and bottom-left).
//! - **Pose**: `p_cam = R · p_marker + t` ([`MarkerToCamera`]); t is P2 in the camera frame.
//! - **Euler angles**: R = Rx(α)·Ry(β)·Rz(γ), see [`crate::geometry::euler`].

use nalgebra::{Isometry3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// A point in the image, in pixels (distorted, as the sensor sees it; origin at the centre of
/// the top-left pixel, u right, v down). In the paper's form the same type carries
/// image-plane millimetres; the [`crate::geometry::camera::Camera`] says which.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelPoint(pub Point2<f64>);

impl PixelPoint {
    /// A point from its two coordinates (px, or image-plane mm for the paper's form).
    pub fn new(u: f64, v: f64) -> Self {
        Self(Point2::new(u, v))
    }
    /// Horizontal coordinate, right positive.
    pub fn u(&self) -> f64 {
        self.0.x
    }
    /// Vertical coordinate, down positive.
    pub fn v(&self) -> f64 {
        self.0.y
    }
    /// Whether the point lies in an image of `width_px` × `height_px`, between its outer
    /// pixel edges: pixel centres are at integer coordinates, so inside is
    /// [−0.5, width − 0.5] × [−0.5, height − 0.5].
    pub fn inside_image(&self, width_px: f64, height_px: f64) -> bool {
        (-0.5..=width_px - 0.5).contains(&self.u()) && (-0.5..=height_px - 0.5).contains(&self.v())
    }
}

/// An undistorted point on the z = 1 plane of the camera frame (dimensionless).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalizedPoint(pub Point2<f64>);

impl NormalizedPoint {
    /// A point from x_n, y_n.
    pub fn new(x: f64, y: f64) -> Self {
        Self(Point2::new(x, y))
    }
    /// x_n = x / z.
    pub fn x(&self) -> f64 {
        self.0.x
    }
    /// y_n = y / z.
    pub fn y(&self) -> f64 {
        self.0.y
    }
    /// The camera-frame point at depth `z_mm` on this ray (paper Eq. 6).
    pub fn at_depth(&self, z_mm: f64) -> CameraPoint {
        CameraPoint(Point3::new(self.0.x * z_mm, self.0.y * z_mm, z_mm))
    }
}

/// A point in the marker frame, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerPoint(pub Point3<f64>);

/// A point in the camera frame, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPoint(pub Point3<f64>);

impl CameraPoint {
    /// The ray through this point, as a normalised image point; `None` at or behind the
    /// camera's z = 0 plane.
    pub fn normalized(&self) -> Option<NormalizedPoint> {
        (self.0.z > 0.0).then(|| NormalizedPoint::new(self.0.x / self.0.z, self.0.y / self.0.z))
    }
}

/// The marker's pose in the camera frame: `p_cam = R_cm · p_marker + t_cm`, t in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerToCamera(pub Isometry3<f64>);

impl MarkerToCamera {
    /// A pose from its rotation and its translation (P2 in the camera frame, mm).
    pub fn new(r_cm: Rotation3<f64>, t_cm_mm: Vector3<f64>) -> Self {
        Self(Isometry3::from_parts(
            Translation3::from(t_cm_mm),
            UnitQuaternion::from_rotation_matrix(&r_cm),
        ))
    }
    /// The rotation R_cm.
    pub fn rotation(&self) -> Rotation3<f64> {
        self.0.rotation.to_rotation_matrix()
    }
    /// The translation t_cm, mm: where the marker origin P2 sits in the camera frame.
    pub fn translation_mm(&self) -> Vector3<f64> {
        self.0.translation.vector
    }
    /// Maps a marker-frame point into the camera frame.
    pub fn transform(&self, p_marker: &MarkerPoint) -> CameraPoint {
        CameraPoint(self.0.transform_point(&p_marker.0))
    }
    /// The inverse pose.
    pub fn inverse(&self) -> CameraToMarker {
        CameraToMarker(self.0.inverse())
    }
}

/// The camera's pose in the marker frame: `p_marker = R_mc · p_cam + t_mc`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraToMarker(pub Isometry3<f64>);

impl CameraToMarker {
    /// Maps a camera-frame point into the marker frame.
    pub fn transform(&self, p_cam: &CameraPoint) -> MarkerPoint {
        MarkerPoint(self.0.transform_point(&p_cam.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Inside an image runs to the outer edges of its border pixels, half a pixel beyond
    /// their centres.
    #[test]
    fn inside_an_image_reaches_the_outer_pixel_edges() {
        let (w, h) = (640.0, 480.0);
        for (u, v) in [(-0.5, -0.5), (639.5, 479.5), (0.0, 0.0), (320.0, 240.0)] {
            assert!(PixelPoint::new(u, v).inside_image(w, h), "({u}, {v})");
        }
        for (u, v) in [(-0.51, 0.0), (639.51, 0.0), (0.0, -0.51), (0.0, 479.51)] {
            assert!(!PixelPoint::new(u, v).inside_image(w, h), "({u}, {v})");
        }
    }

    #[test]
    fn inverse_pose_maps_camera_points_back_to_the_marker() {
        let r = Rotation3::from_euler_angles(0.3, -0.2, 1.1);
        let pose = MarkerToCamera::new(r, Vector3::new(10.0, -20.0, 500.0));
        let p_marker = MarkerPoint(Point3::new(-25.0, 40.0, 0.0));
        let back = pose.inverse().transform(&pose.transform(&p_marker));
        assert_relative_eq!(back.0, p_marker.0, epsilon = 1e-9);
    }

    #[test]
    fn points_behind_the_camera_have_no_ray() {
        assert!(
            CameraPoint(Point3::new(1.0, 1.0, -5.0))
                .normalized()
                .is_none()
        );
        let n = CameraPoint(Point3::new(10.0, -5.0, 100.0)).normalized();
        assert_eq!(n, Some(NormalizedPoint::new(0.1, -0.05)));
    }
}
