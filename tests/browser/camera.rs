//! The setup page's live camera mode in headless Chromium: a fake camera plays the `still`
//! video rendered by `qrpose render --sequence still --y4m` (Chromium's
//! `--use-fake-device-for-media-stream --use-file-for-fake-video-capture`, the permission
//! prompt answered by `--use-fake-ui-for-media-stream`); "Use camera" must stream it over
//! `GET /v1/stream` within the page's Content-Security-Policy, list every code as a
//! `tracking` track with the numbers of the service's answer, draw each track's filtered pose
//! projected with the intrinsics (checked against the projection computed here and against
//! the render's truth), never let frames queue, and "Stop" must close the session (1000) and
//! the camera. A refused stream must say why in words.

use super::support::{Server, client, scratch_dir};
use super::webdriver::{Browser, ENTER};
use super::{
    DESKTOP, assert_axes_match, assert_fits_a_phone, axes, lock, maybe_write_screenshot, open_page,
    severe,
};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Frames of the rendered video: Chromium loops them, and the camera stands still, so a few
/// are enough (each 1280 × 720 frame takes 1.4 MB and a second or more to render).
const FRAMES: usize = 4;
/// The `still` video's codes, and their sides (mm).
const CODES: [(&str, f64); 4] = [
    ("NEAR-400", 50.0),
    ("MID-700", 80.0),
    ("FAR-1000", 50.0),
    ("FAR-1500", 80.0),
];
/// Frames the page must go on streaming after every code is tracked.
const SUSTAINED_FRAMES: u64 = 20;
/// A site with the `still` video's camera (1280 × 720, f = 1000 px, principal point at the
/// centre) that sizes its codes by their payloads.
const SITE_YAML: &str = "cameras:\n  cam:\n    intrinsics: {fx_px: 1000, fy_px: 1000, \
    cx_px: 639.5, cy_px: 359.5}\nmarkers:\n  default_size_mm: 50\n  sizes:\n    \
    - {prefix: \"MID-\", size_mm: 80}\n    - {prefix: \"FAR-1500\", size_mm: 80}\n";
/// A tracked code's filtered position may be this far from the truth, as a fraction of its
/// distance (a wrong marker size or focal length is off by far more).
const POSITION_TOL: f64 = 0.03;
/// ... and its rotation this far, degrees (a flipped planar pose is off by far more).
const ROTATION_TOL_DEG: f64 = 8.0;
/// The marker side the page draws with (from the answer's reference point) against the
/// site's, mm.
const SIDE_TOL_MM: f64 = 1e-6;

/// `qrpose-sim render --sequence still --y4m`: the video file and the truth of its first frame.
fn still_video() -> (PathBuf, Value) {
    let dir = scratch_dir("browser-camera");
    let y4m = dir.join("still.y4m");
    let out = dir.join("still");
    let frames = FRAMES.to_string();
    let flags = ["--sequence", "still", "--frames", &frames, "--y4m"].map(std::ffi::OsStr::new);
    let paths = [y4m.as_os_str(), "--out".as_ref(), out.as_os_str()];
    super::support::render(&[&flags[..], &paths[..]].concat());
    let truth = std::fs::read_to_string(out.join("truth.jsonl")).expect("truth.jsonl");
    let first = truth.lines().next().expect("a frame's truth");
    (y4m, serde_json::from_str(first).expect("JSON"))
}

fn site_file() -> PathBuf {
    let path = scratch_dir("browser-camera").join("site.yaml");
    std::fs::write(&path, SITE_YAML).expect("a site file");
    path
}

/// Chromium with a fake camera (playing `video`, or its own test pattern) and the camera
/// permission granted.
fn browser_with_fake_camera(video: Option<&Path>) -> Browser {
    let mut switches = vec![
        "--use-fake-device-for-media-stream".to_owned(),
        "--use-fake-ui-for-media-stream".to_owned(),
    ];
    if let Some(video) = video {
        switches.push(format!(
            "--use-file-for-fake-video-capture={}",
            video.display()
        ));
    }
    Browser::start_with(DESKTOP.0, DESKTOP.1, &switches)
}

/// Chooses the site camera `id` and leaves the marker size to the site.
fn choose_site_camera(browser: &Browser, id: &str) {
    browser.click(&browser.find("#camera-mode-id"));
    browser.wait_for(
        "the site's cameras are listed",
        "return document.getElementById('site-status').textContent.includes('camera(s)');",
    );
    browser.type_into(&browser.find("#camera-id"), id);
    browser.run("document.getElementById('marker-size-mm').value = '';", &[]);
}

/// A gauge or counter of `GET /metrics`.
fn metric(server: &Server, name: &str) -> f64 {
    let text = client()
        .get(server.url("/metrics"))
        .send()
        .and_then(reqwest::blocking::Response::text)
        .expect("the metrics");
    text.lines()
        .find_map(|line| line.strip_prefix(name)?.strip_prefix(' ')?.parse().ok())
        .unwrap_or_else(|| panic!("no {name} in the metrics"))
}

fn wait_for_metric(server: &Server, name: &str, value: f64) {
    let started = Instant::now();
    while metric(server, name) != value {
        assert!(
            started.elapsed() < super::webdriver::PATIENCE,
            "{name} never became {value}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The angle between two rotation matrices, degrees.
fn rotation_between_deg(a: &Value, b: &Value) -> f64 {
    let m = |v: &Value, i: usize, j: usize| v[i][j].as_f64().expect("a matrix entry");
    let trace: f64 = (0..3)
        .map(|k| (0..3).map(|i| m(a, i, k) * m(b, i, k)).sum::<f64>())
        .sum();
    ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

fn xyz(v: &Value) -> [f64; 3] {
    if v.is_array() {
        [0, 1, 2].map(|k| v[k].as_f64().expect("a number"))
    } else {
        ["x", "y", "z"].map(|k| v[k].as_f64().expect("a number"))
    }
}

fn matrix(v: &Value) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| v[i][j].as_f64().expect("a matrix entry")))
}

/// One tracked code of the answer the page drew: its numbers in the list are the answer's,
/// its pose is near the truth, and its drawn axes are its filtered pose projected.
fn check_track(shown: &Value, track: &Value, truth: &Value) {
    let id = track["id"].as_str().expect("an id");
    let payload = track["payload"].as_str().expect("a payload");
    let card = &shown["cards"][id];
    assert_eq!(card["payload"], json!(payload), "{id}: {card}");
    assert_eq!(card["status"], json!("tracking"), "{id}: {card}");
    assert_eq!(
        card["ambiguity_resolved"],
        json!(track["ambiguity_resolved"].to_string()),
        "{id}"
    );
    let position = xyz(&track["pose"]["position_mm"]);
    let distance_mm = position.iter().map(|p| p * p).sum::<f64>().sqrt();
    let shown_distance: f64 = card["distance_mm"]
        .as_str()
        .and_then(|v| v.parse().ok())
        .expect("a distance");
    assert!((shown_distance - distance_mm).abs() < 1e-9, "{id}: {card}");

    let code = truth["codes"]
        .as_array()
        .expect("codes")
        .iter()
        .find(|c| c["payload"] == json!(payload))
        .unwrap_or_else(|| panic!("{payload} is not in the video"));
    let true_position = xyz(&code["position_mm"]);
    let off_mm = (0..3)
        .map(|k| (position[k] - true_position[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        off_mm < POSITION_TOL * distance_mm,
        "{payload}: {off_mm:.1} mm from the truth at {distance_mm:.0} mm"
    );
    let off_deg = rotation_between_deg(
        &track["pose"]["rotation"]["matrix"],
        &code["rotation_matrix"],
    );
    assert!(off_deg < ROTATION_TOL_DEG, "{payload}: {off_deg:.1}° off");

    let drawn = shown["drawn"]
        .as_array()
        .expect("drawn tracks")
        .iter()
        .find(|d| d["id"] == json!(id))
        .unwrap_or_else(|| panic!("{id} is not drawn"));
    let side_mm = drawn["side_mm"].as_f64().expect("a side");
    let size_mm = CODES
        .iter()
        .find(|(p, _)| *p == payload)
        .map(|(_, s)| *s)
        .expect("a size");
    assert!((side_mm - size_mm).abs() < SIDE_TOL_MM, "{id}: {side_mm}");
    let expected = axes(
        position,
        matrix(&track["pose"]["rotation"]["matrix"]),
        side_mm,
    );
    assert_axes_match(&drawn["axes"], &expected, id);
}

/// What the page shows after the answer it drew last, read at once: the answer, the overlay's
/// drawn tracks, the list's cards and the counts of frames.
const SHOWN: &str = "
    const overlay = document.getElementById('live-overlay');
    const list = document.getElementById('tracks');
    const cards = {};
    for (const card of list.querySelectorAll('[data-track-id]')) {
      const fields = {};
      for (const node of card.querySelectorAll('[data-field]'))
        fields[node.dataset.field] = node.dataset.value ?? node.textContent;
      cards[card.dataset.trackId] = fields;
    }
    const tracking = Object.values(cards).filter(c => c.status === 'tracking').map(c => c.payload);
    if (tracking.length < arguments[0] || overlay.dataset.frame !== list.dataset.frame) return null;
    return {answer: JSON.parse(document.getElementById('live-json').textContent),
            drawn: JSON.parse(overlay.dataset.tracks), cards,
            stats: {...document.getElementById('live-stats').dataset}};";

#[test]
fn the_live_camera_draws_every_tracked_code_and_stop_closes_the_session() {
    let _one = lock();
    let (video, truth) = still_video();
    let site = site_file();
    let server = Server::start_with(&["--site", &site.display().to_string()]);
    let browser = browser_with_fake_camera(Some(&video));
    open_page(&browser, &server);
    choose_site_camera(&browser, "cam");

    // The keyboard reaches "Use camera" from the camera id field.
    browser.tab_to("camera-start", 10);
    browser.press(ENTER);
    let condition = format!(
        "return (function() {{ {SHOWN} }}).apply(null, [{}]);",
        CODES.len()
    );
    let shown = browser.wait_for("every code of the video is a tracking track", &condition);

    // The list shows every code, each tracking, with the answer's numbers.
    let answer = &shown["answer"];
    let tracks = answer["tracks"].as_array().expect("tracks");
    let mut payloads: Vec<&str> = tracks
        .iter()
        .filter(|t| t["status"] == json!("tracking"))
        .map(|t| t["payload"].as_str().expect("a payload"))
        .collect();
    payloads.sort_unstable();
    let mut expected: Vec<&str> = CODES.iter().map(|(p, _)| *p).collect();
    expected.sort_unstable();
    assert_eq!(payloads, expected, "{answer}");
    for track in tracks.iter().filter(|t| t["status"] == json!("tracking")) {
        check_track(&shown, track, &truth);
    }
    // Frames went one or two at a time: none waited long enough for the service to drop it.
    let stat = |name: &str| -> u64 {
        shown["stats"][name]
            .as_str()
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no {name}: {shown}"))
    };
    assert_eq!(stat("dropped"), 0, "{}", shown["stats"]);
    assert_eq!(stat("problems"), 0, "{}", shown["stats"]);
    assert!(stat("sent") - stat("answered") <= 2, "{}", shown["stats"]);
    let answered = stat("answered");
    println!(
        "live camera: {answered} frames answered before every code was tracking, frame {}",
        answer["frame"]["index"]
    );

    // The overlay has drawn each tracking track's x axis in red.
    let drawn = browser.run(
        "const c = document.getElementById('live-overlay');
         const data = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
         let opaque = 0;
         for (let k = 3; k < data.length; k += 4) if (data[k] > 0) opaque++;
         const reds = JSON.parse(c.dataset.tracks).filter(t => t.status === 'tracking').map(t => {
           const a = t.axes, u = Math.round((a.origin[0] + a.ends[0][0]) / 2),
                 v = Math.round((a.origin[1] + a.ends[0][1]) / 2);
           return [...c.getContext('2d').getImageData(u, v, 1, 1).data];
         });
         return {opaque, reds, width: c.width, height: c.height};",
        &[],
    );
    assert_eq!(
        (drawn["width"].as_u64(), drawn["height"].as_u64()),
        (Some(1280), Some(720))
    );
    assert!(drawn["opaque"].as_u64() > Some(2000), "{drawn}");
    for rgba in drawn["reds"].as_array().expect("pixels") {
        assert!(
            rgba[0].as_u64() > Some(200)
                && rgba[1].as_u64() < Some(60)
                && rgba[2].as_u64() < Some(60)
                && rgba[3].as_u64() > Some(200),
            "the middle of an x axis is {rgba}"
        );
    }
    assert_eq!(metric(&server, "qrpose_stream_sessions_open"), 1.0);

    // Streaming on: still none dropped, never more than two out.
    let steady = browser.wait_for(
        "more frames are answered",
        &format!(
            "const s = document.getElementById('live-stats');
             return Number(s.dataset.answered) >= {} && {{...s.dataset, text: s.textContent}};",
            answered + SUSTAINED_FRAMES
        ),
    );
    println!("live camera: {}", steady["text"]);
    let count = |name: &str| -> u64 {
        steady[name]
            .as_str()
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no {name}: {steady}"))
    };
    assert_eq!((count("dropped"), count("problems")), (0, 0), "{steady}");
    assert!(count("sent") - count("answered") <= 2, "{steady}");
    browser.scroll_to("#live");
    maybe_write_screenshot("setup-page-camera.png", &browser.screenshot(), DESKTOP);
    // At phone width the picture and the track table stay within the page's width.
    assert_fits_a_phone(&browser, "the live page");
    browser.set_viewport(DESKTOP.0, DESKTOP.1, false);

    // Stop: the session closes normally and the camera is released.
    browser.click(&browser.find("#camera-stop"));
    let closed = browser.wait_for(
        "the page says the session closed",
        "const live = document.getElementById('live');
         return live.dataset.state === 'closed' && {code: live.dataset.closeCode,
           text: document.getElementById('live-status').textContent,
           camera: document.getElementById('live-video').srcObject,
           start: document.getElementById('camera-start').disabled};",
    );
    assert_eq!(closed["code"], json!("1000"), "{closed}");
    assert!(
        closed["text"]
            .as_str()
            .is_some_and(|t| t.contains("closed normally")),
        "{closed}"
    );
    assert_eq!(closed["camera"], Value::Null);
    assert_eq!(closed["start"], json!(false));
    wait_for_metric(&server, "qrpose_stream_sessions_open", 0.0);
    assert!(metric(&server, "qrpose_stream_frames_answered_total") >= answered as f64);
    // Within the page's CSP (a violation is a console error), nothing went wrong.
    assert_eq!(severe(&browser.log()), Vec::<&(String, String)>::new());
}

#[test]
fn a_refused_stream_says_why_in_words() {
    let _one = lock();
    let site = site_file();
    let server = Server::start_with(&["--site", &site.display().to_string()]);
    let browser = browser_with_fake_camera(None);
    open_page(&browser, &server);
    choose_site_camera(&browser, "no-such-camera");

    browser.click(&browser.find("#camera-start"));
    let shown = browser.wait_for(
        "the refusal is shown",
        "const live = document.getElementById('live');
         return live.dataset.state === 'refused' && {
           status: document.getElementById('live-status').textContent,
           title: document.getElementById('error-title').textContent,
           meta: document.getElementById('error-meta').textContent,
           camera: document.getElementById('live-video').srcObject};",
    );

    assert!(
        shown["status"]
            .as_str()
            .is_some_and(|s| s.contains("refused") && s.contains("unknown_camera")),
        "{shown}"
    );
    assert_eq!(shown["title"], json!("Unknown camera"));
    assert!(
        shown["meta"]
            .as_str()
            .is_some_and(|m| m.contains("camera_id") && m.contains("422")),
        "{shown}"
    );
    assert_eq!(shown["camera"], Value::Null, "the camera is released");
    // The browser logs the refused upgrade and the 422 it asked for the reason; the page
    // itself logs nothing.
    for (_, message) in severe(&browser.log()) {
        assert!(message.contains("/v1/stream"), "a console error: {message}");
    }
}
