//! `qrpose-sim render --pick-study` and `--pick-scene`: the files a study writes, the site
//! file qrpose reads for it, and a scene file rendered again to the same truth.

use nalgebra::Isometry3;
use qrpose_sim::pick::PoseSpec;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-pick-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn run_json(args: &[&str]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_qrpose-sim"))
        .args(args)
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("json")
}

fn read_json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("written")).expect("json")
}

fn pose(v: &Value) -> Isometry3<f64> {
    serde_json::from_value::<PoseSpec>(v.clone())
        .expect("a pose")
        .to_isometry()
        .expect("rigid")
}

#[test]
fn a_study_writes_photos_truth_scene_and_a_site_file_qrpose_reads() {
    let dir = temp_dir("study");
    let out = dir.to_str().expect("utf-8");
    let summary = run_json(&[
        "render",
        "--pick-study",
        "5",
        "--picks",
        "3",
        "--out",
        out,
        "--supersample",
        "1",
    ]);
    assert_eq!(summary["photos"], 3 + 20);
    assert_eq!(summary["products_in_view"], 3 + 20);
    let truth = read_json(&dir.join("truth.json"));
    let photos = truth["photos"].as_array().expect("photos");
    for photo in photos {
        let image = photo["image"].as_str().expect("a file name");
        assert!(image.ends_with(".jpg"), "{image}");
        assert!(dir.join(image).is_file(), "{image}");
    }
    // The site file: the wrist camera on the flange, and each product's rule with the
    // grasps the truth gives.
    let site = qrpose_site::Site::load(&dir.join("site.yaml")).expect("qrpose reads it");
    let wrist = site.camera("wrist").expect("the camera");
    assert_eq!(
        wrist.camera_mount.map(|m| m.parent),
        Some(qrpose_site::MountParent::Flange)
    );
    let scene = read_json(&dir.join("scene.json"));
    for (product, spec) in scene["products"]
        .as_array()
        .expect("products")
        .iter()
        .enumerate()
    {
        let payload = spec["payload"].as_str().expect("payload");
        let (_, rule) = site.object_for(payload).expect("a rule");
        let marker = pose(&spec["marker_in_object"]);
        let t = rule.marker_in_object.translation_mm - marker.translation.vector;
        assert!(t.norm() < 1e-9, "product {product}");
        assert_eq!(
            site.sizes().lookup(Some(payload)).map(|s| s.size_mm),
            spec["code_size_mm"].as_f64()
        );
        for (g, grasp) in rule
            .grasps
            .iter()
            .zip(spec["grasps"].as_array().expect("grasps"))
        {
            assert_eq!(g.name, grasp["name"].as_str().expect("name"));
            let d = g.grasp_in_object.translation_mm - pose(&grasp["pose"]).translation.vector;
            assert!(d.norm() < 1e-9, "{}", g.name);
        }
    }
    // The scene file renders again to the same truth.
    let again = dir.join("again");
    run_json(&[
        "render",
        "--pick-scene",
        dir.join("scene.json").to_str().expect("utf-8"),
        "--out",
        again.to_str().expect("utf-8"),
        "--supersample",
        "1",
    ]);
    // The same truth, to the rounding of the scene file's numbers.
    let again = read_json(&again.join("truth.json"));
    let again = again["photos"].as_array().expect("photos");
    assert_eq!(again.len(), photos.len());
    for (a, b) in again.iter().zip(photos) {
        assert_eq!(a["label"], b["label"]);
        let corners = |p: &Value| -> Vec<f64> {
            p["products"][0]["code"]["corners_px"]
                .as_array()
                .expect("corners")
                .iter()
                .flat_map(|c| {
                    c.as_array()
                        .expect("uv")
                        .iter()
                        .map(|x| x.as_f64().expect("px"))
                })
                .collect()
        };
        let (ca, cb) = (corners(a), corners(b));
        assert_eq!(ca.len(), 8);
        let worst = ca
            .iter()
            .zip(&cb)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{}: {worst} px", a["label"]);
    }
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn the_pick_flags_do_not_mix_with_a_single_code() {
    let out = Command::new(env!("CARGO_BIN_EXE_qrpose-sim"))
        .args([
            "render",
            "--pick-study",
            "1",
            "--out",
            "x",
            "--payload",
            "A",
        ])
        .output()
        .expect("runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot be used with"));
}
