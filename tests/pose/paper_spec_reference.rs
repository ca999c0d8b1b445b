//! A second, deliberately plain implementation of docs/paper-method.md, written from the text alone,
//! against which `method = "paper"` must agree to 1e-9 mm on random inputs and parameters.

use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;
use qrpose::api::{
    estimate_corners,
    request::{CameraDto, CornerOrderDto, CornersRequest, MarkerDto, MethodDto, SolverDto},
};

const AGREE_MM: f64 = 1e-9;

struct Reference {
    z: [f64; 4],
    converged: bool,
    iterations: u32,
    e_c: Option<f64>,
    residuals: [f64; 6],
}

/// docs/paper-method.md, step by step. `xn` are the normalised corners P1..P4.
fn reference(xn: [[f64; 2]; 4], l: f64, z0: f64, k: f64, e_d: f64, n_max: u32) -> Reference {
    let edges = [(0, 1), (1, 2), (2, 3), (0, 3), (0, 2), (1, 3)];
    let lengths = [l, l, l, l, 2f64.sqrt() * l, 2f64.sqrt() * l];
    let at = [[0, 3, 4], [0, 1, 5], [1, 2, 4], [2, 3, 5]];
    let errors = |z: &[f64; 4]| {
        let p: Vec<[f64; 3]> = (0..4)
            .map(|i| [xn[i][0] * z[i], xn[i][1] * z[i], z[i]])
            .collect();
        let mut e = [0.0; 6];
        for (j, &(a, b)) in edges.iter().enumerate() {
            let d = ((p[a][0] - p[b][0]).powi(2)
                + (p[a][1] - p[b][1]).powi(2)
                + (p[a][2] - p[b][2]).powi(2))
            .sqrt();
            e[j] = lengths[j] - d;
        }
        e
    };
    let mut z = [z0; 4];
    let mut e_c = None;
    for n in 1..=n_max {
        let e = errors(&z);
        let mut next = z;
        for i in 0..4 {
            next[i] = z[i] + k * (e[at[i][0]] + e[at[i][1]] + e[at[i][2]]) / 3.0;
        }
        let change: f64 = (0..4).map(|i| (next[i] - z[i]).abs()).sum();
        z = next;
        e_c = Some(change);
        if change <= e_d {
            return Reference {
                z,
                converged: true,
                iterations: n,
                e_c,
                residuals: errors(&z),
            };
        }
    }
    Reference {
        z,
        converged: false,
        iterations: n_max,
        e_c,
        residuals: errors(&z),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn paper_method_agrees_with_a_plain_reading_of_spec_section_2(
        (ax, ay, az) in (-25.0..25.0f64, -25.0..25.0f64, -180.0..180.0f64),
        (x, y, z) in (-100.0..100.0f64, -100.0..100.0f64, 100.0..600.0f64),
        l in 20.0..80.0f64,
        z0 in 100.0..800.0f64,
        k in 0.5..2.0f64,
        e_d in 0.01..2.0f64,
        n_max in 1u64..60,
    ) {
        let f = 2.82;
        let r = Rotation3::from_euler_angles(ax.to_radians(), ay.to_radians(), az.to_radians());
        let model = [[0.0, l, 0.0], [0.0, 0.0, 0.0], [-l, 0.0, 0.0], [-l, l, 0.0]];
        let cam: Vec<Vector3<f64>> = model.iter().map(|m| r * Vector3::from(*m) + Vector3::new(x, y, z)).collect();
        let xn: [[f64; 2]; 4] = std::array::from_fn(|i| [cam[i].x / cam[i].z, cam[i].y / cam[i].z]);
        let request = CornersRequest {
            corners_px: None,
            corners_mm: Some(xn.iter().map(|p| vec![p[0] * f, p[1] * f]).collect()),
            corner_order: CornerOrderDto::Paper,
            camera: CameraDto { focal_length_mm: Some(f), ..Default::default() },
            marker: Some(MarkerDto { size_mm: l }),
            payload: None,
            solver: SolverDto { method: MethodDto::Paper, initial_z_mm: Some(z0), gain: k, tolerance_mm: e_d, max_iterations: n_max, ..SolverDto::default() },
            prior: None,
            flange_pose: None,
            min_grasp_probability: None,
        };
        let ours = estimate_corners(&request, None).map_err(|p| TestCaseError::fail(p.detail))?;
        // Same normalised inputs as the service sees them (x' / f).
        let xn_seen: [[f64; 2]; 4] = std::array::from_fn(|i| [xn[i][0] * f / f, xn[i][1] * f / f]);
        let want = reference(xn_seen, l, z0, k, e_d, u32::try_from(n_max).unwrap_or(u32::MAX));
        let d = &ours.diagnostics;
        prop_assert_eq!(d.converged, want.converged);
        prop_assert_eq!(d.iterations, want.iterations);
        for (i, c) in ours.corners_mm.iter().enumerate() {
            prop_assert!((c.z - want.z[i]).abs() < AGREE_MM, "z{}: {} vs {}", i + 1, c.z, want.z[i]);
            prop_assert!((c.x - xn_seen[i][0] * want.z[i]).abs() < AGREE_MM && (c.y - xn_seen[i][1] * want.z[i]).abs() < AGREE_MM);
        }
        let e_c = d.convergence_error_mm.zip(want.e_c).map(|(a, b)| (a - b).abs());
        prop_assert!(e_c.is_some_and(|diff| diff < AGREE_MM), "e_c {:?} vs {:?}", d.convergence_error_mm, want.e_c);
        let residuals = d.side_residuals_mm.ok_or_else(|| TestCaseError::fail("no residuals"))?;
        for (a, b) in residuals.iter().zip(want.residuals) {
            prop_assert!((a - b).abs() < AGREE_MM, "residual {a} vs {b}");
        }
    }
}
