//! Codes read correctly on a folder of real photos with a `manifest.json` (the zxing-cpp
//! sample set in `shared/data/qr-photos/zxing-cpp/`), per folder and per detector.
//!
//! ```sh
//! cargo run --release --example real_photos -- ../shared/data/qr-photos/zxing-cpp
//! cargo run --release --features zxing-cpp --example real_photos -- ../shared/data/qr-photos/zxing-cpp
//! ```
//!
//! A code counts as read when a detected symbol's text equals one of the image's expected
//! texts. Prints a markdown table and writes nothing; with `--misses`, also each image
//! where `auto` missed a code, with what every detector read there.

use qrpose::detect::{Backend, DetectorChoice, decode, find_candidates};
use std::collections::BTreeMap;
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let show_misses = args.iter().any(|a| a == "--misses");
    let root = PathBuf::from(
        args.iter()
            .find(|a| !a.starts_with("--"))
            .cloned()
            .unwrap_or_else(|| "../shared/data/qr-photos/zxing-cpp".to_owned()),
    );
    let manifest: serde_json::Value = match std::fs::read(root.join("manifest.json"))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
    {
        Some(m) => m,
        None => {
            eprintln!("no manifest.json under {}", root.display());
            std::process::exit(1);
        }
    };
    let images = manifest["images"].as_array().cloned().unwrap_or_default();
    let mut detectors: Vec<(&str, DetectorChoice)> = vec![
        ("rqrr", DetectorChoice::Only(Backend::Rqrr)),
        ("rxing", DetectorChoice::Only(Backend::Rxing)),
    ];
    if Backend::ZxingCpp.is_built() {
        detectors.push(("zxing-cpp", DetectorChoice::Only(Backend::ZxingCpp)));
    }
    detectors.push(("auto", DetectorChoice::Auto));
    // folder -> detector -> (read, total)
    let mut table: BTreeMap<String, BTreeMap<&str, (usize, usize)>> = BTreeMap::new();
    for entry in &images {
        let path = root.join(entry["path"].as_str().unwrap_or_default());
        let group = entry["group"].as_str().unwrap_or("?").to_owned();
        let expected: Vec<String> = entry["expected_texts"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|t| t.as_str().map(str::to_owned))
                    .collect()
            })
            .unwrap_or_default();
        let Ok(bytes) = std::fs::read(&path) else {
            eprintln!("cannot read {}", path.display());
            continue;
        };
        let image = decode::decode_gray(&bytes, &decode::DecodeLimits::default());
        let mut seen = Vec::new();
        for (name, choice) in &detectors {
            let texts: Vec<String> = image
                .as_ref()
                .ok()
                .and_then(|img| find_candidates(img, *choice).ok())
                .unwrap_or_default()
                .into_iter()
                .filter_map(|c| c.text)
                .collect();
            let read = expected.iter().filter(|t| texts.contains(t)).count();
            seen.push(format!("{name} {read}/{} {texts:?}", expected.len()));
            if show_misses && *name == "auto" && read < expected.len() {
                println!(
                    "miss {}: expected {expected:?}; {}",
                    path.display(),
                    seen.join("; ")
                );
            }
            let cell = table
                .entry(group.clone())
                .or_default()
                .entry(name)
                .or_default();
            cell.0 += read;
            cell.1 += expected.len();
        }
    }
    let names: Vec<&str> = detectors.iter().map(|(n, _)| *n).collect();
    println!("| folder | codes | {} |", names.join(" | "));
    println!("|---|---|{}", "---|".repeat(names.len()));
    let mut totals: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for (group, row) in &table {
        let codes = row.values().next().map_or(0, |c| c.1);
        let cells: Vec<String> = names
            .iter()
            .map(|n| {
                let (r, t) = row.get(n).copied().unwrap_or_default();
                let total = totals.entry(n).or_default();
                total.0 += r;
                total.1 += t;
                format!("{r}")
            })
            .collect();
        println!("| {group} | {codes} | {} |", cells.join(" | "));
    }
    let codes = totals.values().next().map_or(0, |c| c.1);
    let cells: Vec<String> = names
        .iter()
        .map(|n| {
            let (r, t) = totals.get(n).copied().unwrap_or_default();
            format!("{r} ({:.1} %)", 100.0 * r as f64 / t.max(1) as f64)
        })
        .collect();
    println!("| **all** | {codes} | {} |", cells.join(" | "));
}
