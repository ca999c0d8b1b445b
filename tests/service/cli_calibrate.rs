//! `qrpose calibrate`: rendered photos of a printed code with a known camera in, the camera
//! out (close to the truth), the OpenCV file written by `--out` read back by the site
//! file's reader as the same camera, and a refusal as a problem document with exit code 2.

#[path = "../support/calibration.rs"]
mod calibration;

use qrpose_site::calibration::{CalibrationFormat, parse_calibration};
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_qrpose");

/// A directory of its own for this test, emptied.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-calibrate-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}

#[test]
fn photos_of_a_printed_code_give_the_camera_and_a_file_the_site_reads() {
    let dir = scratch("photos");
    let paths = calibration::photo_files(&dir);
    let out = dir.join("front.yaml");
    let run = Command::new(BIN)
        .arg("calibrate")
        .args(["--marker-size-mm", &calibration::CODE_MM.to_string()])
        .arg("--out")
        .arg(&out)
        .args(&paths)
        .output()
        .expect("qrpose runs");
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let answer: Value = serde_json::from_slice(&run.stdout).expect("JSON on stdout");
    println!(
        "camera {} std {} rms {} px, warnings {}",
        answer["camera"], answer["std"], answer["reprojection_rms_px"], answer["warnings"]
    );
    let truth = calibration::camera();
    let camera = &answer["camera"];
    let got = |key: &str| camera[key].as_f64().expect("a number");
    for (key, want) in [("fx_px", truth.fx()), ("fy_px", truth.fy())] {
        assert!(
            (got(key) / want - 1.0).abs() < 0.002,
            "{key}: {} against {want}",
            got(key)
        );
    }
    for (key, want) in [("cx_px", truth.cx()), ("cy_px", truth.cy())] {
        assert!(
            (got(key) - want).abs() < 1.5,
            "{key}: {} against {want}",
            got(key)
        );
    }
    let k1 = camera["distortion"]["k1"].as_f64().expect("k1");
    assert!((k1 - calibration::LENS[0]).abs() < 0.01, "k1 {k1}");
    let views = answer["views"].as_array().expect("views");
    assert_eq!(views.len(), paths.len());
    assert!(views.iter().all(|v| v["used"] == true), "{views:?}");
    assert_eq!(answer["camera"]["distortion"]["model"], "plumb_bob");
    // The file is the answer's `opencv_yaml`, and the site's reader gets the same camera.
    let text = std::fs::read_to_string(&out).expect("--out written");
    assert_eq!(Some(text.as_str()), answer["opencv_yaml"].as_str());
    let read = parse_calibration(&text).expect("the site reads it");
    assert_eq!(read.format, CalibrationFormat::OpenCv);
    assert_eq!(
        read.image_size_px,
        Some((calibration::SIZE_PX.0, calibration::SIZE_PX.1))
    );
    assert_eq!(
        [
            read.camera.fx(),
            read.camera.fy(),
            read.camera.cx(),
            read.camera.cy()
        ],
        [got("fx_px"), got("fy_px"), got("cx_px"), got("cy_px")]
    );
    let ros = answer["ros_camera_info_yaml"]
        .as_str()
        .expect("the ROS file");
    let read_ros = parse_calibration(ros).expect("the site reads the ROS file");
    assert_eq!(read_ros.camera, read.camera);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn two_photos_are_refused_with_a_problem_and_exit_code_2() {
    let dir = scratch("two");
    // The count is checked before any photo is read.
    let paths: Vec<PathBuf> = (0..2)
        .map(|k| {
            let path = dir.join(format!("view_{k}.jpg"));
            std::fs::write(&path, b"not read").expect("writes a file");
            path
        })
        .collect();
    let run = Command::new(BIN)
        .args(["calibrate", "--marker-size-mm", "100"])
        .args(&paths)
        .output()
        .expect("qrpose runs");
    assert_eq!(run.status.code(), Some(2));
    assert!(run.stdout.is_empty());
    let problem: Value = serde_json::from_slice(&run.stderr).expect("a problem on stderr");
    assert_eq!(problem["code"], "too_few_views");
    assert_eq!(problem["status"], 422);
    let _ = std::fs::remove_dir_all(&dir);
}
