//! Closed-form planar pose: both candidates of the planar ambiguity by IPPE.
//!
//! Collins & Bartoli, "Infinitesimal Plane-Based Pose Estimation", IJCV 109 (2014). The
//! homography H maps the centred model plane (X, Y) onto normalised image points. At the
//! model origin (the marker centre) its image is v = (p, q) and its Jacobian J (2×2) fixes
//! the first two columns of the rotation up to one sign, which gives exactly two candidate
//! rotations; each gets the least-squares translation. On exact input one of the two is
//! the true pose; under noise both are refined by [`super::refine`].
//!
//! Model plane coordinates: the marker frame shifted to the centroid of the model points (for
//! the four corners, the marker centre: P1 (l/2, l/2), P2 (l/2, −l/2), P3 (−l/2, −l/2),
//! P4 (−l/2, l/2)), so the rotation is the marker-to-camera rotation itself. Four corners
//! get their homography in closed form ([`homography_from_square`]); more points (e.g. the
//! finder patterns' corners) get it by the normalised DLT of
//! [`crate::geometry::homography::fit_homography_dlt`].

use crate::geometry::{frames::NormalizedPoint, homography::with_unit_h33, marker::Marker};
use nalgebra::{Matrix2, Matrix3, Rotation3, Vector3};

/// One candidate pose: rotation and the marker centre in the camera frame (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentredPose {
    /// Marker-to-camera rotation.
    pub r: Rotation3<f64>,
    /// Marker centre in the camera frame, mm.
    pub centre_mm: Vector3<f64>,
}

/// Model corners P1..P4 relative to the marker centre, mm (z = 0).
pub fn centred_model(marker: &Marker) -> [Vector3<f64>; 4] {
    let c = marker.centre().0.coords;
    marker.object_points().map(|m| m.0.coords - c)
}

/// The homography from centred model-plane coordinates (mm) to normalised image points,
/// scaled so that H33 = 1. Closed form for four points: unit square → quadrilateral
/// (Heckbert 1989), composed with model → unit square. `None` when degenerate.
pub fn homography_from_square(
    rays: &[NormalizedPoint; 4],
    marker: &Marker,
) -> Option<Matrix3<f64>> {
    // Unit-square corners (0,0), (1,0), (1,1), (0,1) are P3, P2, P1, P4.
    let [p1, p2, p3, p4] = rays;
    let (x0, y0, x1, y1, x2, y2, x3, y3) = (
        p3.x(),
        p3.y(),
        p2.x(),
        p2.y(),
        p1.x(),
        p1.y(),
        p4.x(),
        p4.y(),
    );
    let sx = x0 - x1 + x2 - x3;
    let sy = y0 - y1 + y2 - y3;
    let (dx1, dx2, dy1, dy2) = (x1 - x2, x3 - x2, y1 - y2, y3 - y2);
    let den = dx1 * dy2 - dx2 * dy1;
    if den == 0.0 {
        return None;
    }
    let g = (sx * dy2 - dx2 * sy) / den;
    let h = (dx1 * sy - sx * dy1) / den;
    #[rustfmt::skip]
    let h_square = Matrix3::new(
        x1 - x0 + g * x1, x3 - x0 + h * x3, x0,
        y1 - y0 + g * y1, y3 - y0 + h * y3, y0,
        g,                h,                1.0,
    );
    let l = marker.size_mm();
    #[rustfmt::skip]
    let model_to_square = Matrix3::new(
        1.0 / l, 0.0,     0.5,
        0.0,     1.0 / l, 0.5,
        0.0,     0.0,     1.0,
    );
    with_unit_h33(&(h_square * model_to_square))
}

/// The rotation taking the z axis onto the unit vector along `a`.
fn rotation_z_to(a: &Vector3<f64>) -> Matrix3<f64> {
    let a = a.normalize();
    let d = 1.0 / (1.0 + a.z);
    // The rotation about ẑ × a taking a onto ẑ; its transpose takes ẑ onto a.
    #[rustfmt::skip]
    let to_z = Matrix3::new(
        1.0 - a.x * a.x * d, -a.x * a.y * d,      -a.x,
        -a.x * a.y * d,      1.0 - a.y * a.y * d, -a.y,
        a.x,                 a.y,                 1.0 - (a.x * a.x + a.y * a.y) * d,
    );
    to_z.transpose()
}

/// IPPE's two rotations from the homography's Jacobian `j` at the model origin and the
/// origin's image `v` (Collins & Bartoli 2014, Section 4). `None` when J is singular.
pub fn ippe_rotations(j: &Matrix2<f64>, v: (f64, f64)) -> Option<[Rotation3<f64>; 2]> {
    let (p, q) = v;
    let rv = rotation_z_to(&Vector3::new(p, q, 1.0));
    // B = [I₂ | −v] · Rv[:, 0..2]
    #[rustfmt::skip]
    let b = Matrix2::new(
        rv[(0, 0)] - p * rv[(2, 0)], rv[(0, 1)] - p * rv[(2, 1)],
        rv[(1, 0)] - q * rv[(2, 0)], rv[(1, 1)] - q * rv[(2, 1)],
    );
    let a = b.try_inverse()? * j;
    // γ: the largest singular value of A.
    let ata = a.transpose() * a;
    let half_tr = 0.5 * (ata[(0, 0)] + ata[(1, 1)]);
    let gap = (0.25 * (ata[(0, 0)] - ata[(1, 1)]).powi(2) + ata[(0, 1)] * ata[(0, 1)]).sqrt();
    let gamma = (half_tr + gap).sqrt();
    if gamma.is_nan() || gamma <= f64::EPSILON {
        return None;
    }
    let rt = a / gamma;
    let b0 = (1.0 - rt[(0, 0)].powi(2) - rt[(1, 0)].powi(2))
        .max(0.0)
        .sqrt();
    let mut b1 = (1.0 - rt[(0, 1)].powi(2) - rt[(1, 1)].powi(2))
        .max(0.0)
        .sqrt();
    if -(rt[(0, 0)] * rt[(0, 1)] + rt[(1, 0)] * rt[(1, 1)]) < 0.0 {
        b1 = -b1;
    }
    let candidate = |sign: f64| {
        let c1 = Vector3::new(rt[(0, 0)], rt[(1, 0)], sign * b0);
        let c2 = Vector3::new(rt[(0, 1)], rt[(1, 1)], sign * b1);
        let local = Matrix3::from_columns(&[c1, c2, c1.cross(&c2)]);
        // Orthonormal by construction (unit columns; b1's sign makes c1 ⟂ c2 because A/γ has
        // largest singular value 1), so no projection onto SO(3) is needed.
        Rotation3::from_matrix_unchecked(rv * local)
    };
    Some([candidate(1.0), candidate(-1.0)])
}

/// The model origin that best explains the rays for a given rotation, by linear least
/// squares on x_n·(q_z + c_z) = q_x + c_x and y_n·(q_z + c_z) = q_y + c_y, q = R·m.
pub fn centre_for_rotation(
    rays: &[NormalizedPoint],
    model: &[Vector3<f64>],
    r: &Rotation3<f64>,
) -> Option<Vector3<f64>> {
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for (n, m) in rays.iter().zip(model) {
        let q = r * m;
        let rows = [
            (Vector3::new(1.0, 0.0, -n.x()), n.x() * q.z - q.x),
            (Vector3::new(0.0, 1.0, -n.y()), n.y() * q.z - q.y),
        ];
        for (row, rhs) in rows {
            ata += row * row.transpose();
            atb += row * rhs;
        }
    }
    super::lm::solve_spd(&ata, &atb)
}

/// Both IPPE candidates from a homography H (model plane, centred, mm → normalised image,
/// H33 = 1), with each candidate's least-squares origin for `model` (centred, z = 0).
pub fn candidates_from_homography(
    h: &Matrix3<f64>,
    rays: &[NormalizedPoint],
    model: &[Vector3<f64>],
) -> Option<[CentredPose; 2]> {
    let v = (h[(0, 2)], h[(1, 2)]);
    #[rustfmt::skip]
    let j = Matrix2::new(
        h[(0, 0)] - h[(2, 0)] * v.0, h[(0, 1)] - h[(2, 1)] * v.0,
        h[(1, 0)] - h[(2, 0)] * v.1, h[(1, 1)] - h[(2, 1)] * v.1,
    );
    let [ra, rb] = ippe_rotations(&j, v)?;
    let a = CentredPose {
        r: ra,
        centre_mm: centre_for_rotation(rays, model, &ra)?,
    };
    let b = CentredPose {
        r: rb,
        centre_mm: centre_for_rotation(rays, model, &rb)?,
    };
    Some([a, b])
}

/// Both IPPE candidates for the four corner rays P1..P4, or `None` for a degenerate outline.
pub fn candidates(rays: &[NormalizedPoint; 4], marker: &Marker) -> Option<[CentredPose; 2]> {
    let h = homography_from_square(rays, marker)?;
    candidates_from_homography(&h, rays, &centred_model(marker))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{
        euler::{EulerXyz, angle_between},
        frames::MarkerToCamera,
        homography::fit_homography_dlt,
    };
    use nalgebra::Point2;

    #[test]
    fn homography_maps_model_corners_onto_their_rays() {
        let marker = Marker::try_new(40.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::from_degrees(30.0, -20.0, 75.0).to_rotation(),
            Vector3::new(-30.0, 25.0, 250.0),
        );
        let rays = marker
            .object_points()
            .map(|m| pose.transform(&m).normalized().expect("in front"));
        let h = homography_from_square(&rays, &marker).expect("non-degenerate");
        for (m, n) in centred_model(&marker).iter().zip(&rays) {
            let x = h * Vector3::new(m.x, m.y, 1.0);
            assert!((x.x / x.z - n.x()).abs() < 1e-14 && (x.y / x.z - n.y()).abs() < 1e-14);
        }
    }

    #[test]
    fn one_candidate_is_the_exact_pose_and_the_other_is_its_mirror() {
        let marker = Marker::try_new(50.0).expect("valid size");
        for (name, a, b, g) in [
            ("tilt x", 40.0, 0.0, 0.0),
            ("tilt xy", 20.0, -30.0, 170.0),
            ("near frontal", 2.0, 1.0, 45.0),
        ] {
            let r = EulerXyz::from_degrees(a, b, g).to_rotation();
            let pose = MarkerToCamera::new(r, Vector3::new(60.0, -50.0, 400.0));
            let rays = marker
                .object_points()
                .map(|m| pose.transform(&m).normalized().expect("in front"));
            let [c1, c2] = candidates(&rays, &marker).expect("non-degenerate");
            let errs = [angle_between(&c1.r, &r), angle_between(&c2.r, &r)];
            let best = if errs[0] < errs[1] { c1 } else { c2 };
            assert!(
                errs[0].min(errs[1]) < 1e-9,
                "{name}: rotation errors {errs:?} rad"
            );
            let centre = pose.transform(&marker.centre()).0.coords;
            assert!(
                (best.centre_mm - centre).norm() < 1e-7,
                "{name}: centre {:?}",
                best.centre_mm
            );
            assert!(
                errs[0].max(errs[1]) > 1e-3,
                "{name}: the candidates should differ"
            );
        }
    }

    #[test]
    fn dlt_homography_agrees_with_the_closed_form_on_four_corners() {
        let marker = Marker::try_new(30.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::from_degrees(-25.0, 35.0, -120.0).to_rotation(),
            Vector3::new(15.0, 40.0, 320.0),
        );
        let rays = marker
            .object_points()
            .map(|m| pose.transform(&m).normalized().expect("in front"));
        let model_xy = centred_model(&marker).map(|m| Point2::new(m.x, m.y));
        let dlt = fit_homography_dlt(&model_xy, &rays.map(|r| r.0))
            .ok()
            .and_then(|h| with_unit_h33(&h))
            .expect("non-degenerate");
        let closed = homography_from_square(&rays, &marker).expect("non-degenerate");
        assert!(
            (dlt - closed).norm() < 1e-9 * closed.norm(),
            "{dlt} vs {closed}"
        );
    }
}
