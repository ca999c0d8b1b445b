//! `qrpose-sim simulate`, run as a user would: the JSON and CSV of a small grid, the
//! heatmaps, the paper's Tables 5-9, and a refusal.

use serde_json::Value;
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_qrpose-sim"))
        .args(args)
        .output()
        .expect("qrpose-sim runs")
}

fn json(bytes: &[u8]) -> Value {
    serde_json::from_slice(bytes)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(bytes)))
}

#[test]
fn simulate_prints_spec_json_for_a_tiny_grid() {
    let out = run(&[
        "simulate",
        "--method",
        "depth-newton",
        "--sets",
        "X-0-0,0-0-Z",
        "--distances-mm",
        "500,100",
        "--stride",
        "10",
        "--format",
        "json",
    ]);
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json(&out.stdout);
    assert_eq!(v["method"], "depth-newton");
    assert_eq!(
        v["convergence_pct"]["X-0-0"],
        serde_json::json!([100.0, 100.0])
    );
    assert_eq!(
        v["coverage_pct"]["0-0-Z"],
        serde_json::json!([100.0, 100.0])
    );
    assert_eq!(v["overall_convergence_pct"], 100.0);
}

#[test]
fn simulate_writes_heatmaps_and_max_angles() {
    let dir = std::env::temp_dir().join(format!("qrpose-heatmaps-{}", std::process::id()));
    let out = run(&[
        "simulate",
        "--method",
        "paper",
        "--sets",
        "5-5-Z",
        "--distances-mm",
        "100",
        "--stride",
        "5",
        "--format",
        "csv",
        "--out",
        dir.to_str().expect("utf-8 path"),
    ]);
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = String::from_utf8_lossy(&out.stdout);
    assert!(csv.starts_with("method,set,distance_mm,convergence_pct,coverage_pct,paper_convergence_pct\npaper,5-5-Z,100,"), "{csv}");
    assert!(
        csv.trim_end().ends_with(",96.37"),
        "the paper's Table 10 value sits beside ours: {csv}"
    );
    let svg = std::fs::read_to_string(dir.join("paper_5-5-Z_100mm.svg")).expect("panel heatmap");
    assert!(svg.contains("<svg") && svg.contains("5-5-Z at 100 mm"));
    assert!(dir.join("paper_overview_100mm.svg").exists());
    let angles = std::fs::read_to_string(dir.join("max_angles.csv")).expect("max angles");
    assert_eq!(
        angles.lines().count(),
        1 + 5 * 5,
        "header and 5 × 5 positions"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn simulate_tables_prints_every_paper_case() {
    let out = run(&["simulate", "--tables"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for table in 5..=9 {
        assert!(text.contains(&format!("Table {table}:")), "Table {table}");
    }
    assert_eq!(text.lines().filter(|l| l.starts_with("5-5-Z")).count(), 5);
}

#[test]
fn simulate_refuses_an_unknown_set() {
    let out = run(&["simulate", "--sets", "Q-0-0"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown rotation set"));
}
