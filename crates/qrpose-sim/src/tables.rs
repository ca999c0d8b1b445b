//! The paper's Tables 5-9: one case per set and distance, P2 at (60, −50, z), at the angle of
//! the "calculated" column, with the paper's "simulated" estimate; and ours beside it.

use super::evaluate::{Outcome, evaluate};
use super::grid::{Case, DISTANCES_MM, FOCAL_LENGTH_MM, rotation_set};
use super::run::{SimError, paper_setup};
use nalgebra::Vector3;
use qrpose_core::estimate::Method;
use qrpose_core::geometry::euler::EulerXyz;
use std::fmt::Write;

/// One row of Tables 5-9.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperRow {
    /// Working distance z of P2, mm (500 = Table 5 … 100 = Table 9).
    pub distance_mm: f64,
    /// Rotation set.
    pub set: &'static str,
    /// The "calculated" (true) free angle, degrees.
    pub angle_deg: f64,
    /// The paper's simulated free angle, degrees.
    pub paper_angle_deg: f64,
    /// The paper's simulated P2, mm.
    pub paper_p2_mm: [f64; 3],
}

const fn row(
    distance_mm: f64,
    set: &'static str,
    angle_deg: f64,
    paper_angle_deg: f64,
    p2: [f64; 3],
) -> PaperRow {
    PaperRow {
        distance_mm,
        set,
        angle_deg,
        paper_angle_deg,
        paper_p2_mm: p2,
    }
}

/// P2's true x and y in every row, mm.
pub const P2_XY_MM: [f64; 2] = [60.0, -50.0];

/// Tables 5-9 as printed. Table 9 prints "X-5-5" twice; its first such row sits where every
/// other table has X-5-0, so it is read as X-5-0.
pub const PAPER_ROWS: [PaperRow; 60] = [
    row(500.0, "X-0-0", 22.0, 23.22, [59.18, -49.48, 493.97]),
    row(500.0, "X-0-5", 16.0, 15.69, [59.54, -49.78, 496.98]),
    row(500.0, "X-5-0", 23.0, 21.16, [60.40, -50.49, 504.10]),
    row(500.0, "X-5-5", 25.0, 24.06, [60.27, -50.39, 503.02]),
    row(500.0, "0-Y-0", 25.0, 25.27, [59.72, -49.93, 498.45]),
    row(500.0, "0-Y-5", 25.0, 23.60, [60.38, -50.48, 503.99]),
    row(500.0, "5-Y-0", 20.0, 18.40, [60.33, -50.44, 503.58]),
    row(500.0, "5-Y-5", 14.0, 12.64, [60.08, -50.23, 501.43]),
    row(500.0, "0-0-Z", 25.0, 25.12, [59.51, -49.75, 496.70]),
    row(500.0, "0-5-Z", 25.0, 25.35, [59.62, -49.85, 497.65]),
    row(500.0, "5-0-Z", 25.0, 25.33, [59.47, -49.71, 496.33]),
    row(500.0, "5-5-Z", 25.0, 25.30, [59.61, -49.84, 497.54]),
    row(400.0, "X-0-0", 19.0, 19.32, [59.89, -49.89, 399.66]),
    row(400.0, "X-0-5", 15.0, 13.48, [60.29, -50.22, 402.32]),
    row(400.0, "X-5-0", 25.0, 23.31, [60.61, -50.48, 404.45]),
    row(400.0, "X-5-5", 25.0, 23.80, [60.53, -50.42, 403.91]),
    row(400.0, "0-Y-0", 24.0, 22.92, [60.24, -50.17, 401.95]),
    row(400.0, "0-Y-5", 25.0, 23.34, [60.48, -50.37, 403.54]),
    row(400.0, "5-Y-0", 18.0, 16.27, [60.21, -50.15, 401.74]),
    row(400.0, "5-Y-5", 16.0, 14.32, [60.20, -50.14, 401.67]),
    row(400.0, "0-0-Z", 25.0, 25.14, [59.04, -49.17, 393.93]),
    row(400.0, "0-5-Z", 25.0, 24.99, [59.46, -49.53, 396.79]),
    row(400.0, "5-0-Z", 25.0, 25.18, [59.41, -49.48, 396.44]),
    row(400.0, "5-5-Z", 25.0, 25.26, [59.57, -49.61, 397.48]),
    row(300.0, "X-0-0", 18.0, 17.71, [59.96, -50.03, 299.90]),
    row(300.0, "X-0-5", 15.0, 14.05, [60.03, -50.08, 300.21]),
    row(300.0, "X-5-0", 23.0, 21.15, [60.48, -50.46, 302.50]),
    row(300.0, "X-5-5", 25.0, 23.23, [60.61, -50.57, 303.13]),
    row(300.0, "0-Y-0", 23.0, 21.74, [60.29, -50.30, 301.55]),
    row(300.0, "0-Y-5", 25.0, 23.41, [60.41, -50.40, 302.12]),
    row(300.0, "5-Y-0", 22.0, 20.12, [60.56, -50.53, 302.89]),
    row(300.0, "5-Y-5", 18.0, 16.19, [60.16, -50.19, 300.88]),
    row(300.0, "0-0-Z", 25.0, 25.15, [58.92, -49.16, 294.70]),
    row(300.0, "0-5-Z", 25.0, 24.98, [59.44, -49.59, 297.29]),
    row(300.0, "5-0-Z", 25.0, 25.38, [58.95, -49.18, 294.83]),
    row(300.0, "5-5-Z", 25.0, 25.29, [59.46, -49.61, 297.38]),
    row(200.0, "X-0-0", 14.0, 12.49, [60.30, -50.24, 200.93]),
    row(200.0, "X-0-5", 15.0, 13.41, [60.31, -50.24, 200.95]),
    row(200.0, "X-5-0", 24.0, 22.30, [60.73, -50.60, 202.37]),
    row(200.0, "X-5-5", 23.0, 23.92, [59.47, -49.55, 198.17]),
    row(200.0, "0-Y-0", 22.0, 20.16, [60.52, -50.42, 201.66]),
    row(200.0, "0-Y-5", 22.0, 21.82, [60.20, -50.15, 200.59]),
    row(200.0, "5-Y-0", 25.0, 23.24, [60.68, -50.55, 202.19]),
    row(200.0, "5-Y-5", 25.0, 23.32, [60.61, -50.49, 201.95]),
    row(200.0, "0-0-Z", 25.0, 25.11, [59.78, -49.81, 199.20]),
    row(200.0, "0-5-Z", 25.0, 24.76, [60.01, -50.00, 199.97]),
    row(200.0, "5-0-Z", 25.0, 25.31, [59.79, -49.81, 199.24]),
    row(200.0, "5-5-Z", 25.0, 25.20, [59.95, -49.95, 199.76]),
    row(100.0, "X-0-0", 12.0, 10.74, [60.12, -50.12, 100.23]),
    row(100.0, "X-0-5", 13.0, 11.23, [59.96, -49.99, 99.97]),
    row(100.0, "X-5-0", 25.0, 23.13, [60.66, -50.57, 101.13]),
    row(100.0, "X-5-5", 25.0, 23.37, [60.67, -50.58, 101.15]),
    row(100.0, "0-Y-0", 25.0, 23.20, [60.48, -50.42, 100.82]),
    row(100.0, "0-Y-5", 25.0, 23.15, [60.63, -50.54, 101.08]),
    row(100.0, "5-Y-0", 25.0, 23.55, [60.48, -50.42, 100.83]),
    row(100.0, "5-Y-5", 25.0, 23.72, [60.51, -50.44, 100.87]),
    row(100.0, "0-0-Z", 25.0, 25.09, [59.96, -49.98, 99.96]),
    row(100.0, "0-5-Z", 25.0, 24.52, [59.97, -50.00, 99.98]),
    row(100.0, "5-0-Z", 25.0, 25.30, [59.94, -49.97, 99.92]),
    row(100.0, "5-5-Z", 25.0, 25.02, [60.02, -50.04, 100.06]),
];

impl PaperRow {
    /// The simulated case of this row.
    pub fn case(&self) -> Option<Case> {
        Some(Case {
            p2_mm: Vector3::new(P2_XY_MM[0], P2_XY_MM[1], self.distance_mm),
            set: rotation_set(self.set)?,
            angle_deg: self.angle_deg,
        })
    }
}

/// One method's result on one row: the free angle and P2 it estimated.
#[derive(Debug, Clone, PartialEq)]
pub struct RowEstimate {
    /// The judged outcome.
    pub outcome: Outcome,
    /// The estimated free angle, degrees (NaN without an estimate).
    pub angle_deg: f64,
    /// The estimated P2, mm: from the iteration for the depth methods, the pose otherwise.
    pub p2_mm: [f64; 3],
}

/// Runs `method` on a row's case (exact projection).
///
/// # Errors
/// [`SimError`] if the paper's camera or marker cannot be built.
pub fn estimate_row(row: &PaperRow, method: Method) -> Result<Option<RowEstimate>, SimError> {
    let (camera, marker) = paper_setup()?;
    let Some(case) = row.case() else {
        return Ok(None);
    };
    let Some(corners) = case.image_plane_corners_mm(&marker, FOCAL_LENGTH_MM) else {
        return Ok(None);
    };
    let outcome = evaluate(&case, &corners, &camera, &marker, method);
    let (angle_deg, p2_mm) = match &outcome.estimate {
        Some(e) => {
            let euler = EulerXyz::from_rotation(&e.pose.rotation()).to_degrees();
            let p2 = e.corners_cam[1].0;
            (euler[case.set.free as usize], [p2.x, p2.y, p2.z])
        }
        None => (f64::NAN, [f64::NAN; 3]),
    };
    Ok(Some(RowEstimate {
        outcome,
        angle_deg,
        p2_mm,
    }))
}

/// Tables 5-9 as text: the paper's simulated values beside each method's estimate.
///
/// # Errors
/// [`SimError`] if the paper's camera or marker cannot be built.
pub fn comparison_text() -> Result<String, SimError> {
    let methods = [Method::Paper, Method::DepthNewton, Method::Reprojection];
    let mut out = String::new();
    for (table, z) in DISTANCES_MM.iter().enumerate() {
        let _ = writeln!(
            out,
            "Table {}: P2 at (60, -50, {z}) mm. Angle deg; P2 x, y, z mm.",
            table + 5
        );
        let _ = writeln!(
            out,
            "{:<6} {:>5} | {:>28} | {:>37} | {:>28} | {:>28}",
            "set",
            "true",
            "paper (printed)",
            "paper method (ours; k, solved)",
            "depth-newton",
            "reprojection"
        );
        for row in PAPER_ROWS.iter().filter(|r| r.distance_mm == *z) {
            let [px, py, pz] = row.paper_p2_mm;
            let _ = write!(
                out,
                "{:<6} {:>5.1} | {:>6.2} {:>6.2} {:>6.2} {:>7.2} |",
                row.set, row.angle_deg, row.paper_angle_deg, px, py, pz
            );
            for m in methods {
                match estimate_row(row, m)? {
                    Some(r) => {
                        let [x, y, zz] = r.p2_mm;
                        let _ = write!(
                            out,
                            " {:>6.2} {:>6.2} {:>6.2} {:>7.2}",
                            r.angle_deg, x, y, zz
                        );
                        if m == Method::Paper {
                            let k = r
                                .outcome
                                .gain
                                .map_or("  - ".to_owned(), |k| format!("{k:.1}"));
                            let _ = write!(
                                out,
                                " {k:>4} {:>3}",
                                if r.outcome.solved { "yes" } else { "no" }
                            );
                        }
                        out.push_str(" |");
                    }
                    None => out.push_str(" no case |"),
                }
            }
            out.push('\n');
        }
        out.push('\n');
    }
    Ok(out)
}
