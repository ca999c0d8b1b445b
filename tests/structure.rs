//! The shape of the workspace that the compiler alone does not keep: the numerical core and
//! the detector pull in no async or HTTP crate, and no source file grows past 500 lines.

use std::path::{Path, PathBuf};
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Crates that belong to the service, never to the library crates.
const SERVICE_ONLY: [&str; 7] = [
    "tokio",
    "axum",
    "hyper",
    "tower",
    "utoipa",
    "reqwest",
    "prometheus-client",
];

/// The packages `package` depends on (normal dependencies, transitively), by name.
fn dependency_names(package: &str) -> Vec<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let out = Command::new(cargo)
        .current_dir(ROOT)
        .args([
            "tree",
            "--offline",
            "--locked",
            "-p",
            package,
            "-e",
            "normal",
            "--prefix",
            "none",
            "--format",
            "{p}",
        ])
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "cargo tree -p {package}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|line| line.split_whitespace().next().map(str::to_owned))
        .collect()
}

#[test]
fn the_core_and_the_detector_pull_in_no_async_or_http_crate() {
    for package in ["qrpose-core", "qrpose-detect", "qrpose-sim", "qrpose-site"] {
        let names = dependency_names(package);
        assert!(
            names.iter().any(|n| n == "nalgebra"),
            "{package}: {names:?}"
        );
        for forbidden in SERVICE_ONLY {
            assert!(
                !names.iter().any(|n| n == forbidden),
                "{package} depends on {forbidden}"
            );
        }
    }
    let core = dependency_names("qrpose-core");
    assert!(
        !core.iter().any(|n| n == "image" || n == "rxing"),
        "qrpose-core is numerical only: {core:?}"
    );
}

/// Every `.rs` file under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("a readable directory") {
        let path = entry.expect("an entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn no_source_file_is_over_500_lines() {
    let mut files = Vec::new();
    rust_files(&Path::new(ROOT).join("src"), &mut files);
    for krate in std::fs::read_dir(Path::new(ROOT).join("crates")).expect("crates/") {
        rust_files(&krate.expect("a crate").path().join("src"), &mut files);
    }
    assert!(files.len() > 40, "{} files", files.len());
    let long: Vec<String> = files
        .iter()
        .filter_map(|f| {
            let lines = std::fs::read_to_string(f).expect("utf-8").lines().count();
            (lines > 500).then(|| format!("{} ({lines} lines)", f.display()))
        })
        .collect();
    assert!(long.is_empty(), "split these: {long:?}");
}
