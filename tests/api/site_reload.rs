//! Reloading the site under load: requests keep coming while good and bad site files are
//! reloaded; none fails, and none sees half of one site and half of another.

use crate::helpers::spawn_app_with;
use qrpose::config::Settings;
use reqwest::StatusCode;
use serde_json::{Value, json};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Site A: the front camera at fx = 1000 px, codes 50 mm by default.
const SITE_A: &str = "cameras:
  front:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}
markers:
  default_size_mm: 50
";
/// Site B: the same camera id at fx = 1200 px (another calibration file), codes 60 mm.
const SITE_B: &str = "cameras:
  front:
    calibration: front-b.yaml
markers:
  default_size_mm: 60
";
const CALIBRATION_B: &str = "%YAML:1.0
---
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1200., 0., 639.5, 0., 1200., 359.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
";
/// Refused: a negative default size.
const SITE_BAD: &str = "cameras:
  front:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}
markers:
  default_size_mm: -5
";

/// Replaces `path` atomically, as an operator's deployment should.
fn replace(path: &Path, text: &str) {
    let temporary = path.with_extension("tmp");
    std::fs::write(&temporary, text).expect("written");
    std::fs::rename(&temporary, path).expect("renamed");
}

fn request() -> Value {
    json!({
        "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
        "camera": {"id": "front"}
    })
}

/// (marker size, distance) of an answer.
fn size_and_distance(pose: &Value) -> (f64, f64) {
    (
        pose["marker_size_mm"].as_f64().expect("a size"),
        pose["distance_mm"].as_f64().expect("a distance"),
    )
}

#[tokio::test]
async fn reloads_under_load_never_fail_a_request_nor_mix_two_sites() {
    let dir = std::env::temp_dir().join(format!("qrpose-site-reload-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    std::fs::write(dir.join("front-b.yaml"), CALIBRATION_B).expect("written");
    let site_file = dir.join("site.yaml");
    replace(&site_file, SITE_A);
    let app = Arc::new(
        spawn_app_with(Settings {
            site: Some(site_file.clone()),
            ..Settings::default()
        })
        .await,
    );
    let reload = |app: Arc<crate::helpers::TestApp>| async move {
        app.request(reqwest::Method::POST, "/v1/site/reload")
            .await
            .status()
    };
    let answer_a: Value = app
        .post_corners(&request())
        .await
        .json()
        .await
        .expect("JSON");
    replace(&site_file, SITE_B);
    assert_eq!(reload(Arc::clone(&app)).await, StatusCode::OK);
    let answer_b: Value = app
        .post_corners(&request())
        .await
        .json()
        .await
        .expect("JSON");
    let (a, b) = (size_and_distance(&answer_a), size_and_distance(&answer_b));
    assert!(a.0 != b.0 && (a.1 - b.1).abs() > 1.0, "{a:?} {b:?}");

    let stop = Arc::new(AtomicBool::new(false));
    let clients: Vec<_> = (0..4)
        .map(|_| {
            let (app, stop) = (Arc::clone(&app), Arc::clone(&stop));
            tokio::spawn(async move {
                let mut answered = 0;
                while !stop.load(Ordering::Relaxed) {
                    let response = app.post_corners(&request()).await;
                    assert_eq!(response.status(), StatusCode::OK, "a request failed");
                    let got = size_and_distance(&response.json().await.expect("JSON"));
                    let same = |x: (f64, f64)| x.0 == got.0 && (x.1 - got.1).abs() < 1e-9;
                    assert!(
                        same(a) || same(b),
                        "a mixed site: {got:?}, not {a:?} or {b:?}"
                    );
                    answered += 1;
                }
                answered
            })
        })
        .collect();
    let mut refused = 0;
    for round in 0..30 {
        let (text, good) = match round % 3 {
            0 => (SITE_A, true),
            1 => (SITE_BAD, false),
            _ => (SITE_B, true),
        };
        replace(&site_file, text);
        let status = reload(Arc::clone(&app)).await;
        let expected = if good {
            StatusCode::OK
        } else {
            StatusCode::UNPROCESSABLE_ENTITY
        };
        assert_eq!(status, expected, "round {round}");
        refused += usize::from(!good);
        tokio::time::sleep(std::time::Duration::from_millis(5)).await;
    }
    stop.store(true, Ordering::Relaxed);
    let mut answered = 0;
    for client in clients {
        answered += client.await.expect("a client never fails");
    }
    assert!(answered > 30, "only {answered} requests during the reloads");
    assert_eq!(
        app.state.metrics.site_reload_count(false),
        u64::try_from(refused).expect("small")
    );
    std::fs::remove_dir_all(dir).ok();
}
