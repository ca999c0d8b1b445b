//! `qrpose render` with several codes: `--random-scene` and `--scene FILE.json` print the
//! ground truth of every code under `codes` and write the image; the single-code flags
//! cannot be mixed with them. `--sequence` writes rendered video (JPEG frames or a `.y4m`
//! file) and one truth line per frame.

use serde_json::{Value, json};
use std::path::PathBuf;
use std::process::Command;

fn qrpose() -> Command {
    Command::new(env!("CARGO_BIN_EXE_qrpose-sim"))
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-render-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn run_json(cmd: &mut Command) -> Value {
    let out = cmd.output().expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("json")
}

fn corners(code: &Value) -> Vec<[f64; 2]> {
    let c = code["truth"]["corners_px"].as_array().expect("corners");
    c.iter()
        .map(|p| [p[0].as_f64().expect("u"), p[1].as_f64().expect("v")])
        .collect()
}

#[test]
fn random_scene_lists_every_code_and_writes_the_image() {
    let dir = temp_dir("random");
    let path = dir.join("scene.png");
    let render = |path: &PathBuf| {
        run_json(
            qrpose()
                .args(["render", "--random-scene", "7", "--noise", "1.5", "--out"])
                .arg(path),
        )
    };
    let truth = render(&path);
    let bytes = std::fs::read(&path).expect("the image exists");
    assert!(bytes.starts_with(b"\x89PNG"), "a PNG");
    assert_eq!(truth["scene"], json!({"random_seed": 7}));
    assert_eq!(truth["image"]["width_px"], json!(1280));
    assert_eq!(truth["image"]["height_px"], json!(720));
    let codes = truth["codes"].as_array().expect("codes");
    assert!((2..=6).contains(&codes.len()), "{} codes", codes.len());
    let mut payloads: Vec<&str> = codes
        .iter()
        .map(|c| c["payload"].as_str().expect("payload"))
        .collect();
    payloads.sort_unstable();
    payloads.dedup();
    assert_eq!(payloads.len(), codes.len(), "distinct payloads");
    for code in codes {
        let size = code["size_mm"].as_f64().expect("size");
        assert!((30.0..=120.0).contains(&size));
        for p in corners(code) {
            assert!(
                p[0] > 0.0 && p[0] < 1279.0 && p[1] > 0.0 && p[1] < 719.0,
                "{p:?}"
            );
        }
        for k in 0..3 {
            let (given, truth) = (&code["position_mm"][k], &code["truth"]["position_mm"][k]);
            let (given, truth) = (given.as_f64().expect("x"), truth.as_f64().expect("x"));
            assert!((given - truth).abs() < 1e-6);
        }
    }
    // The same seed, the same scene.
    let again = render(&dir.join("again.png"));
    assert_eq!(again["codes"], truth["codes"]);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_scene_file_places_each_code_where_it_says() {
    let dir = temp_dir("file");
    let scene = dir.join("scene.json");
    let file = json!({
        "width_px": 800,
        "height_px": 600,
        "camera": {"fx_px": 900, "fy_px": 900},
        "codes": [
            {"payload": "LEFT", "size_mm": 40, "position_mm": [-100, 0, 450],
             "rotation_euler_xyz_deg": {"alpha": 0, "beta": 20, "gamma": 10}},
            {"payload": "RIGHT", "ec_level": "q", "size_mm": 50, "position_mm": [110, 20, 500]}
        ]
    });
    std::fs::write(&scene, file.to_string()).expect("writes the scene");
    let path = dir.join("scene.jpg");
    let truth = run_json(
        qrpose()
            .args(["render", "--jpeg-quality", "85", "--scene"])
            .arg(&scene)
            .arg("--out")
            .arg(&path),
    );
    assert!(
        std::fs::read(&path)
            .expect("the image exists")
            .starts_with(&[0xFF, 0xD8])
    );
    assert_eq!(truth["camera"]["cx_px"], json!(399.5));
    let codes = truth["codes"].as_array().expect("codes");
    assert_eq!(codes.len(), 2);
    assert_eq!(codes[0]["payload"], json!("LEFT"));
    assert_eq!(codes[1]["ec_level"], json!("Q"));
    assert_eq!(
        codes[1]["truth"]["position_mm"],
        json!([110.0, 20.0, 500.0])
    );
    // Fronto-parallel: the right code's corners are an axis-aligned square of 900·50/500 px.
    let c = corners(&codes[1]);
    assert!((c[1][0] - c[0][0] - 90.0).abs() < 1e-6 && (c[3][1] - c[0][1] - 90.0).abs() < 1e-6);
    assert!(
        corners(&codes[0])[1][0] < c[0][0],
        "left code left of the right one"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn scene_flags_refuse_single_code_flags_and_bad_scenes() {
    let dir = temp_dir("refuse");
    let out = dir.join("x.png");
    let status = |args: &[&str]| {
        qrpose()
            .arg("render")
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .expect("runs")
            .status
            .code()
    };
    assert_eq!(status(&["--random-scene", "1", "--payload", "A"]), Some(2));
    assert_eq!(status(&["--random-scene", "1", "--z-mm", "300"]), Some(2));
    let scene = dir.join("scene.json");
    std::fs::write(&scene, r#"{"codes": [{"payload": "A", "size_mm": 40}]}"#).expect("writes");
    let scene = scene.to_str().expect("utf-8 path");
    assert_eq!(status(&["--scene", scene, "--random-scene", "1"]), Some(2));
    let out = qrpose()
        .args(["render", "--scene", scene, "--out"])
        .arg(dir.join("y.png"))
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let problem: Value = serde_json::from_slice(&out.stderr).expect("problem json");
    assert_eq!(problem["code"], json!("missing_field"));
    assert_eq!(problem["field"], json!("/codes/0/position_mm"));
    std::fs::remove_dir_all(&dir).ok();
}

/// A two-code video: 160 × 120, the camera sliding right past the codes in 5 frames.
const SMALL_SEQUENCE: &str = r#"{
  "name": "cli-test", "width_px": 160, "height_px": 120,
  "camera": {"fx_px": 150, "fy_px": 150},
  "fps": 25,
  "codes": [
    {"payload": "ONE", "size_mm": 60, "position_mm": [-60, 0, 500]},
    {"payload": "TWO", "size_mm": 60, "position_mm": [60, 0, 500],
     "rotation_euler_xyz_deg": {"beta": 20}}
  ],
  "trajectory": {"keyframes": [
    {"time_ms": 0, "position_mm": [-40, 0, 0], "look_at_mm": [-40, 0, 500]},
    {"time_ms": 160, "position_mm": [40, 0, 0], "look_at_mm": [40, 0, 500]}
  ]},
  "effects": {"supersample": 2, "noise": 1, "jpeg_quality": 80}
}"#;

fn truth_lines(dir: &std::path::Path) -> Vec<Value> {
    let text = std::fs::read_to_string(dir.join("truth.jsonl")).expect("truth.jsonl");
    text.lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect()
}

#[test]
fn a_sequence_file_writes_jpeg_frames_and_one_truth_line_each() {
    let dir = temp_dir("sequence-jpeg");
    let spec = dir.join("seq.json");
    std::fs::write(&spec, SMALL_SEQUENCE).expect("writes the sequence");
    let out = dir.join("frames");
    let summary = run_json(
        qrpose()
            .args(["render", "--sequence"])
            .arg(&spec)
            .arg("--out")
            .arg(&out),
    );
    assert_eq!(summary["frames"], json!(5), "0-160 ms at 25 fps");
    assert_eq!(summary["sequence"], json!("cli-test"));
    let lines = truth_lines(&out);
    assert_eq!(lines.len(), 5);
    for (k, line) in lines.iter().enumerate() {
        assert_eq!(line["index"], json!(k));
        let t = line["capture_time_ms"].as_f64().expect("time");
        assert!((t - 40.0 * k as f64).abs() < 1e-9, "1000 / 25 ms apart");
        let name = line["image"].as_str().expect("image name");
        assert_eq!(name, format!("frame_{k:05}.jpg"));
        let bytes = std::fs::read(out.join(name)).expect("the frame exists");
        assert!(bytes.starts_with(&[0xFF, 0xD8]), "a JPEG");
        let codes = line["codes"].as_array().expect("codes");
        assert!(!codes.is_empty(), "frame {k} sees a code");
        for c in codes {
            assert!(c["corners_px"].as_array().is_some_and(|a| a.len() == 4));
            assert!(c["side_px"].as_f64().is_some() && c["fully_in_view"].is_boolean());
        }
    }
    // The sequence as rendered loads again and renders the same truth.
    let again = dir.join("again");
    run_json(
        qrpose()
            .args(["render", "--sequence"])
            .arg(out.join("sequence.json"))
            .arg("--out")
            .arg(&again),
    );
    assert_eq!(truth_lines(&again), lines);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_builtin_sequence_writes_a_y4m_video_with_camera_overrides() {
    let dir = temp_dir("sequence-y4m");
    let video = dir.join("still.y4m");
    let summary = run_json(
        qrpose()
            .args([
                "render",
                "--sequence",
                "still",
                "--frames",
                "5",
                "--width-px",
                "320",
            ])
            .args([
                "--height-px",
                "180",
                "--fx-px",
                "250",
                "--fy-px",
                "250",
                "--y4m",
            ])
            .arg(&video)
            .arg("--out")
            .arg(&dir),
    );
    assert_eq!(summary["frames"], json!(5));
    assert_eq!(summary["camera"]["cx_px"], json!(159.5));
    let bytes = std::fs::read(&video).expect("the video exists");
    let header = "YUV4MPEG2 W320 H180 F30:1 Ip A1:1 C420jpeg\n";
    assert!(bytes.starts_with(header.as_bytes()));
    let frame = 320 * 180 * 3 / 2;
    assert_eq!(bytes.len(), header.len() + 5 * (6 + frame));
    for k in 0..5 {
        let at = header.len() + k * (6 + frame);
        assert_eq!(&bytes[at..at + 6], b"FRAME\n");
    }
    let lines = truth_lines(&dir);
    assert_eq!(lines.len(), 5);
    assert!(lines.iter().all(|l| l.get("image").is_none()));
    assert_eq!(lines[0]["codes"].as_array().map(Vec::len), Some(4));
    assert!(!dir.join("frame_00000.jpg").exists());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sequence_flags_refuse_photo_flags_and_unknown_sequences() {
    let dir = temp_dir("sequence-refuse");
    let status = |args: &[&str]| {
        qrpose()
            .arg("render")
            .args(args)
            .arg("--out")
            .arg(&dir)
            .output()
            .expect("runs")
            .status
            .code()
    };
    assert_eq!(status(&["--sequence", "still", "--payload", "A"]), Some(2));
    assert_eq!(
        status(&["--sequence", "still", "--random-scene", "1"]),
        Some(2)
    );
    assert_eq!(
        status(&["--y4m", "x.y4m"]),
        Some(2),
        "--y4m needs --sequence"
    );
    assert_eq!(
        status(&["--frames", "3"]),
        Some(2),
        "--frames needs --sequence"
    );
    assert_eq!(status(&["--sequence", "no-such-sequence"]), Some(1));
    assert_eq!(status(&["--sequence", "still", "--fps", "0"]), Some(2));
    std::fs::remove_dir_all(&dir).ok();
}
