//! Site files, good and bad: every refusal names the file, the line and a reason a person
//! can act on.

use qrpose_site::{Reason, Site, SiteError, SizeSource};
use std::path::{Path, PathBuf};

const GOOD: &str = "\
cameras:
  front:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}
    distortion: {model: plumb_bob, coefficients: [-0.1, 0.01, 0, 0, 0]}
    mount:
      translation_mm: [250, 0, 400]
      quaternion_wxyz: [0.5, -0.5, 0.5, -0.5]
  rear:
    intrinsics: {fx_px: 800, fy_px: 800, cx_px: 320, cy_px: 240}
markers:
  default_size_mm: 50
  sizes:
    - {payload: \"DOCK-7\", size_mm: 120}
    - {prefix: \"TOTE-\", size_mm: 40}
    - {pattern: \"^LOC-[0-9]{4}$\", size_mm: 80}
map:
  - {payload: \"LOC-0001\", translation_mm: [1000, 2000, 0], quaternion_wxyz: [1, 0, 0, 0]}
  - {payload: \"LOC-0002\", translation_mm: [3000, 2000, 0], quaternion_wxyz: [0, 0, 0, 2]}
";

fn parse(text: &str) -> Result<Site, SiteError> {
    Site::parse(text, Path::new("/sites/test-site.yaml"))
}

/// A temporary directory of its own for a test.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-site-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    dir
}

#[test]
fn a_good_file_resolves_cameras_sizes_and_map() {
    let site = parse(GOOD).expect("a valid site");
    assert_eq!(site.cameras().keys().collect::<Vec<_>>(), ["front", "rear"]);
    let front = site.camera("front").expect("front");
    assert_eq!(front.camera.fx(), 1000.0);
    assert_eq!(
        front.camera.distortion().coefficients(),
        [-0.1, 0.01, 0.0, 0.0, 0.0]
    );
    let mount = front.mount.expect("a mount");
    // The quaternion (0.5, -0.5, 0.5, -0.5) turns camera z (forward) into robot x.
    let forward = mount.rotation * nalgebra::Vector3::z();
    assert!(
        (forward - nalgebra::Vector3::x()).norm() < 1e-12,
        "{forward}"
    );
    assert!(site.camera("rear").expect("rear").mount.is_none());
    let s = site.sizes();
    let lookup = |p| s.lookup(Some(p)).map(|l| (l.size_mm, l.source));
    assert_eq!(lookup("DOCK-7"), Some((120.0, SizeSource::SiteExact)));
    assert_eq!(lookup("TOTE-9"), Some((40.0, SizeSource::SitePrefix)));
    assert_eq!(lookup("LOC-0001"), Some((80.0, SizeSource::SitePattern)));
    assert_eq!(lookup("SKU-1"), Some((50.0, SizeSource::SiteDefault)));
    // [0, 0, 0, 2] is normalised to a 180° turn about z.
    let loc2 = site.mapped("LOC-0002").expect("mapped");
    assert!((loc2.rotation.angle() - std::f64::consts::PI).abs() < 1e-12);
    assert!(site.mapped("LOC-0003").is_none());
    assert_eq!(site.sha256_hex().len(), 64);
}

#[test]
fn the_hash_is_the_sha256_of_the_file_bytes() {
    let site = parse("markers: {default_size_mm: 50}\n").expect("valid");
    // sha256("markers: {default_size_mm: 50}\n"), computed with sha256sum.
    assert_eq!(
        site.sha256_hex(),
        qrpose_site::site::sha256_hex(b"markers: {default_size_mm: 50}\n")
    );
    assert_ne!(
        site.sha256_hex(),
        parse("markers: {default_size_mm: 51}\n")
            .expect("valid")
            .sha256_hex()
    );
}

/// `GOOD` with `from` replaced by `to` (which must occur).
fn good_with(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from}");
    GOOD.replacen(from, to, 1)
}

#[test]
fn every_bad_file_is_refused_with_its_line_and_reason() {
    let cases: Vec<(&str, String, Option<usize>, &str)> = vec![
        (
            "unknown top-level key",
            format!("{GOOD}camras: {{}}\n"),
            Some(19),
            "unknown field `camras`",
        ),
        (
            "unknown camera key",
            good_with("    mount:\n", "    mounting:\n"),
            Some(5),
            "unknown field `mounting`",
        ),
        (
            "unknown size-rule key",
            good_with("{prefix: \"TOTE-\"", "{prefx: \"TOTE-\""),
            Some(14),
            "unknown field `prefx`",
        ),
        (
            "duplicate exact payload",
            good_with(
                "    - {prefix: \"TOTE-\", size_mm: 40}\n",
                "    - {payload: \"DOCK-7\", size_mm: 100}\n",
            ),
            Some(14),
            "payload \"DOCK-7\" is listed twice",
        ),
        (
            "duplicate mapped payload",
            good_with("\"LOC-0002\"", "\"LOC-0001\""),
            Some(18),
            "payload \"LOC-0001\" is listed twice",
        ),
        (
            "invalid regular expression",
            good_with("^LOC-[0-9]{4}$", "^LOC-[0-9{4}$"),
            Some(15),
            "invalid pattern",
        ),
        (
            "zero quaternion",
            good_with("[0, 0, 0, 2]", "[0, 0, 0, 0]"),
            Some(18),
            "is not a rotation",
        ),
        (
            "non-finite quaternion",
            good_with("[0, 0, 0, 2]", "[.nan, 0, 0, 1]"),
            Some(18),
            "is not a rotation",
        ),
        (
            "quaternion with three numbers",
            good_with("[0.5, -0.5, 0.5, -0.5]", "[0.5, -0.5, 0.5]"),
            Some(7),
            "quaternion",
        ),
        (
            "negative size",
            good_with("size_mm: 40", "size_mm: -40"),
            Some(14),
            "positive number of mm, got -40",
        ),
        (
            "zero default size",
            good_with("default_size_mm: 50", "default_size_mm: 0"),
            Some(11),
            "positive number of mm, got 0",
        ),
        (
            "rule with two matchers",
            good_with("{prefix: \"TOTE-\"", "{prefix: \"TOTE-\", payload: \"X\""),
            Some(14),
            "exactly one of payload, prefix and pattern",
        ),
        (
            "rule without a matcher",
            good_with("{prefix: \"TOTE-\", size_mm: 40}", "{size_mm: 40}"),
            Some(14),
            "needs one of payload, prefix and pattern",
        ),
        (
            "rule without a size",
            good_with("{prefix: \"TOTE-\", size_mm: 40}", "{prefix: \"TOTE-\"}"),
            Some(14),
            "missing field `size_mm`",
        ),
        ("YAML syntax", good_with("  rear:\n", "  rear\n"), None, ""),
        (
            "negative focal length",
            good_with("fx_px: 800", "fx_px: -800"),
            Some(9),
            "fx_px must be positive",
        ),
        (
            "calibration and intrinsics",
            good_with("  rear:\n", "  rear:\n    calibration: rear.yaml\n"),
            Some(8),
            "give calibration or intrinsics, not both",
        ),
        (
            "neither calibration nor intrinsics",
            good_with(
                "    intrinsics: {fx_px: 800, fy_px: 800, cx_px: 320, cy_px: 240}\n",
                "    mount: {translation_mm: [0, 0, 0], quaternion_wxyz: [1, 0, 0, 0]}\n",
            ),
            Some(8),
            "give calibration (a file) or intrinsics",
        ),
        (
            "missing calibration file",
            good_with(
                "    intrinsics: {fx_px: 800, fy_px: 800, cx_px: 320, cy_px: 240}\n",
                "    calibration: calib/no-such-file.yaml\n",
            ),
            Some(9),
            "/sites/calib/no-such-file.yaml does not exist",
        ),
        (
            "wrong number of distortion coefficients",
            good_with("[-0.1, 0.01, 0, 0, 0]", "[-0.1, 0.01, 0, 0]"),
            Some(4),
            "plumb_bob model takes 5 coefficients, got 4",
        ),
        (
            "unknown distortion model",
            good_with("model: plumb_bob", "model: fisheye"),
            Some(4),
            "unknown variant `fisheye`",
        ),
        (
            "mapped code without a size",
            good_with("  default_size_mm: 50\n", "").replace("LOC-0002", "BAY-0002"),
            Some(17),
            "code \"BAY-0002\" has no size",
        ),
    ];
    for (name, text, line, needle) in cases {
        let err = parse(&text).map(|_| ()).expect_err(name);
        assert_eq!(err.file, Path::new("/sites/test-site.yaml"), "{name}");
        if name == "YAML syntax" {
            assert!(err.line.is_some(), "{name}: {err}");
        } else {
            assert_eq!(err.line, line, "{name}: {err}");
        }
        let shown = err.to_string();
        assert!(shown.contains(needle), "{name}: {shown}");
        assert!(
            shown.starts_with("/sites/test-site.yaml:"),
            "{name}: {shown}"
        );
    }
}

#[test]
fn a_calibration_path_is_resolved_against_the_site_file() {
    let dir = temp_dir("resolve");
    let site_path = dir.join("site.yaml");
    std::fs::write(
        &site_path,
        "cameras:\n  front:\n    calibration: nope.yaml\n",
    )
    .expect("written");
    let err = Site::load(&site_path).map(|_| ()).expect_err("missing");
    assert_eq!(
        err.reason,
        Reason::MissingCalibration {
            id: "front".into(),
            path: dir.join("nope.yaml"),
        }
    );
    assert_eq!(err.line, Some(3));
    let err = Site::load(&dir.join("absent.yaml"))
        .map(|_| ())
        .expect_err("no site");
    assert!(matches!(err.reason, Reason::Read(_)), "{err}");
    std::fs::remove_dir_all(dir).ok();
}
