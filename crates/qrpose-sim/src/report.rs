//! Table 10 and friends as text, JSON (README.md, From the command line) and CSV.

use super::run::{CaseResult, GridResult, Panel};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write;

/// The paper's Table 10: convergence % per set at 500, 400, 300, 200, 100 mm.
pub const PAPER_TABLE_10: [(&str, [f64; 5]); 12] = [
    ("X-0-0", [88.21, 86.39, 78.23, 78.00, 74.60]),
    ("X-0-5", [94.33, 93.42, 83.90, 78.46, 75.96]),
    ("X-5-0", [55.10, 55.56, 56.92, 58.05, 68.03]),
    ("X-5-5", [56.69, 55.78, 57.60, 60.54, 68.03]),
    ("0-Y-0", [79.14, 82.99, 76.87, 77.78, 74.60]),
    ("0-Y-5", [86.17, 90.48, 76.87, 75.28, 72.34]),
    ("5-Y-0", [54.65, 54.88, 55.10, 57.37, 67.35]),
    ("5-Y-5", [53.29, 53.51, 54.20, 57.37, 100.00]),
    ("0-0-Z", [100.00, 100.00, 100.00, 100.00, 100.00]),
    ("0-5-Z", [88.89, 86.17, 86.39, 91.38, 100.00]),
    ("5-0-Z", [88.89, 87.07, 84.13, 85.26, 98.19]),
    ("5-5-Z", [77.32, 77.78, 78.00, 86.85, 96.37]),
];

/// The paper's overall convergence figure, %.
pub const PAPER_OVERALL_PCT: f64 = 77.28;

/// Error statistics over a set of cases.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Cases counted.
    pub cases: usize,
    /// Share solved (docs/paper-method.md, The paper's simulation), %.
    pub solved_pct: f64,
    /// Share converged (the method's own criterion), %.
    pub converged_pct: f64,
    /// Mean of max |ΔEuler| over cases with an estimate, degrees.
    pub angle_error_mean_deg: f64,
    /// 95th percentile of max |ΔEuler|, degrees.
    pub angle_error_p95_deg: f64,
    /// Mean of max |Δz_i|, mm.
    pub depth_error_mean_mm: f64,
    /// 95th percentile of max |Δz_i|, mm.
    pub depth_error_p95_mm: f64,
}

/// The q-quantile (0..1) of finite values, by the nearest-rank method; NaN when empty.
pub fn quantile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    // Nearest rank: the smallest k with k / n ≥ q, counted without float-to-int casts.
    let n = values.len();
    let rank = (1..=n).find(|&k| k as f64 >= q * n as f64).unwrap_or(n);
    values[rank - 1]
}

impl ErrorStats {
    /// Statistics of the given cases.
    pub fn of<'a>(cases: impl Iterator<Item = &'a CaseResult>) -> Self {
        let mut n = 0;
        let (mut solved, mut converged) = (0, 0);
        let (mut angles, mut depths) = (Vec::new(), Vec::new());
        for c in cases {
            n += 1;
            solved += usize::from(c.solved);
            converged += usize::from(c.converged);
            if c.angle_error_deg.is_finite() && c.depth_error_mm.is_finite() {
                angles.push(c.angle_error_deg);
                depths.push(c.depth_error_mm);
            }
        }
        let mean = |v: &[f64]| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let pct = |k: usize| 100.0 * k as f64 / n.max(1) as f64;
        Self {
            cases: n,
            solved_pct: pct(solved),
            converged_pct: pct(converged),
            angle_error_mean_deg: mean(&angles),
            angle_error_p95_deg: quantile(&mut angles, 0.95),
            depth_error_mean_mm: mean(&depths),
            depth_error_p95_mm: quantile(&mut depths, 0.95),
        }
    }
}

/// JSON document of `docs/paper-method.md` (The `simulate` output), plus per-set error statistics when noise was applied.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimulationJson {
    /// The method.
    pub method: String,
    /// Convergence % per set, one value per distance in run order.
    pub convergence_pct: BTreeMap<String, Vec<f64>>,
    /// Coverage % per set, same shape.
    pub coverage_pct: BTreeMap<String, Vec<f64>>,
    /// Mean of all panels' convergence %.
    pub overall_convergence_pct: f64,
    /// Mean of all panels' coverage %.
    pub overall_coverage_pct: f64,
    /// The distances, mm, of the per-set arrays.
    pub distances_mm: Vec<f64>,
    /// With `--noise-px`: the noise and per-set statistics.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseJson>,
}

/// The noise study's part of the JSON.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseJson {
    /// σ per coordinate, px.
    pub sigma_px: f64,
    /// Pixel pitch, µm.
    pub pixel_size_um: f64,
    /// Seed.
    pub seed: u64,
    /// Statistics per set over all its distances, positions and angles.
    pub per_set: BTreeMap<String, ErrorStats>,
}

fn per_set<F: Fn(&Panel) -> f64>(result: &GridResult, f: F) -> BTreeMap<String, Vec<f64>> {
    let mut map: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for p in &result.panels {
        map.entry(p.set.name.to_owned()).or_default().push(f(p));
    }
    map
}

/// Per-set statistics over all of a set's cases.
pub fn stats_per_set(result: &GridResult) -> BTreeMap<String, ErrorStats> {
    result
        .spec
        .sets
        .iter()
        .map(|s| {
            let cases = result
                .panels
                .iter()
                .filter(|p| p.set.name == s.name)
                .flat_map(|p| p.cases.iter().flatten());
            (s.name.to_owned(), ErrorStats::of(cases))
        })
        .collect()
}

/// The JSON document of a run.
pub fn to_json(result: &GridResult) -> SimulationJson {
    SimulationJson {
        method: result.method.as_str().to_owned(),
        convergence_pct: per_set(result, Panel::convergence_pct),
        coverage_pct: per_set(result, Panel::coverage_pct),
        overall_convergence_pct: result.overall_convergence_pct(),
        overall_coverage_pct: result.overall_coverage_pct(),
        distances_mm: result.spec.distances_mm.clone(),
        noise: result.spec.noise.map(|n| NoiseJson {
            sigma_px: n.sigma_px,
            pixel_size_um: n.pixel_size_um,
            seed: n.seed,
            per_set: stats_per_set(result),
        }),
    }
}

/// CSV: one row per set and distance.
pub fn to_csv(result: &GridResult) -> String {
    let mut out =
        String::from("method,set,distance_mm,convergence_pct,coverage_pct,paper_convergence_pct\n");
    for p in &result.panels {
        let paper =
            paper_value(p.set.name, p.distance_mm).map_or(String::new(), |v| format!("{v:.2}"));
        let _ = writeln!(
            out,
            "{},{},{},{:.2},{:.2},{paper}",
            result.method.as_str(),
            p.set.name,
            p.distance_mm,
            p.convergence_pct(),
            p.coverage_pct()
        );
    }
    out
}

/// CSV of every position's maximum solved angle (−1 = diverged).
pub fn max_angles_csv(result: &GridResult) -> String {
    let mut out = String::from("set,distance_mm,x_mm,y_mm,max_angle_deg\n");
    for p in &result.panels {
        let angles = p.max_angles_deg();
        let mut k = 0;
        for x in &p.x_mm {
            for y in &p.y_mm {
                let _ = writeln!(
                    out,
                    "{},{},{x},{y},{}",
                    p.set.name, p.distance_mm, angles[k]
                );
                k += 1;
            }
        }
    }
    out
}

/// The paper's Table 10 value for a set and distance.
pub fn paper_value(set: &str, distance_mm: f64) -> Option<f64> {
    let col = super::grid::DISTANCES_MM
        .iter()
        .position(|d| *d == distance_mm)?;
    PAPER_TABLE_10
        .iter()
        .find(|(s, _)| *s == set)
        .map(|(_, v)| v[col])
}

/// Table 10 as text: ours beside the paper's, per set and distance; then coverage.
pub fn to_table(result: &GridResult) -> String {
    let mut out = String::new();
    let ds = &result.spec.distances_mm;
    let _ = writeln!(
        out,
        "method: {}   convergence % (ours / paper) and coverage %",
        result.method.as_str()
    );
    let _ = write!(out, "{:<7}", "set");
    for d in ds {
        let _ = write!(out, " | {:>6} mm conv   cover", d);
    }
    out.push('\n');
    for set in &result.spec.sets {
        let _ = write!(out, "{:<7}", set.name);
        for d in ds {
            match result.panel(set.name, *d) {
                Some(p) => {
                    let paper = paper_value(set.name, *d)
                        .map_or("   -  ".to_owned(), |v| format!("{v:6.2}"));
                    let _ = write!(
                        out,
                        " | {:6.2}/{paper} {:6.2}",
                        p.convergence_pct(),
                        p.coverage_pct()
                    );
                }
                None => out.push_str(" |                        "),
            }
        }
        out.push('\n');
    }
    let _ = writeln!(
        out,
        "overall convergence {:.2} % (paper {PAPER_OVERALL_PCT:.2} %), coverage {:.2} %",
        result.overall_convergence_pct(),
        result.overall_coverage_pct()
    );
    if let Some(n) = result.spec.noise {
        let _ = writeln!(
            out,
            "\nnoise σ = {} px at {} µm/px (seed {}):",
            n.sigma_px, n.pixel_size_um, n.seed
        );
        let _ = writeln!(
            out,
            "{:<7} | solved % | conv. % | angle err mean / p95 (deg) | depth err mean / p95 (mm)",
            "set"
        );
        for (name, s) in stats_per_set(result) {
            let _ = writeln!(
                out,
                "{name:<7} | {:8.2} | {:7.2} | {:10.3} / {:8.3}     | {:10.3} / {:8.3}",
                s.solved_pct,
                s.converged_pct,
                s.angle_error_mean_deg,
                s.angle_error_p95_deg,
                s.depth_error_mean_mm,
                s.depth_error_p95_mm
            );
        }
    }
    out
}
