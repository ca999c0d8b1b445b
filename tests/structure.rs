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
    for package in [
        "qrpose-core",
        "qrpose-detect",
        "qrpose-sim",
        "qrpose-site",
        "qrpose-calib",
        "qrpose-track",
    ] {
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

/// The JPEG splice (crates/jpeg-overlay) is a codec library of its own: no async or HTTP
/// crate, no image decoder or encoder (those are its tests' dev-dependencies), nothing of
/// qrpose.
#[test]
fn the_jpeg_splice_pulls_in_no_async_http_or_image_crate() {
    let names = dependency_names("jpeg-overlay");
    assert!(names.iter().any(|n| n == "thiserror"), "{names:?}");
    // Every qrpose crate depends on qrpose-core.
    let others = ["image", "zune-jpeg", "jpeg-encoder", "qrpose-core"];
    for forbidden in SERVICE_ONLY.iter().chain(&others) {
        assert!(
            !names.iter().any(|n| n == forbidden),
            "jpeg-overlay depends on {forbidden}"
        );
    }
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

/// Longest README, in lines: a user's page, not a lab notebook (docs/measurements/ keeps the
/// dated logs).
const README_MAX_LINES: usize = 250;

/// Most rows of the README's results table (the one whose header starts `| what | result`);
/// the other figures live in the docs it links.
const README_MAX_RESULT_ROWS: usize = 8;

/// The two commands a fresh machine with only the Rust toolchain runs first.
const FIRST_COMMANDS: [&str; 2] = ["cargo run --release -- serve", "cargo test"];

#[test]
fn the_readme_is_short_and_starts_with_the_two_commands() {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).expect("README.md");
    let lines = readme.lines().count();
    assert!(
        lines <= README_MAX_LINES,
        "README.md has {lines} lines, at most {README_MAX_LINES}"
    );
    let head: String = readme.lines().take(20).collect::<Vec<_>>().join("\n");
    for command in FIRST_COMMANDS {
        assert!(
            head.contains(command),
            "README.md's first 20 lines lack `{command}`"
        );
    }
    let rows = readme
        .lines()
        .skip_while(|l| !l.starts_with("| what | result"))
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .count();
    assert!(
        (1..=README_MAX_RESULT_ROWS).contains(&rows),
        "README.md's results table has {rows} rows, at most {README_MAX_RESULT_ROWS}"
    );
}

/// Whether `word` looks like an abbreviated or full git commit hash: 7-40 lowercase hex
/// digits with at least one digit and one letter a-f (so neither a number nor a word like
/// "deadbeef"; a SHA-256 is 64 and never matches).
fn is_hash_like(word: &str) -> bool {
    (7..=40).contains(&word.len())
        && word
            .bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
        && word.bytes().any(|b| b.is_ascii_digit())
        && word.bytes().any(|b| b.is_ascii_alphabetic())
}

/// The commit hashes cited in `text`: hash-like words in backticks (`4a75b23`) or after the
/// word "commit" / "commits". Words are maximal runs of ASCII letters and digits, so a hex
/// colour (`#ff00ff`) or a truncated SHA-256 after "sha256" is not one.
fn cited_commit_hashes(text: &str) -> Vec<String> {
    let bytes = text.as_bytes();
    let mut found = Vec::new();
    let mut previous_word = "";
    let mut previous_end = 0;
    let mut start = 0;
    while start < bytes.len() {
        if !bytes[start].is_ascii_alphanumeric() {
            start += 1;
            continue;
        }
        let end = bytes[start..]
            .iter()
            .position(|b| !b.is_ascii_alphanumeric())
            .map_or(bytes.len(), |n| start + n);
        let word = &text[start..end];
        let in_backticks = start > 0 && bytes[start - 1] == b'`' && bytes.get(end) == Some(&b'`');
        let after_commit = matches!(previous_word, "commit" | "commits" | "Commit" | "Commits")
            && text[previous_end..start].chars().all(char::is_whitespace);
        if is_hash_like(word) && (in_backticks || after_commit) {
            found.push(word.to_owned());
        }
        previous_word = word;
        previous_end = end;
        start = end;
    }
    found
}

#[test]
fn the_commit_hash_pattern_flags_commits_and_spares_hashes_and_colours() {
    assert_eq!(cited_commit_hashes("at commit 4a75b23, then"), ["4a75b23"]);
    assert_eq!(cited_commit_hashes("commits 7df67bc and"), ["7df67bc"]);
    assert_eq!(
        cited_commit_hashes("the tree at `ec49edb` plus"),
        ["ec49edb"]
    );
    let sha256 = "9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08";
    for innocent in [
        "yellow `#ffff00`, magenta `#ff00ff`",
        "frames sha256 2419489fe886",
        &format!("its sha256 `{sha256}`") as &str,
        "commit deadbeef and commit 1234567",
        "4a75b23 without a cue",
        "a commit, 4a75b23",
    ] {
        assert!(cited_commit_hashes(innocent).is_empty(), "{innocent}");
    }
}

#[test]
fn no_commit_hash_in_the_readme_or_the_reference_pages() {
    let mut pages = vec![Path::new(ROOT).join("README.md")];
    for entry in std::fs::read_dir(Path::new(ROOT).join("docs")).expect("docs/") {
        let path = entry.expect("an entry").path();
        if path.is_file() && path.extension().is_some_and(|e| e == "md") {
            pages.push(path);
        }
    }
    assert!(pages.len() > 5, "{pages:?}");
    let cited: Vec<String> = pages
        .iter()
        .flat_map(|page| {
            let text = std::fs::read_to_string(page).expect("utf-8");
            cited_commit_hashes(&text)
                .into_iter()
                .map(move |hash| format!("{}: {hash}", page.display()))
        })
        .collect();
    assert!(
        cited.is_empty(),
        "commit hashes belong in docs/measurements/ only: {cited:?}"
    );
}

/// The words serde's messages start with that choose a problem's code (`missing_field`,
/// `unknown_field`, `unknown_variant`): only [`SERDE_WORDING_READER`] reads them, pinned by
/// its tests against serde's own constructors.
const SERDE_MESSAGE_WORDS: [&str; 3] = ["missing field", "unknown field", "unknown variant"];

/// The one file of the service that reads serde's wording.
const SERDE_WORDING_READER: &str = "src/api/problem/shape.rs";

/// The code of a source file without its tests: what comes before its first
/// `#[cfg(test)]`, nothing for a file of tests (`tests.rs`, or under a `tests/` folder).
fn code_outside_tests<'a>(path: &Path, text: &'a str) -> &'a str {
    let is_tests = path.file_name().is_some_and(|n| n == "tests.rs")
        || path.components().any(|c| c.as_os_str() == "tests");
    if is_tests {
        return "";
    }
    text.find("#[cfg(test)]").map_or(text, |end| &text[..end])
}

/// The string literals in `code` that start with one of [`SERDE_MESSAGE_WORDS`].
fn serde_message_literals(code: &str) -> Vec<&'static str> {
    SERDE_MESSAGE_WORDS
        .iter()
        .filter(|words| code.contains(&format!("\"{words}")))
        .copied()
        .collect()
}

#[test]
fn the_serde_message_check_finds_message_matching_and_spares_tests() {
    let matching = "if message.starts_with(\"unknown field\") {\n";
    let path = Path::new("src/api/problem.rs");
    assert_eq!(
        serde_message_literals(code_outside_tests(path, matching)),
        ["unknown field"]
    );
    let in_tests = format!("fn f() {{}}\n#[cfg(test)]\nmod tests {{ {matching} }}");
    assert!(serde_message_literals(code_outside_tests(path, &in_tests)).is_empty());
    let tests_file = Path::new("src/api/problem/tests.rs");
    assert!(serde_message_literals(code_outside_tests(tests_file, matching)).is_empty());
    let docs = "/// refused as `missing_field`, a missing field\n";
    assert!(serde_message_literals(code_outside_tests(path, docs)).is_empty());
}

#[test]
fn only_one_file_chooses_error_codes_from_serdes_message_text() {
    let mut files = Vec::new();
    rust_files(&Path::new(ROOT).join("src"), &mut files);
    assert!(files.len() > 40, "{} files", files.len());
    let reader = Path::new(ROOT).join(SERDE_WORDING_READER);
    let reader_text = std::fs::read_to_string(&reader).expect("the wording reader");
    assert!(
        !serde_message_literals(code_outside_tests(&reader, &reader_text)).is_empty(),
        "{SERDE_WORDING_READER} reads serde's wording"
    );
    let found: Vec<String> = files
        .iter()
        .filter(|file| **file != reader)
        .flat_map(|file| {
            let text = std::fs::read_to_string(file).expect("utf-8");
            serde_message_literals(code_outside_tests(file, &text))
                .into_iter()
                .map(move |words| format!("{}: \"{words}", file.display()))
        })
        .collect();
    assert!(
        found.is_empty(),
        "choose codes through api::problem::ShapeKind, not serde's text: {found:?}"
    );
}

/// The service binary links neither the renderer nor the simulation's plotting and progress
/// crates: `qrpose render` and `qrpose simulate` are `qrpose-sim`'s.
#[test]
fn the_service_links_no_renderer_plotting_or_progress_bar() {
    let names = dependency_names("qrpose");
    assert!(names.iter().any(|n| n == "axum"), "{names:?}");
    for forbidden in ["qrpose-sim", "plotters", "indicatif", "rayon"] {
        assert!(
            !names.iter().any(|n| n == forbidden),
            "qrpose depends on {forbidden}"
        );
    }
}

/// Most test binaries the root crate may build: each links the whole service, so each
/// costs a link; `tests/NAME.rs` and `tests/NAME/main.rs` are one each, and the library's
/// and the binary's unit tests one each.
const ROOT_TEST_BINARIES_MAX: usize = 12;

#[test]
fn the_root_crate_builds_at_most_twelve_test_binaries() {
    let mut binaries = vec!["src/lib.rs".to_owned(), "src/main.rs".to_owned()];
    for entry in std::fs::read_dir(Path::new(ROOT).join("tests")).expect("tests/") {
        let path = entry.expect("an entry").path();
        let name = path.display().to_string();
        if path.extension().is_some_and(|e| e == "rs") || path.join("main.rs").is_file() {
            binaries.push(name);
        }
    }
    assert!(binaries.len() > 4, "{binaries:?}");
    assert!(
        binaries.len() <= ROOT_TEST_BINARIES_MAX,
        "{} test binaries, at most {ROOT_TEST_BINARIES_MAX}: {binaries:?}",
        binaries.len()
    );
}

/// The container health check stays a small client of a kept crate (reqwest), not an HTTP
/// implementation of its own.
#[test]
fn the_health_check_is_at_most_150_lines() {
    let path = Path::new(ROOT).join("src/cli/healthcheck.rs");
    let lines = std::fs::read_to_string(&path)
        .expect("src/cli/healthcheck.rs")
        .lines()
        .count();
    assert!(lines <= 150, "{} has {lines} lines", path.display());
}

#[test]
fn every_crate_has_a_readme() {
    let crates = std::fs::read_dir(Path::new(ROOT).join("crates")).expect("crates/");
    let missing: Vec<String> = crates
        .map(|entry| entry.expect("a crate").path())
        .filter(|krate| !krate.join("README.md").is_file())
        .map(|krate| krate.display().to_string())
        .collect();
    assert!(missing.is_empty(), "crates without a README: {missing:?}");
}

/// The library crates, as Rust paths name them.
const LIBRARY_CRATES: [&str; 7] = [
    "qrpose_core",
    "qrpose_detect",
    "qrpose_site",
    "qrpose_track",
    "qrpose_calib",
    "qrpose_sim",
    "jpeg_overlay",
];

/// Where `text` names one of `paths` (or a library crate) as a Rust path.
fn named_paths(text: &str, paths: &[&str]) -> Vec<String> {
    let mut named: Vec<String> = paths
        .iter()
        .filter(|path| text.contains(*path))
        .map(|path| (*path).to_owned())
        .collect();
    for krate in LIBRARY_CRATES {
        let forms = [
            format!("{krate}::"),
            format!("use {krate}"),
            format!("{krate} as"),
        ];
        if forms.iter().any(|form| text.contains(form.as_str())) {
            named.push(krate.to_owned());
        }
    }
    named
}

#[test]
fn the_path_check_finds_crate_paths_and_spares_metric_names() {
    let http = ["crate::detect", "crate::estimate", "crate::geometry"];
    assert_eq!(
        named_paths("use qrpose_site::Site;", &http),
        ["qrpose_site"]
    );
    assert_eq!(
        named_paths("crate::detect::cancel::CancelFlag", &http),
        ["crate::detect"]
    );
    assert!(named_paths("\"qrpose_site_reloads_total\" crate::app::Site", &http).is_empty());
}

/// The service edge reaches the crates only through the application layer, and the
/// application layer knows nothing of the server's settings.
#[test]
fn http_reaches_the_crates_only_through_the_application_layer() {
    let mut files = Vec::new();
    rust_files(&Path::new(ROOT).join("src/http"), &mut files);
    assert!(files.len() > 20, "{} files", files.len());
    let http = ["crate::detect", "crate::estimate", "crate::geometry"];
    let found: Vec<String> = files
        .iter()
        .flat_map(|file| {
            let text = std::fs::read_to_string(file).expect("utf-8");
            named_paths(&text, &http)
                .into_iter()
                .map(move |path| format!("{}: {path}", file.display()))
        })
        .collect();
    assert!(found.is_empty(), "name these through crate::app: {found:?}");
    let mut app = Vec::new();
    rust_files(&Path::new(ROOT).join("src/app"), &mut app);
    let config: Vec<String> = app
        .iter()
        .filter(|file| {
            std::fs::read_to_string(file)
                .expect("utf-8")
                .contains("crate::config")
        })
        .map(|file| file.display().to_string())
        .collect();
    assert!(
        config.is_empty(),
        "the application layer names config: {config:?}"
    );
}

/// The numerical core keeps no state of its own: no thread-local or global counter for
/// tests to read (the image answer counts its solves where a test can see them).
#[test]
fn the_core_keeps_no_global_or_thread_local_state() {
    let mut files = Vec::new();
    rust_files(&Path::new(ROOT).join("crates/qrpose-core/src"), &mut files);
    assert!(files.len() > 10, "{} files", files.len());
    let stateful: Vec<String> = files
        .iter()
        .filter(|file| {
            let text = std::fs::read_to_string(file).expect("utf-8");
            text.contains("thread_local!") || text.contains("static mut ")
        })
        .map(|file| file.display().to_string())
        .collect();
    assert!(stateful.is_empty(), "state in the core: {stateful:?}");
}
