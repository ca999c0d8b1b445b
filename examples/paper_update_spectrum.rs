//! Why the paper's update (Eq. 12) loses the tilt: its linearisation at the true solution.
//!
//! `cargo run --release --example paper_update_spectrum`
//!
//! Near the true depths z*, one simultaneous update is z ← z + k·A·e(z), with A the 4×6
//! averaging of the three edges at each corner (Table 2 as docs/paper-method.md reads it) and
//! e the six condition errors (Eqs. 10-11). Linearised, the error δ = z − z* evolves as
//! δ ← (I + k·A·E)·δ with E = ∂e/∂z. The iteration converges locally only if every
//! eigenvalue μ = 1 + k·λ of that matrix has |μ| < 1, and an eigenvalue with |μ| close to 1
//! moves so slowly that e_c = Σ|Δz| drops below e_d = 1 mm long before that mode is
//! corrected (the iteration "converges" to the wrong depths). This prints, for a few views,
//! each mode's shape (how the four corners move) and μ at k = 1 and k = 2.

use nalgebra::{Matrix4, SMatrix, Vector3};
use qrpose::geometry::{
    euler::EulerXyz,
    frames::MarkerToCamera,
    marker::{EDGES, INCIDENT_EDGES, Marker},
};

fn update_matrix(pose: &MarkerToCamera, marker: &Marker) -> Matrix4<f64> {
    let p = marker.object_points().map(|m| pose.transform(&m).0.coords);
    let q = p.map(|c| c / c.z);
    // E = ∂e/∂z: e_j = L_j − |P_a − P_b|, P_i = z_i·q_i.
    let mut e = SMatrix::<f64, 6, 4>::zeros();
    for (j, edge) in EDGES.iter().enumerate() {
        let d: Vector3<f64> = p[edge.a] - p[edge.b];
        e[(j, edge.a)] = -d.dot(&q[edge.a]) / d.norm();
        e[(j, edge.b)] = d.dot(&q[edge.b]) / d.norm();
    }
    let mut a = SMatrix::<f64, 4, 6>::zeros();
    for (i, incident) in INCIDENT_EDGES.iter().enumerate() {
        for &j in incident {
            a[(i, j)] = 1.0 / 3.0;
        }
    }
    a * e
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let marker = Marker::try_new(50.0)?;
    let views = [
        (
            "on axis, square on, 500 mm",
            [0.0, 0.0, 0.0],
            [25.0, -25.0, 500.0],
        ),
        (
            "(60, -50) mm off axis, square on, 500 mm",
            [0.0, 0.0, 0.0],
            [60.0, -50.0, 500.0],
        ),
        (
            "(60, -50) mm off axis, tilted 20° about y, 500 mm",
            [0.0, 20.0, 0.0],
            [60.0, -50.0, 500.0],
        ),
        (
            "(100, 100) mm off axis, square on, 100 mm",
            [0.0, 0.0, 0.0],
            [100.0, 100.0, 100.0],
        ),
    ];
    for (name, angles, p2) in views {
        let pose = MarkerToCamera::new(
            EulerXyz::from_degrees(angles[0], angles[1], angles[2]).to_rotation(),
            Vector3::from(p2),
        );
        let ae = update_matrix(&pose, &marker);
        println!("{name}:");
        let eig = ae.complex_eigenvalues();
        let mut modes: Vec<_> = eig.iter().collect();
        modes.sort_by(|a, b| a.re.total_cmp(&b.re));
        for lambda in modes {
            let mu1 = (1.0 + lambda).norm();
            let mu2 = (1.0 + 2.0 * lambda).norm();
            let shape = if lambda.im.abs() < 1e-12 {
                // Null vector of (AE − λI) gives how the corners move in this mode.
                let m = ae - Matrix4::identity() * lambda.re;
                let svd = m.svd(false, true);
                let v = svd.v_t.map(|vt| vt.row(3).transpose().normalize());
                v.map_or("?".to_owned(), |v| {
                    format!("[{:+.2} {:+.2} {:+.2} {:+.2}]", v[0], v[1], v[2], v[3])
                })
            } else {
                "complex pair".to_owned()
            };
            println!(
                "  λ = {:+.5}{:+.5}i  mode (z1..z4) {shape}  |μ| at k=1: {mu1:.5}, at k=2: {mu2:.5}",
                lambda.re, lambda.im
            );
        }
    }
    Ok(())
}
