//! How the flange moved between the views: whether its rotations turn about at least two
//! distinct axes (without them the mount cannot be told: a rotation about one axis leaves
//! the mount's translation along that axis, and its rotation about it relative to the
//! target, free; Tsai and Lenz 1989, Sec. III, and Park and Martin 1994, Sec. III), and the
//! largest rotation between two views.

use super::rigid::{compose, inverse, log_rotation};
use crate::model::Pose;
use nalgebra::{Matrix3, Vector3};

/// Relative rotations smaller than this (5°) have no axis worth counting: with the
/// default flange noise of 0.02°, their axis is known to about 0.3°.
pub const MIN_AXIS_ROTATION_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// The motions' axes must spread by at least this (10°) from their main axis for the
/// motion to count as about two axes; below it `degenerate_motion` is returned.
pub const MIN_AXIS_SPREAD_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// Every pair's relative rotation vector log(R_{G_j⁻¹·G_i}), i < j, rad.
fn relative_rotations(g: &[Pose]) -> Vec<Vector3<f64>> {
    let mut out = Vec::new();
    for i in 0..g.len() {
        for j in i + 1..g.len() {
            out.push(log_rotation(&compose(&inverse(&g[j]), &g[i]).r));
        }
    }
    out
}

/// The largest angle between a relative rotation's axis (those above
/// [`MIN_AXIS_ROTATION_RAD`]) and the axes' main direction (the scatter matrix's leading
/// eigenvector; an axis and its opposite are the same axis), rad; 0 when no rotation is
/// large enough to have an axis.
pub(crate) fn axis_spread_rad(g: &[Pose]) -> f64 {
    let axes: Vec<Vector3<f64>> = relative_rotations(g)
        .into_iter()
        .filter(|w| w.norm() >= MIN_AXIS_ROTATION_RAD)
        .map(|w| w.normalize())
        .collect();
    if axes.is_empty() {
        return 0.0;
    }
    let scatter: Matrix3<f64> = axes.iter().map(|a| a * a.transpose()).sum();
    let eigen = scatter.symmetric_eigen();
    let main = eigen.eigenvalues.imax();
    let e1 = eigen.eigenvectors.column(main).into_owned();
    axes.iter()
        .map(|a| a.dot(&e1).abs().min(1.0).acos())
        .fold(0.0, f64::max)
}

/// The largest rotation between two of the poses, rad.
pub(crate) fn largest_rotation_rad(g: &[Pose]) -> f64 {
    relative_rotations(g)
        .iter()
        .map(Vector3::norm)
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn about(axis: Vector3<f64>, angle: f64) -> Pose {
        Pose {
            r: Rotation3::new(axis.normalize() * angle),
            t_mm: Vector3::new(angle * 100.0, 0.0, 0.0),
        }
    }

    #[test]
    fn rotations_about_one_axis_have_no_spread_and_two_axes_do() {
        let z = Vector3::z();
        let one: Vec<Pose> = [0.0, 0.3, 0.7, -0.4].iter().map(|&a| about(z, a)).collect();
        assert!(axis_spread_rad(&one) < 1e-9);
        assert!((largest_rotation_rad(&one) - 1.1).abs() < 1e-9);
        let mut two = one.clone();
        two.push(about(Vector3::x(), 0.5));
        assert!(axis_spread_rad(&two) > MIN_AXIS_SPREAD_RAD);
        let still: Vec<Pose> = (0..4).map(|i| about(z, 0.01 * f64::from(i))).collect();
        assert_eq!(axis_spread_rad(&still), 0.0);
    }
}
