//! The paper's simulation grid (Section 8, Tables 3-4; docs/paper-method.md, The paper's simulation).
//!
//! f = 2.82 mm, l = 50 mm, exact projection to image-plane millimetres. P2 at
//! x, y ∈ {−100, −90, …, 100} mm and z ∈ {500, 400, 300, 200, 100} mm; twelve rotation sets
//! (Table 4) whose free angle a takes 0, 1, …, 25° while the two others are fixed.

use nalgebra::Vector3;
use qrpose_core::geometry::{
    euler::EulerXyz,
    frames::{MarkerToCamera, PixelPoint},
    marker::Marker,
};

/// Focal length of the paper's simulated camera, mm (Table 3).
pub const FOCAL_LENGTH_MM: f64 = 2.82;
/// Side of the simulated QR code, mm (Table 3).
pub const MARKER_SIZE_MM: f64 = 50.0;
/// P2's x and y positions, mm: −100 to 100 in steps of 10 (21 values each).
pub const XY_STEP_MM: f64 = 10.0;
/// Number of x (and y) positions.
pub const XY_COUNT: usize = 21;
/// The working distances, mm, in the paper's column order.
pub const DISTANCES_MM: [f64; 5] = [500.0, 400.0, 300.0, 200.0, 100.0];
/// The free angle's values: 0, 1, …, 25°.
pub const ANGLE_COUNT: usize = 26;
/// The gains k of the paper's sweep: 0.8, 0.9, …, 2.0.
pub const GAINS: [f64; 13] = [
    0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0,
];

/// Which of α, β, γ a rotation set varies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FreeAxis {
    /// α about x.
    X,
    /// β about y.
    Y,
    /// γ about z.
    Z,
}

/// One of Table 4's rotation combination sets, e.g. "X-0-5": α free, β = 0°, γ = 5°.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationSet {
    /// The set's name as the paper prints it.
    pub name: &'static str,
    /// The free angle.
    pub free: FreeAxis,
    /// (α, β, γ) in degrees with the free one at 0.
    pub fixed_deg: [f64; 3],
}

impl RotationSet {
    /// The Euler angles of this set at free angle `a_deg`.
    pub fn euler(&self, a_deg: f64) -> EulerXyz {
        let mut deg = self.fixed_deg;
        deg[self.free as usize] = a_deg;
        EulerXyz::from_degrees(deg[0], deg[1], deg[2])
    }
}

const fn set(name: &'static str, free: FreeAxis, fixed_deg: [f64; 3]) -> RotationSet {
    RotationSet {
        name,
        free,
        fixed_deg,
    }
}

/// Table 4's twelve sets, in Table 10's row order.
pub const ROTATION_SETS: [RotationSet; 12] = [
    set("X-0-0", FreeAxis::X, [0.0, 0.0, 0.0]),
    set("X-0-5", FreeAxis::X, [0.0, 0.0, 5.0]),
    set("X-5-0", FreeAxis::X, [0.0, 5.0, 0.0]),
    set("X-5-5", FreeAxis::X, [0.0, 5.0, 5.0]),
    set("0-Y-0", FreeAxis::Y, [0.0, 0.0, 0.0]),
    set("0-Y-5", FreeAxis::Y, [0.0, 0.0, 5.0]),
    set("5-Y-0", FreeAxis::Y, [5.0, 0.0, 0.0]),
    set("5-Y-5", FreeAxis::Y, [5.0, 0.0, 5.0]),
    set("0-0-Z", FreeAxis::Z, [0.0, 0.0, 0.0]),
    set("0-5-Z", FreeAxis::Z, [0.0, 5.0, 0.0]),
    set("5-0-Z", FreeAxis::Z, [5.0, 0.0, 0.0]),
    set("5-5-Z", FreeAxis::Z, [5.0, 5.0, 0.0]),
];

/// The rotation set of a given name.
pub fn rotation_set(name: &str) -> Option<RotationSet> {
    ROTATION_SETS.iter().copied().find(|s| s.name == name)
}

/// The i-th x or y position, mm (i = 0 → −100).
pub fn xy_mm(i: usize) -> f64 {
    -100.0 + XY_STEP_MM * i as f64
}

/// One simulated case: where P2 is, which set, which free angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Case {
    /// P2 in the camera frame, mm.
    pub p2_mm: Vector3<f64>,
    /// The rotation set.
    pub set: RotationSet,
    /// The free angle, degrees.
    pub angle_deg: f64,
}

impl Case {
    /// The true rotation angles.
    pub fn euler(&self) -> EulerXyz {
        self.set.euler(self.angle_deg)
    }

    /// The true pose: R from the set, t = P2.
    pub fn pose(&self) -> MarkerToCamera {
        MarkerToCamera::new(self.euler().to_rotation(), self.p2_mm)
    }

    /// True depths z1..z4 of the corners, mm.
    pub fn true_depths_mm(&self, marker: &Marker) -> [f64; 4] {
        let pose = self.pose();
        marker.object_points().map(|m| pose.transform(&m).0.z)
    }

    /// The exact image of the corners P1..P4 in image-plane mm: x' = f·X/Z (paper Eqs. 4-5).
    /// `None` when a corner is at or behind the camera.
    pub fn image_plane_corners_mm(
        &self,
        marker: &Marker,
        focal_length_mm: f64,
    ) -> Option<[PixelPoint; 4]> {
        let pose = self.pose();
        let mut out = [PixelPoint::new(0.0, 0.0); 4];
        for (o, m) in out.iter_mut().zip(marker.object_points()) {
            let p = pose.transform(&m).0;
            if p.z <= 0.0 {
                return None;
            }
            *o = PixelPoint::new(focal_length_mm * p.x / p.z, focal_length_mm * p.y / p.z);
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_has_the_papers_dimensions() {
        assert_eq!(xy_mm(0), -100.0);
        assert_eq!(xy_mm(XY_COUNT - 1), 100.0);
        assert_eq!(
            ROTATION_SETS.len() * DISTANCES_MM.len() * XY_COUNT * XY_COUNT * ANGLE_COUNT,
            687_960
        );
        assert!(
            (GAINS[12] - 2.0).abs() < 1e-12
                && GAINS.windows(2).all(|w| (w[1] - w[0] - 0.1).abs() < 1e-9)
        );
    }

    #[test]
    fn sets_put_the_free_angle_on_their_axis() {
        let e = rotation_set("5-Y-5")
            .expect("known set")
            .euler(17.0)
            .to_degrees();
        assert_eq!(e.map(|v| (v * 1e9).round() / 1e9), [5.0, 17.0, 5.0]);
        let e = rotation_set("X-5-0")
            .expect("known set")
            .euler(3.0)
            .to_degrees();
        assert_eq!(e.map(|v| (v * 1e9).round() / 1e9), [3.0, 5.0, 0.0]);
    }

    #[test]
    fn image_plane_projection_is_focal_length_times_x_over_z() {
        let marker = Marker::try_new(MARKER_SIZE_MM).expect("valid size");
        let case = Case {
            p2_mm: Vector3::new(60.0, -50.0, 500.0),
            set: ROTATION_SETS[0],
            angle_deg: 0.0,
        };
        let c = case
            .image_plane_corners_mm(&marker, FOCAL_LENGTH_MM)
            .expect("in front");
        // P2 sits at (60, −50, 500): x' = 2.82 · 60 / 500.
        assert!(
            (c[1].u() - 2.82 * 60.0 / 500.0).abs() < 1e-15
                && (c[1].v() + 2.82 * 50.0 / 500.0).abs() < 1e-15
        );
    }
}
