//! Site files from the command line: `qrpose site check`, `qrpose serve --site` refusing a
//! bad file at start, and `qrpose estimate --site … --camera-id …` on the README's worked
//! example (`tests/fixtures/site/`).

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_qrpose");
const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/site");

fn run(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().expect("qrpose runs")
}

fn fixture(name: &str) -> String {
    Path::new(FIXTURES).join(name).display().to_string()
}

fn stdout_json(out: &Output) -> Value {
    assert!(
        out.status.success(),
        "exit {:?}, stderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// A directory of its own with a copy of the fixture site, `from` replaced by `to` in
/// `warehouse.yaml`; its path.
fn site_copy(name: &str, from: &str, to: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-site-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    for file in ["front-opencv.yaml", "rear-camera-info.yaml"] {
        std::fs::copy(Path::new(FIXTURES).join(file), dir.join(file)).expect("copied");
    }
    let text = std::fs::read_to_string(fixture("warehouse.yaml")).expect("read");
    assert!(text.contains(from), "{from}");
    let path = dir.join("warehouse.yaml");
    std::fs::write(&path, text.replacen(from, to, 1)).expect("written");
    path
}

#[test]
fn site_check_prints_what_the_file_resolves_to() {
    let v = stdout_json(&run(&["site", "check", &fixture("warehouse.yaml")]));
    let bytes = std::fs::read(fixture("warehouse.yaml")).expect("read");
    assert_eq!(v["sha256"], qrpose_site::site::sha256_hex(&bytes));
    assert_eq!(v["cameras"]["front"]["calibration"]["format"], "opencv");
    assert_eq!(v["cameras"]["front"]["camera"]["fx_px"], 1000.0);
    assert_eq!(v["cameras"]["rear"]["camera"]["distortion"]["k1"], -0.04);
    assert_eq!(v["markers"]["default_size_mm"], 50.0);
    assert_eq!(v["map"].as_array().map(Vec::len), Some(2));
}

#[test]
fn site_check_refuses_a_bad_file_with_exit_2_and_file_line_reason() {
    let cases = [
        (
            "unknown key",
            "  sizes:",
            "  size:",
            17,
            "unknown field `size`",
        ),
        (
            "missing calibration",
            "calibration: rear-camera-info.yaml",
            "calibration: gone.yaml",
            11,
            "does not exist",
        ),
        (
            "zero quaternion",
            "[0.5, -0.5, -0.5, 0.5]",
            "[0, 0, 0, 0]",
            14,
            "is not a rotation",
        ),
    ];
    for (name, from, to, line, reason) in cases {
        let path = site_copy(&name.replace(' ', "-"), from, to);
        let out = run(&["site", "check", &path.display().to_string()]);
        assert_eq!(out.status.code(), Some(2), "{name}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        let location = format!("{}:{line}:", path.display());
        assert!(stderr.contains(&location), "{name}: {stderr}");
        assert!(stderr.contains(reason), "{name}: {stderr}");
        assert!(out.stdout.is_empty(), "{name}");
    }
}

#[test]
fn serve_refuses_a_bad_site_at_start_with_exit_2() {
    let path = site_copy("serve", "default_size_mm: 50", "default_size_mm: -50");
    let out = run(&[
        "serve",
        "--addr",
        "127.0.0.1:0",
        "--site",
        &path.display().to_string(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!("{}:16:", path.display())) && stderr.contains("positive"),
        "{stderr}"
    );
    assert!(!String::from_utf8_lossy(&out.stdout).contains("listening"));
}

#[test]
fn estimate_with_a_site_and_a_camera_id_localises_the_robot_of_the_readme() {
    let dir = std::env::temp_dir().join(format!("qrpose-site-cli-photo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    let photo = dir.join("warehouse.jpg").display().to_string();
    let args = ["--scene", &fixture("scene.json"), "--out", &photo];
    crate::support::render(&args.map(std::ffi::OsStr::new));
    let v = stdout_json(&run(&[
        "estimate",
        "--site",
        &fixture("warehouse.yaml"),
        "--camera-id",
        "front",
        "--image",
        &photo,
    ]));
    let sources: Vec<(&str, &str)> = v["markers"]
        .as_array()
        .expect("markers")
        .iter()
        .map(|m| {
            (
                m["payload"].as_str().unwrap_or_default(),
                m["pose"]["marker_size_source"].as_str().unwrap_or_default(),
            )
        })
        .collect();
    assert_eq!(sources.len(), 3, "{sources:?}");
    assert!(sources.contains(&("SKU-1", "site:default")), "{sources:?}");
    assert!(
        sources.contains(&("LOC-0001", "site:pattern")),
        "{sources:?}"
    );
    let robot = &v["localization"]["robot_pose_in_world"];
    let p = &robot["position_mm"];
    let off_mm = ((p["x"].as_f64().unwrap_or(0.0) - 12000.0).powi(2)
        + (p["y"].as_f64().unwrap_or(0.0) - 4500.0).powi(2)
        + p["z"].as_f64().unwrap_or(1e9).powi(2))
    .sqrt();
    let heading = robot["rotation"]["euler_xyz_deg"]["gamma"]
        .as_f64()
        .unwrap_or(0.0);
    assert!(off_mm < 5.0, "robot {off_mm} mm off: {robot}");
    assert!((heading - 90.0).abs() < 0.3, "heading {heading}°");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn estimate_with_an_unknown_camera_id_is_refused_with_exit_2() {
    let out = run(&[
        "estimate",
        "--site",
        &fixture("warehouse.yaml"),
        "--camera-id",
        "roof",
        "--image",
        &fixture("front-opencv.yaml"),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let problem: Value = serde_json::from_slice(&out.stderr).expect("a problem on stderr");
    assert_eq!(problem["code"], "unknown_camera");
    assert_eq!(problem["field"], "camera_id");
}

/// Polls `url` until `done` holds for its body, for at most ten seconds.
fn poll_until(url: &str, done: impl Fn(&str) -> bool) -> String {
    crate::support::tls_provider();
    let client = reqwest::blocking::Client::builder()
        .no_proxy()
        .build()
        .expect("a client");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    loop {
        let body = client
            .get(url)
            .send()
            .and_then(reqwest::blocking::Response::text)
            .unwrap_or_default();
        if done(&body) || std::time::Instant::now() > deadline {
            return body;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

#[test]
fn serve_reloads_the_site_on_sighup_and_keeps_it_when_the_new_file_is_bad() {
    use std::io::BufRead;
    let path = site_copy("sighup", "default_size_mm: 50", "default_size_mm: 50");
    let mut child = Command::new(BIN)
        .args(["serve", "--addr", "127.0.0.1:0", "--site"])
        .arg(&path)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("qrpose serve starts");
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("the listening line");
    let base = line.trim().trim_start_matches("listening on ").to_owned();
    let hup = || {
        let status = Command::new("kill")
            .args(["-HUP", &child.id().to_string()])
            .status()
            .expect("kill runs");
        assert!(status.success());
    };
    let good = std::fs::read_to_string(&path).expect("read");
    std::fs::write(
        &path,
        good.replace("default_size_mm: 50", "default_size_mm: 55"),
    )
    .expect("w");
    hup();
    let site = poll_until(&format!("{base}/v1/site"), |b| {
        b.contains("\"default_size_mm\":55.0")
    });
    assert!(site.contains("\"default_size_mm\":55.0"), "{site}");
    std::fs::write(
        &path,
        good.replace("default_size_mm: 50", "default_size_mm: -1"),
    )
    .expect("w");
    hup();
    let failed = "qrpose_site_reloads_total{outcome=\"failed\"} 1";
    let metrics = poll_until(&format!("{base}/metrics"), |b| b.contains(failed));
    assert!(metrics.contains(failed), "{metrics}");
    let site = poll_until(&format!("{base}/v1/site"), |_| true);
    assert!(
        site.contains("\"default_size_mm\":55.0"),
        "the old site stays: {site}"
    );
    child.kill().expect("stopped");
    child.wait().expect("reaped");
}

#[test]
fn estimate_of_a_corners_request_by_camera_id_matches_the_same_request_with_intrinsics() {
    let plain = stdout_json(&run(&[
        "estimate",
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/fixtures/corners_request.json"
        ),
    ]));
    let dir = std::env::temp_dir().join(format!("qrpose-site-cli-corners-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    let request = dir.join("request.json");
    let body = serde_json::json!({
        "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
        "camera": {"id": "front"},
        "payload": "SKU-1"
    });
    std::fs::write(&request, body.to_string()).expect("written");
    let by_id = stdout_json(&run(&[
        "estimate",
        "--site",
        &fixture("warehouse.yaml"),
        &request.display().to_string(),
    ]));
    assert_eq!(by_id["position_mm"], plain["position_mm"]);
    assert_eq!(by_id["marker_size_source"], "site:default");
    assert!(by_id["pose_in_robot"].is_object() && plain["pose_in_robot"].is_null());
    std::fs::remove_dir_all(dir).ok();
}

/// A refused auth file or TLS file stops `qrpose serve` before it listens, exit 2, naming
/// the file: each is loaded and validated once, into the state the server then runs on.
#[test]
fn serve_refuses_a_bad_auth_or_tls_file_at_start_with_exit_2() {
    let dir = std::env::temp_dir().join(format!("qrpose-serve-files-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    let auth = dir.join("auth.yaml");
    std::fs::write(&auth, "clients: [").expect("written");
    let cert = dir.join("cert.pem");
    std::fs::write(&cert, "not a certificate").expect("written");
    let (auth, cert) = (auth.display().to_string(), cert.display().to_string());
    for flags in [
        vec!["--auth-file", auth.as_str()],
        vec!["--tls-cert", cert.as_str(), "--tls-key", cert.as_str()],
    ] {
        let out = run(&[&["serve", "--addr", "127.0.0.1:0"], &flags[..]].concat());
        assert_eq!(out.status.code(), Some(2), "{flags:?}: {out:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(flags[1]), "{flags:?}: {stderr}");
        assert!(!String::from_utf8_lossy(&out.stdout).contains("listening"));
    }
}
