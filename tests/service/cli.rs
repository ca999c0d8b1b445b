//! The `qrpose` binary's `estimate` command, run as a user would.

use serde_json::Value;
use std::io::Write;
use std::process::{Command, Output, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_qrpose");
const FIXTURE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/corners_request.json"
);

fn run(args: &[&str], stdin: Option<&str>) -> Output {
    let mut child = Command::new(BIN)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("qrpose starts");
    if let Some(input) = stdin {
        child
            .stdin
            .take()
            .expect("stdin")
            .write_all(input.as_bytes())
            .expect("write stdin");
    }
    drop(child.stdin.take());
    child.wait_with_output().expect("qrpose finishes")
}

fn json(bytes: &[u8]) -> Value {
    serde_json::from_slice(bytes)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(bytes)))
}

#[test]
fn estimate_prints_the_pose_of_a_request_file() {
    let out = run(&["estimate", FIXTURE], None);
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json(&out.stdout);
    let z = v["position_mm"]["z"].as_f64().expect("position z");
    assert!(
        (z - 498.0).abs() < 5.0,
        "a 100 px wide 50 mm code at f = 1000 px is ~500 mm away, got {z}"
    );
    assert_eq!(v["diagnostics"]["method"], "reprojection");
    assert_eq!(v["corners_mm"][2]["qr_corner"], "top_left");
    assert_eq!(v["rotation"]["matrix"].as_array().map(Vec::len), Some(3));
}

#[test]
fn estimate_reads_standard_input_and_gives_the_same_pose() {
    let body = std::fs::read_to_string(FIXTURE).expect("fixture");
    let from_stdin = json(&run(&["estimate", "-"], Some(&body)).stdout);
    let from_file = json(&run(&["estimate", FIXTURE], None).stdout);
    assert_eq!(from_stdin["position_mm"], from_file["position_mm"]);
    assert_eq!(from_stdin["rotation"], from_file["rotation"]);
}

#[test]
fn estimate_refuses_bad_input_with_a_problem_document_and_exit_code_2() {
    let cases = [
        ("{", "malformed_json", None),
        (
            r#"{"corners_px": [[1,1],[2,1],[2,2]], "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 0, "cy_px": 0}, "marker": {"size_mm": 50}}"#,
            "corner_count",
            Some("/corners_px"),
        ),
        (
            r#"{"corners_px": [[1,1],[2,1],[2,2],[1,2]], "camera": {"fx_px": 0, "fy_px": 1000, "cx_px": 0, "cy_px": 0}, "marker": {"size_mm": 50}}"#,
            "invalid_camera_parameter",
            Some("/camera/fx_px"),
        ),
    ];
    for (body, code, field) in cases {
        let out = run(&["estimate", "-"], Some(body));
        assert_eq!(out.status.code(), Some(2), "{body}");
        assert!(out.stdout.is_empty(), "{body}: nothing on stdout");
        let problem = json(&out.stderr);
        assert_eq!(problem["code"], code, "{body}");
        assert_eq!(problem["field"].as_str(), field, "{body}");
        assert_eq!(
            problem["status"].as_u64().map(|s| s / 100),
            Some(4),
            "{body}"
        );
    }
}

#[test]
fn estimate_reports_a_missing_file_as_a_failure() {
    let out = run(&["estimate", "/nonexistent/request.json"], None);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read"));
}

/// Regression: `qrpose estimate … | head -c 10` made `print_json` panic ("failed printing
/// to stdout: Broken pipe", exit 101) once the reader had closed the pipe.
#[test]
fn estimate_stops_quietly_when_the_reader_closes_the_pipe() {
    let body = std::fs::read_to_string(FIXTURE).expect("fixture");
    let mut child = Command::new(BIN)
        .args(["estimate", "-", "--pretty"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("qrpose starts");
    // The reader goes away before qrpose has its input, so the write must meet a closed pipe.
    drop(child.stdout.take());
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(body.as_bytes())
        .expect("write stdin");
    let out = child.wait_with_output().expect("qrpose finishes");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "stderr: {stderr}");
    assert_eq!(out.status.code(), Some(141), "stderr: {stderr}");
}

/// The query parameters of `POST /v1/pose/image` in the committed OpenAPI document.
fn image_query_parameters() -> Vec<String> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/openapi.json");
    let doc = json(&std::fs::read(path).expect("the committed document"));
    let mut names = Vec::new();
    for p in doc["paths"]["/v1/pose/image"]["post"]["parameters"]
        .as_array()
        .expect("parameters")
        .iter()
        .filter(|p| p["in"] == "query")
    {
        match p["schema"]["oneOf"].as_array() {
            // An object parameter (`style: form, explode: true`, the camera): each property
            // of each form is a query parameter of its own.
            Some(forms) => {
                for form in forms {
                    for name in form["properties"].as_object().expect("properties").keys() {
                        if !names.contains(name) {
                            names.push(name.clone());
                        }
                    }
                }
            }
            None => names.push(p["name"].as_str().expect("a name").to_owned()),
        }
    }
    names
}

#[test]
fn every_image_query_parameter_is_a_flag_of_estimate_under_the_same_name() {
    let out = run(&["estimate", "--help"], None);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    let parameters = image_query_parameters();
    assert!(parameters.len() >= 20, "{parameters:?}");
    for name in parameters {
        let flag = format!("--{}", name.replace('_', "-"));
        assert!(
            help.split_whitespace().any(|word| word == flag),
            "{name}: no {flag} in\n{help}"
        );
    }
}

/// Runs `estimate --image` on a file that is never read: flags are refused first.
fn estimate_image_with(flags: &[&str]) -> Output {
    let mut args = vec!["estimate", "--image", "unread.jpg"];
    args.extend_from_slice(flags);
    run(&args, None)
}

#[test]
fn a_bad_flag_is_refused_with_the_query_parameters_problem_naming_the_flag() {
    let cases: [(&[&str], &str, &str); 3] = [
        (&["--fx-px", "wide"], "malformed_query", "fx_px"),
        (&["--method", "newton"], "unknown_variant", "method"),
        (&["--detector", "opencv"], "unknown_variant", "detector"),
    ];
    for (flags, code, field) in cases {
        let out = estimate_image_with(flags);
        assert_eq!(out.status.code(), Some(2), "{flags:?}");
        let problem = json(&out.stderr);
        assert_eq!(problem["code"], code, "{flags:?}: {problem}");
        assert_eq!(problem["field"], field, "{flags:?}: {problem}");
    }
}

#[test]
fn an_out_of_range_flag_names_the_flag_not_a_json_pointer() {
    let dir = std::env::temp_dir().join(format!("qrpose-cli-flags-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let image = dir.join("blank.png");
    let blank = image::GrayImage::from_pixel(32, 32, image::Luma([255]));
    blank.save(&image).expect("png written");
    let path = image.to_str().expect("utf-8 path");
    let cases: [(&[&str], &str, &str); 3] = [
        (&["--fx-px", "-5"], "invalid_camera_parameter", "fx_px"),
        (
            &["--max-iterations", "0"],
            "solver_parameter_out_of_range",
            "max_iterations",
        ),
        (&["--k1", "nan"], "non_finite_number", "k1"),
    ];
    for (flags, code, field) in cases {
        let defaults = [
            ("--fx-px", "900"),
            ("--fy-px", "900"),
            ("--cx-px", "15.5"),
            ("--cy-px", "15.5"),
            ("--marker-size-mm", "40"),
        ];
        let mut args = vec!["estimate", "--image", path];
        for (flag, value) in defaults {
            if !flags.contains(&flag) {
                args.extend([flag, value]);
            }
        }
        args.extend_from_slice(flags);
        let out = run(&args, None);
        assert_eq!(out.status.code(), Some(2), "{flags:?}: {out:?}");
        let problem = json(&out.stderr);
        assert_eq!(problem["code"], code, "{flags:?}: {problem}");
        assert_eq!(problem["field"], field, "{flags:?}: {problem}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `qrpose openapi --auth` and `qrpose asyncapi --auth` print the documents of a server with
/// an auth file (the bearer scheme and each operation's scope); without the flag, a server's
/// without one.
#[test]
fn the_documents_declare_the_bearer_scheme_only_with_auth() {
    for command in ["openapi", "asyncapi"] {
        let open = run(&[command], None);
        let guarded = run(&[command, "--auth"], None);
        assert!(
            open.status.success() && guarded.status.success(),
            "{command}"
        );
        let (open, guarded) = (json(&open.stdout), json(&guarded.stdout));
        assert!(
            open["components"].get("securitySchemes").is_none(),
            "{command}"
        );
        assert_eq!(
            guarded["components"]["securitySchemes"]["bearer"]["scheme"], "bearer",
            "{command}"
        );
    }
}

/// `qrpose render` and `qrpose simulate` run `qrpose-sim` (here `$QRPOSE_SIM`, a script
/// that prints its arguments) with every argument, `--help` included, and exit as it does.
#[test]
fn render_and_simulate_run_qrpose_sim_with_their_arguments() {
    let dir = crate::support::scratch_dir("qrpose-sim-forwarding");
    let script = dir.join("qrpose-sim");
    std::fs::write(&script, "#!/bin/sh\necho \"$@\"\nexit 3\n").expect("write the script");
    std::fs::set_permissions(&script, std::os::unix::fs::PermissionsExt::from_mode(0o755))
        .expect("make it executable");
    for (subcommand, args) in [
        ("render", ["--out", "code.jpg", "--z-mm", "400"].as_slice()),
        ("simulate", ["--method", "paper", "--help"].as_slice()),
    ] {
        let out = Command::new(BIN)
            .arg(subcommand)
            .args(args)
            .env("QRPOSE_SIM", &script)
            .output()
            .expect("qrpose runs");
        assert_eq!(out.status.code(), Some(3), "qrpose-sim's exit code");
        assert_eq!(
            String::from_utf8_lossy(&out.stdout).trim(),
            format!("{subcommand} {}", args.join(" "))
        );
    }
    let missing = Command::new(BIN)
        .args(["render", "--out", "x.jpg"])
        .env("QRPOSE_SIM", dir.join("absent"))
        .output()
        .expect("qrpose runs");
    assert_eq!(missing.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&missing.stderr).contains("cargo build --release -p qrpose-sim"),
        "says how to get it: {}",
        String::from_utf8_lossy(&missing.stderr)
    );
}
