//! The dependency rule of STYLE.md: the numerical core, the detector, the renderer and the simulation never
//! name the HTTP stack, and the wire types name no web framework.

use std::path::{Path, PathBuf};

const HTTP_CRATES: [&str; 5] = ["axum", "tokio", "tower", "reqwest", "hyper"];

fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return files;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files.extend(rust_files(&path));
        } else if path.extension().is_some_and(|e| e == "rs") {
            files.push(path);
        }
    }
    files
}

/// Crate names used as whole words on code lines (comments are prose and may name anything).
fn named_crates(source: &str, crates: &[&str]) -> Vec<(usize, String)> {
    let mut hits = Vec::new();
    for (n, line) in source.lines().enumerate() {
        let code = line.split("//").next().unwrap_or("");
        let words = code.split(|c: char| !(c.is_alphanumeric() || c == '_'));
        for word in words {
            if crates.contains(&word) {
                hits.push((n + 1, word.to_owned()));
            }
        }
    }
    hits
}

fn assert_layer_free_of(module: &str, crates: &[&str]) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("src")
        .join(module);
    let mut violations = Vec::new();
    for file in rust_files(&dir)
        .into_iter()
        .chain([dir.with_extension("rs")])
    {
        if let Ok(source) = std::fs::read_to_string(&file) {
            for (line, name) in named_crates(&source, crates) {
                violations.push(format!("{}:{line} names `{name}`", file.display()));
            }
        }
    }
    assert!(
        violations.is_empty(),
        "layering violations:\n{}",
        violations.join("\n")
    );
}

#[test]
fn core_detector_and_simulation_never_name_the_http_stack_or_openapi() {
    let forbidden: Vec<&str> = HTTP_CRATES.iter().copied().chain(["utoipa"]).collect();
    for module in ["geometry", "estimate", "detect", "sim", "render"] {
        assert_layer_free_of(module, &forbidden);
    }
}

#[test]
fn wire_types_never_name_the_http_stack() {
    assert_layer_free_of("api", &HTTP_CRATES);
}

#[test]
fn the_scanner_sees_code_but_not_comments() {
    let hits = named_crates(
        "use axum::Router; // tokio is fine in prose\nlet tower_x = 1;",
        &HTTP_CRATES,
    );
    assert_eq!(hits, vec![(1, "axum".to_owned())]);
}
