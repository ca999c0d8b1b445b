//! `qrpose track FRAMES…`: the stream's tracker over rendered video
//! frames written by `qrpose render --sequence`, one JSON line per frame, as
//! `GET /v1/stream` answers; bad flags refused with the problem document and exit code 2.

use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

fn qrpose() -> Command {
    Command::new(env!("CARGO_BIN_EXE_qrpose"))
}

/// Four frames of the `still` video, written as JPEG files.
fn frames() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-track-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    let args = ["--sequence", "still", "--frames", "4", "--out"].map(std::ffi::OsStr::new);
    crate::support::render(&[&args[..], &[dir.as_os_str()]].concat());
    dir
}

const CAMERA: [&str; 8] = [
    "--fx-px", "1000", "--fy-px", "1000", "--cx-px", "639.5", "--cy-px", "359.5",
];

#[test]
fn a_directory_of_frames_gives_one_answer_per_frame_with_stable_tracks() {
    // Arrange
    let dir = frames();

    // Act
    let out = qrpose()
        .arg("track")
        .arg(&dir)
        .args(CAMERA)
        .args(["--marker-size-mm", "50", "--coast-ms", "800"])
        .output()
        .expect("runs");

    // Assert
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    assert_eq!(lines.len(), 4, "one line per frame");
    let mut first_ids: Vec<String> = Vec::new();
    for (k, line) in lines.iter().enumerate() {
        assert_eq!(line["frame"]["index"], k);
        let expected_ms = k as f64 * 1000.0 / 30.0;
        let t = line["frame"]["capture_time_ms"].as_f64().expect("a time");
        assert!((t - expected_ms).abs() < 1e-9, "{t} vs {expected_ms}");
        let mut ids: Vec<String> = line["tracks"]
            .as_array()
            .expect("tracks")
            .iter()
            .map(|t| t["id"].as_str().expect("an id").to_owned())
            .collect();
        ids.sort();
        assert!(ids.len() >= 3, "frame {k}: {ids:?}");
        if k == 0 {
            first_ids = ids;
        } else {
            assert_eq!(ids, first_ids, "the same tracks in frame {k}");
        }
    }
    let last = lines.last().expect("a line");
    assert!(
        last["tracks"]
            .as_array()
            .expect("tracks")
            .iter()
            .any(|t| t["status"] == "tracking"),
        "{last}"
    );
}

#[test]
fn a_bad_tracker_flag_is_refused_with_its_problem() {
    let dir = frames();
    let out = qrpose()
        .arg("track")
        .arg(&dir)
        .args(CAMERA)
        .args(["--marker-size-mm", "50", "--coast-ms", "-1"])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let problem: Value = serde_json::from_slice(&out.stderr).expect("a problem document");
    assert_eq!(problem["code"], "invalid_tracker_parameter");
    assert_eq!(problem["field"], "coast_ms");
}
