//! The setup page's hand-eye tab in headless Chromium: eight rendered photos of a printed
//! 100 mm code taken by a camera on the flange with a known mount
//! (`tests/support/hand_eye.rs`) are chosen, and the flange pose of each is pasted as KUKA's
//! A, B, C lines. Pasting one pose too few is refused in the page, with nothing sent; then
//! the page must show the camera's pose within 1.5 mm and 0.2° of the truth, its numbers the
//! answer's, a row per photo, the answer's warnings and its `site_mount`; and a server's
//! refusal shows its title, detail, code and field.

use super::support::{Server, client, scratch_dir};
use super::webdriver::Browser;
use super::{DESKTOP, assert_fits_a_phone, lock, maybe_write_screenshot, open_page, severe};
use nalgebra::Isometry3;
use serde_json::{Value, json};
use std::path::PathBuf;

#[path = "../support/hand_eye.rs"]
mod session;

use session::Setup;

/// Largest distance of the shown camera position from the true mount's, mm.
const TRANSLATION_TOL_MM: f64 = 1.5;
/// Largest angle between the shown camera rotation and the true mount's, degrees.
const ROTATION_TOL_DEG: f64 = 0.2;

/// The session's photos as files, in order.
fn photo_files(views: &[Isometry3<f64>]) -> Vec<PathBuf> {
    let dir = scratch_dir("browser-hand-eye");
    session::photos(views)
        .iter()
        .enumerate()
        .map(|(k, jpeg)| {
            let path = dir.join(format!("photo-{k:03}.jpg"));
            std::fs::write(&path, jpeg).expect("the photo is written");
            path
        })
        .collect()
}

/// A flange pose as a KUKA controller shows it: `X, Y, Z, A, B, C`, in brackets.
fn kuka_line(pose: &Isometry3<f64>) -> String {
    let wire = session::euler_zyx_json(pose);
    let numbers: Vec<String> = ["translation_mm", "euler_zyx_deg"]
        .iter()
        .flat_map(|key| {
            wire[key]
                .as_array()
                .expect("three numbers")
                .iter()
                .map(|v| v.as_f64().expect("a number").to_string())
                .collect::<Vec<_>>()
        })
        .collect();
    format!("[{}]", numbers.join(", "))
}

/// Sets the form's inputs by id (and tells the page, as typing would).
fn set_values(browser: &Browser, values: &Value) {
    browser.run(
        "for (const [id, value] of Object.entries(arguments[0])) {
           const input = document.getElementById(id);
           input.value = value;
           input.dispatchEvent(new Event('input', {bubbles: true}));
         }",
        std::slice::from_ref(values),
    );
}

/// Replaces the pasted poses with `lines`.
fn paste_poses(browser: &Browser, lines: &[String]) {
    set_values(browser, &json!({"he-poses": lines.join("\n")}));
}

fn shown_error(browser: &Browser) -> Value {
    browser.wait_for(
        "the error is shown",
        "const e = document.getElementById('he-error');
         return !e.hidden && {title: document.getElementById('he-error-title').textContent,
                              detail: document.getElementById('he-error-detail').textContent,
                              meta: document.getElementById('he-error-meta').textContent};",
    )
}

/// The numbers of the camera's pose list: `{field: value}`.
fn shown_pose(browser: &Browser) -> Value {
    browser.run(
        "const out = {};
         for (const n of document.querySelectorAll('#he-camera-pose [data-field]'))
           out[n.dataset.field] = n.dataset.value === undefined ? n.textContent : Number(n.dataset.value);
         return out;",
        &[],
    )
}

fn hand_eye_requests(browser: &Browser) -> usize {
    browser
        .run(
            "return performance.getEntriesByType('resource')
               .filter(e => e.name.endsWith('/v1/calibrate/hand-eye')).length;",
            &[],
        )
        .as_u64()
        .and_then(|n| usize::try_from(n).ok())
        .expect("a count")
}

/// `POST /v1/calibrate/hand-eye` of `files` with `request`, as the page sends it.
fn api_problem(server: &Server, files: &[PathBuf], request: &Value) -> Value {
    let mut form = reqwest::blocking::multipart::Form::new().part(
        "request",
        reqwest::blocking::multipart::Part::text(request.to_string())
            .mime_str("application/json")
            .expect("a media type"),
    );
    for file in files {
        form = form.part(
            "image",
            reqwest::blocking::multipart::Part::bytes(std::fs::read(file).expect("the photo"))
                .file_name("photo.jpg")
                .mime_str("image/jpeg")
                .expect("a media type"),
        );
    }
    let response = client()
        .post(server.url("/v1/calibrate/hand-eye"))
        .multipart(form)
        .send()
        .expect("the server answers");
    assert_eq!(response.status(), 422);
    response.json().expect("a problem")
}

#[test]
fn photos_and_pasted_robot_poses_show_the_mount_near_the_truth_and_its_site_snippet() {
    let _one = lock();
    let server = Server::start();
    let views = session::views();
    let files = photo_files(&views);
    let flange = session::flange_poses(Setup::EyeInHand, &views);
    let lines: Vec<String> = flange.iter().map(kuka_line).collect();
    let browser = Browser::start(DESKTOP.0, DESKTOP.1);
    open_page(&browser, &server);
    browser.wait_for(
        "the hand-eye script ran",
        "return document.body.dataset.handEyeReady === 'true';",
    );
    browser.click(&browser.find("#tab-hand-eye"));
    assert_eq!(
        browser.run(
            "return [document.getElementById('hand-eye-panel').hidden,
                     document.getElementById('pose-panel').hidden];",
            &[]
        ),
        json!([false, true])
    );

    let paths: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
    browser.type_into(&browser.find("#he-photos"), &paths.join("\n"));
    let camera = session::camera_json();
    set_values(
        &browser,
        &json!({"he-pose-form": "euler_zyx_deg", "he-size-mm": session::CODE_MM,
                "he-fx-px": camera["fx_px"], "he-fy-px": camera["fy_px"],
                "he-cx-px": camera["cx_px"], "he-cy-px": camera["cy_px"],
                "he-k1": camera["distortion"]["k1"], "he-k2": camera["distortion"]["k2"]}),
    );

    // One pose too few: the page says so and sends nothing.
    paste_poses(&browser, &lines[..lines.len() - 1]);
    let status = browser.run(
        "const s = document.getElementById('he-poses-status');
         return {count: s.dataset.count, flagged: s.classList.contains('flag-yes'), text: s.textContent};",
        &[],
    );
    assert_eq!(status["count"], json!((lines.len() - 1).to_string()));
    assert_eq!(status["flagged"], true, "{status}");
    browser.click(&browser.find("#he-send"));
    let refused = shown_error(&browser);
    assert_eq!(refused["title"], "Robot poses");
    let expected = format!(
        "{} poses are pasted for {} photos",
        lines.len() - 1,
        files.len()
    );
    assert!(
        refused["detail"]
            .as_str()
            .is_some_and(|d| d.starts_with(&expected)),
        "{refused}"
    );
    assert_eq!(refused["meta"], "nothing was sent");
    // A line that is not a pose is named.
    let mut garbled = lines.clone();
    garbled[2] = "412.5, -120, 380.2, 10, 20".to_owned();
    paste_poses(&browser, &garbled);
    browser.click(&browser.find("#he-send"));
    let refused = browser.wait_for(
        "the line is named",
        "const d = document.getElementById('he-error-detail').textContent;
         return d.startsWith('Line 3') && d;",
    );
    assert!(
        refused
            .as_str()
            .is_some_and(|d| d.contains("5 numbers") && d.contains("x y z a b c")),
        "{refused}"
    );
    assert_eq!(hand_eye_requests(&browser), 0, "a request was sent");

    // Every pose: the mount.
    paste_poses(&browser, &lines);
    browser.click(&browser.find("#he-send"));
    browser.wait_for(
        "the answer is shown",
        "return !document.getElementById('he-results').hidden
             && document.getElementById('he-error').hidden;",
    );
    let answer: Value = serde_json::from_str(
        browser
            .run(
                "return document.getElementById('he-json').textContent;",
                &[],
            )
            .as_str()
            .expect("the raw JSON"),
    )
    .expect("the raw JSON parses");
    let shown = shown_pose(&browser);
    let number = |field: &str| {
        shown[field]
            .as_f64()
            .unwrap_or_else(|| panic!("no {field}: {shown}"))
    };
    let translation = ["x", "y", "z"].map(|a| number(&format!("camera_pose.translation_mm.{a}")));
    let rotation =
        ["w", "x", "y", "z"].map(|a| number(&format!("camera_pose.quaternion_wxyz.{a}")));
    let page_pose = json!({"translation_mm": translation, "quaternion_wxyz": rotation});
    let (rotation_deg, translation_mm) =
        session::pose_error(&page_pose, &session::camera_pose(Setup::EyeInHand));
    assert!(
        rotation_deg < ROTATION_TOL_DEG && translation_mm < TRANSLATION_TOL_MM,
        "the page's mount is {rotation_deg}° and {translation_mm} mm off the truth: {page_pose}"
    );
    assert_eq!(
        page_pose["translation_mm"], answer["camera_pose"]["translation_mm"],
        "the page shows the answer's numbers"
    );
    assert_eq!(
        page_pose["quaternion_wxyz"],
        answer["camera_pose"]["quaternion_wxyz"]
    );
    assert_eq!(shown["camera_pose.parent"], "flange frame");
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        let sigma = number(&format!("std.translation_mm.{axis}"));
        assert_eq!(Some(sigma), answer["std"]["translation_mm"][k].as_f64());
        assert!(
            sigma > 0.0 && sigma < TRANSLATION_TOL_MM,
            "σ {axis} {sigma}"
        );
        let sigma = number(&format!("std.rotation_deg.{axis}"));
        assert_eq!(Some(sigma), answer["std"]["rotation_deg"][k].as_f64());
    }
    assert_eq!(
        Some(number("reprojection_rms_px")),
        answer["reprojection_rms_px"].as_f64()
    );

    // The site file's mount, as the answer gives it.
    let mount = browser.run(
        "return document.getElementById('he-site-mount').textContent;",
        &[],
    );
    assert_eq!(mount, answer["site_mount"]);
    assert!(
        mount
            .as_str()
            .is_some_and(|m| m.contains("parent: flange") && m.contains("std:")),
        "{mount}"
    );

    // A row per photo, and the answer's warnings.
    let rows = browser.run(
        "return [...document.querySelectorAll('#he-views tbody tr')].map(r =>
           ({index: Number(r.dataset.viewIndex), used: r.dataset.used === 'true',
             file: r.children[1].textContent,
             points: Number(r.querySelector('[data-field=\"points\"]').textContent)}));",
        &[],
    );
    let expected_rows: Vec<Value> = answer["views"]
        .as_array()
        .expect("views")
        .iter()
        .zip(&files)
        .map(|(view, file)| {
            json!({"index": view["index"], "used": view["used"], "points": view["points"],
                   "file": file.file_name().and_then(|n| n.to_str()).expect("a name")})
        })
        .collect();
    assert_eq!(rows, json!(expected_rows));
    assert_eq!(rows.as_array().map(Vec::len), Some(files.len()));
    let warnings = browser.run(
        "return [...document.querySelectorAll('#he-warnings li[data-code]')].map(l => l.dataset.code);",
        &[],
    );
    assert_eq!(warnings, answer["warnings"]);
    assert_eq!(hand_eye_requests(&browser), 1);
    assert_eq!(severe(&browser.log()), Vec::<&(String, String)>::new());
    browser.run("window.scrollTo(0, 0);", &[]);
    maybe_write_screenshot("hand-eye-tab-desktop.png", &browser.screenshot(), DESKTOP);

    // A camera the server does not know: its refusal, with its code and field.
    browser.click(&browser.find("#he-camera-mode-id"));
    set_values(&browser, &json!({"he-camera-id": "wrist"}));
    let request = json!({"setup": "eye_in_hand", "camera": {"id": "wrist"},
                         "marker": {"size_mm": session::CODE_MM},
                         "flange_poses": flange.iter().map(session::euler_zyx_json).collect::<Vec<_>>()});
    let problem = api_problem(&server, &files, &request);
    browser.click(&browser.find("#he-send"));
    let shown = browser.wait_for(
        "the server's refusal is shown",
        "const e = document.getElementById('he-error');
         const meta = document.getElementById('he-error-meta').textContent;
         return !e.hidden && meta.includes('HTTP 422') && {
           title: document.getElementById('he-error-title').textContent,
           detail: document.getElementById('he-error-detail').textContent, meta};",
    );
    assert_eq!(shown["title"], problem["title"]);
    assert_eq!(shown["detail"], problem["detail"]);
    let meta = shown["meta"].as_str().expect("text");
    let code = problem["code"].as_str().expect("a code");
    let field = problem["field"].as_str().expect("a field");
    assert!(
        meta.contains(&format!("code: {code}")) && meta.contains(&format!("field: {field}")),
        "{meta} (the API: {problem})"
    );
    for (_, message) in severe(&browser.log()) {
        assert!(
            message.contains("/v1/calibrate/hand-eye") && message.contains("422"),
            "a console error: {message}"
        );
    }

    // At phone width nothing sticks out sideways.
    assert_fits_a_phone(&browser, "the hand-eye tab");
}
