//! The paper's Tables 5-9 as named cases: P2 at (60, −50, z) for every rotation set at the
//! angle of the table's "calculated" column, exact projection (docs/paper-method.md, The paper's simulation).

use qrpose::estimate::Method;
use qrpose_sim::tables::{PAPER_ROWS, estimate_row};

/// Exact input must come back this close: degrees, and mm for P2.
const EXACT_TOL: f64 = 1e-6;

#[test]
fn depth_newton_and_reprojection_recover_every_table_case_exactly() {
    for method in [Method::DepthNewton, Method::Reprojection] {
        for row in &PAPER_ROWS {
            let name = format!("{} at {} mm ({method:?})", row.set, row.distance_mm);
            let r = estimate_row(row, method)
                .expect("paper setup")
                .expect("a valid case");
            assert!(r.outcome.solved, "{name}: {:?}", r.outcome);
            assert!(
                (r.angle_deg - row.angle_deg).abs() < EXACT_TOL,
                "{name}: angle {} deg",
                r.angle_deg
            );
            let want = [60.0, -50.0, row.distance_mm];
            for (axis, (got, want)) in ["x", "y", "z"].iter().zip(r.p2_mm.iter().zip(want)) {
                assert!(
                    (got - want).abs() < EXACT_TOL,
                    "{name}: P2 {axis} = {got} mm, want {want} mm"
                );
            }
        }
    }
}

/// The printed method solves 17 of the 60 table cases; each with its first solving gain.
/// Every other case fails the paper's own 2° / 5 mm criterion at every gain.
const PAPER_METHOD_SOLVED: [(f64, &str, f64); 17] = [
    (500.0, "0-0-Z", 0.9),
    (500.0, "5-0-Z", 1.2),
    (500.0, "5-5-Z", 1.0),
    (400.0, "0-0-Z", 0.8),
    (400.0, "5-0-Z", 0.8),
    (400.0, "5-5-Z", 1.1),
    (300.0, "0-0-Z", 0.8),
    (300.0, "5-0-Z", 0.8),
    (300.0, "5-5-Z", 0.8),
    (200.0, "5-Y-5", 1.9),
    (200.0, "0-0-Z", 0.8),
    (200.0, "5-0-Z", 0.8),
    (200.0, "5-5-Z", 0.8),
    (100.0, "0-Y-0", 2.0),
    (100.0, "0-0-Z", 0.8),
    (100.0, "5-0-Z", 0.8),
    (100.0, "5-5-Z", 1.3),
];

#[test]
fn paper_method_solves_exactly_the_recorded_table_cases() {
    for row in &PAPER_ROWS {
        let name = format!("{} at {} mm", row.set, row.distance_mm);
        let r = estimate_row(row, Method::Paper)
            .expect("paper setup")
            .expect("a valid case");
        let expected = PAPER_METHOD_SOLVED
            .iter()
            .find(|(d, s, _)| *d == row.distance_mm && *s == row.set);
        match expected {
            Some(&(_, _, gain)) => {
                assert!(
                    r.outcome.solved,
                    "{name}: expected solved at k = {gain}: {:?}",
                    r.outcome.gain
                );
                let got = r.outcome.gain.expect("a solving gain");
                assert!(
                    (got - gain).abs() < 1e-9,
                    "{name}: first solving gain {got}, want {gain}"
                );
                assert!(
                    r.outcome.angle_error_deg <= 2.0 && r.outcome.depth_error_mm <= 5.0,
                    "{name}"
                );
            }
            None => assert!(
                !r.outcome.solved,
                "{name}: unexpectedly solved at k = {:?}",
                r.outcome.gain
            ),
        }
    }
}

#[test]
fn paper_method_loses_most_of_a_25_degree_tilt() {
    // Table 5, 0-Y-0: the paper prints 25.27° for a true 25°; the printed update returns a
    // marker turned far less, because it barely moves the corners' relative depths.
    let row = PAPER_ROWS
        .iter()
        .find(|r| r.distance_mm == 500.0 && r.set == "0-Y-0")
        .expect("row");
    let r = estimate_row(row, Method::Paper)
        .expect("paper setup")
        .expect("a valid case");
    assert!(r.angle_deg < 20.0, "estimated {} deg", r.angle_deg);
}
