//! The setup page's calibration tab in headless Chromium: the arrow keys reach the tab; eight
//! rendered photos of a printed 100 mm code with a known camera (`tests/support/calibration.rs`)
//! are dropped on its drop zone and sent to `POST /v1/calibrate`; the page must show the
//! camera near the render's truth with a standard deviation for each number, one row per
//! photo, every view's points drawn over its photo with their residual vectors at the scale
//! it states (a figure enlarges, another scale redraws them), every used point on the
//! coverage image, and download links whose contents are the answer's OpenCV and ROS files,
//! which the site's reader takes as the same camera; nothing may stick out at phone width.

use super::support::{Server, scratch_dir};
use super::webdriver::Browser;
use super::{DESKTOP, assert_fits_a_phone, lock, maybe_write_screenshot, open_page, severe};
use qrpose_site::calibration::parse_calibration;
use serde_json::{Value, json};
use std::path::PathBuf;

#[path = "../support/calibration.rs"]
mod photos;

/// WebDriver's code for the right arrow key.
const ARROW_RIGHT: &str = "\u{E014}";
/// Largest focal length error the page's numbers may show, fraction (as the API's test).
const FOCAL_TOL: f64 = 0.002;
/// Largest principal point error, px.
const PRINCIPAL_POINT_TOL_PX: f64 = 1.5;

/// Drops `files` on the tab's drop zone: WebDriver cannot drag from the desktop, so a file
/// input of the test's own takes them and a `drop` event carries its files to the zone.
fn drop_files(browser: &Browser, files: &[PathBuf]) {
    browser.run(
        "const input = document.createElement('input');
         input.type = 'file'; input.multiple = true; input.id = 'test-staging';
         document.body.prepend(input);",
        &[],
    );
    let paths: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
    browser.type_into(&browser.find("#test-staging"), &paths.join("\n"));
    browser.run(
        "const input = document.getElementById('test-staging');
         const transfer = new DataTransfer();
         for (const file of input.files) transfer.items.add(file);
         input.remove();
         document.getElementById('calib-drop-zone').dispatchEvent(
           new DragEvent('drop', {bubbles: true, cancelable: true, dataTransfer: transfer}));",
        &[],
    );
}

/// A number the page shows (`data-field`'s `data-value`, and `data-std`).
fn shown(browser: &Browser, field: &str) -> (f64, Option<f64>) {
    let node = browser.run(
        "const n = document.querySelector('#calib-camera [data-field=\"' + arguments[0] + '\"]');
         return n && {value: n.dataset.value, std: n.dataset.std ?? null, text: n.textContent};",
        &[json!(field)],
    );
    let number = |v: &Value| v.as_str().and_then(|s| s.parse::<f64>().ok());
    let value = number(&node["value"]).unwrap_or_else(|| panic!("no {field}: {node}"));
    (value, number(&node["std"]))
}

/// The text a download link holds (its `data:` URL decoded).
fn download(browser: &Browser, id: &str) -> String {
    browser
        .run(
            "const a = document.getElementById(arguments[0]);
             return a.href.startsWith('data:') && a.hasAttribute('download')
               && decodeURIComponent(a.href.slice(a.href.indexOf(',') + 1));",
            &[json!(id)],
        )
        .as_str()
        .unwrap_or_else(|| panic!("{id} is no data: download link"))
        .to_owned()
}

#[test]
fn dropped_photos_of_a_printed_code_show_its_camera_views_residuals_coverage_and_files() {
    let _one = lock();
    let server = Server::start();
    let files = photos::photo_files(&scratch_dir("browser-calibration"));
    let browser = Browser::start(DESKTOP.0, DESKTOP.1);
    open_page(&browser, &server);
    browser.wait_for(
        "the calibration script ran",
        "return document.body.dataset.calibrationReady === 'true';",
    );

    // The arrow key moves from the Pose tab to the Calibration tab and shows its panel.
    browser.run("document.getElementById('tab-pose').focus();", &[]);
    browser.press(ARROW_RIGHT);
    let tabs = browser.run(
        "const t = document.getElementById('tab-calibration');
         return {focused: document.activeElement === t, selected: t.getAttribute('aria-selected'),
                 pose: document.getElementById('pose-panel').hidden,
                 calibration: document.getElementById('calibration-panel').hidden};",
        &[],
    );
    assert_eq!(
        tabs,
        json!({"focused": true, "selected": "true", "pose": true, "calibration": false})
    );

    drop_files(&browser, &files);
    let chosen = browser.run(
        "return [document.getElementById('calib-chosen').dataset.count,
                 document.getElementById('calib-photos').files.length];",
        &[],
    );
    assert_eq!(
        chosen,
        json!([files.len().to_string(), 0]),
        "the drop chose them"
    );
    browser.run(
        "document.getElementById('calib-size-mm').value = arguments[0];",
        &[json!(photos::CODE_MM)],
    );
    browser.click(&browser.find("#calib-send"));
    browser.wait_for(
        "the answer is drawn",
        "return !document.getElementById('calib-results').hidden
             && document.getElementById('calib-coverage').dataset.state === 'drawn';",
    );
    let answer: Value = serde_json::from_str(
        browser
            .run(
                "return document.getElementById('calib-json').textContent;",
                &[],
            )
            .as_str()
            .expect("the raw JSON"),
    )
    .expect("the raw JSON parses");

    // The camera, near the truth, each number with its standard deviation.
    let truth = photos::camera();
    let (fx, fx_std) = shown(&browser, "fx_px");
    let (fy, fy_std) = shown(&browser, "fy_px");
    let (cx, _) = shown(&browser, "cx_px");
    let (cy, _) = shown(&browser, "cy_px");
    assert!((fx / truth.fx() - 1.0).abs() < FOCAL_TOL, "fx {fx}");
    assert!((fy / truth.fy() - 1.0).abs() < FOCAL_TOL, "fy {fy}");
    assert!((cx - truth.cx()).abs() < PRINCIPAL_POINT_TOL_PX, "cx {cx}");
    assert!((cy - truth.cy()).abs() < PRINCIPAL_POINT_TOL_PX, "cy {cy}");
    assert_eq!(Some(fx), answer["camera"]["fx_px"].as_f64());
    assert_eq!(fx_std, answer["std"]["fx_px"].as_f64());
    assert!(fx_std.is_some_and(|s| s > 0.0) && fy_std.is_some_and(|s| s > 0.0));
    for name in ["k1", "k2", "p1", "p2", "k3"] {
        let (value, std) = shown(&browser, &format!("distortion.{name}"));
        assert_eq!(Some(value), answer["camera"]["distortion"][name].as_f64());
        assert!(std.is_some(), "{name} has no standard deviation");
    }
    let (k1, _) = shown(&browser, "distortion.k1");
    assert!((k1 - photos::LENS[0]).abs() < 0.01, "k1 {k1}");

    // A row and a figure per photo, each view's points drawn at the stated residual scale.
    let rows = browser.run(
        "return [...document.querySelectorAll('#calib-views tbody tr')].map(r =>
           ({index: r.dataset.viewIndex, used: r.dataset.used, file: r.children[1].textContent,
             points: r.querySelector('[data-field=\"points\"]').textContent}));",
        &[],
    );
    let rows = rows.as_array().expect("rows");
    assert_eq!(rows.len(), files.len());
    for (k, (row, file)) in rows.iter().zip(&files).enumerate() {
        let name = file.file_name().and_then(|n| n.to_str()).expect("a name");
        let points = answer["views"][k]["points"].as_u64().expect("points");
        assert_eq!(
            row,
            &json!({"index": k.to_string(), "used": "true", "file": name,
                    "points": points.to_string()})
        );
    }
    let figures = browser.run(
        "return [...document.querySelectorAll('#calib-figures canvas')].map(c =>
           ({index: c.dataset.viewIndex, state: c.dataset.state, points: c.dataset.points,
             scale: c.dataset.residualScale, width: c.width}));",
        &[],
    );
    let note = browser.run(
        "const n = document.getElementById('calib-scale-note');
         return {scale: n.dataset.residualScale, text: n.textContent};",
        &[],
    );
    let scale = note["scale"].as_str().expect("a scale");
    assert!(
        note["text"]
            .as_str()
            .is_some_and(|t| t.contains(&format!("drawn {scale} times"))),
        "{note}"
    );
    assert!(scale.parse::<f64>().is_ok_and(|s| s >= 10.0), "{note}");
    for (k, figure) in figures.as_array().expect("figures").iter().enumerate() {
        let points = answer["views"][k]["image_points"]
            .as_array()
            .expect("image_points")
            .len();
        assert_eq!(
            figure,
            &json!({"index": k.to_string(), "state": "drawn", "points": points.to_string(),
                    "scale": scale, "width": photos::SIZE_PX.0}),
        );
    }
    assert_eq!(figures.as_array().map(Vec::len), Some(files.len()));
    assert_inlier_drawn(&browser, &answer["views"][0]);

    // Every used point on the coverage image, with the answer's grid.
    let used_points: u64 = answer["views"]
        .as_array()
        .expect("views")
        .iter()
        .filter(|v| v["used"] == json!(true))
        .map(|v| v["points"].as_u64().expect("points"))
        .sum();
    let coverage = browser.run(
        "return {points: document.getElementById('calib-coverage').dataset.points,
                 covered: document.getElementById('calib-coverage-note').dataset.covered};",
        &[],
    );
    let covered = answer["coverage"]["counts"]
        .as_array()
        .expect("counts")
        .iter()
        .filter(|n| n.as_u64() > Some(0))
        .count();
    assert_eq!(
        coverage,
        json!({"points": used_points.to_string(), "covered": covered.to_string()})
    );

    // The files: the answer's, and the site's reader takes them as the shown camera.
    let opencv = download(&browser, "calib-download-opencv");
    assert!(opencv.starts_with("%YAML:1.0\n---\n"), "{opencv}");
    assert_eq!(Some(opencv.as_str()), answer["opencv_yaml"].as_str());
    let ros = download(&browser, "calib-download-ros");
    assert_eq!(Some(ros.as_str()), answer["ros_camera_info_yaml"].as_str());
    for text in [&opencv, &ros] {
        let read = parse_calibration(text).expect("the site reads it");
        assert_eq!([read.camera.fx(), read.camera.cy()], [fx, cy], "{text}");
    }

    // A figure enlarges to the panel's width.
    let narrow = browser.run(
        "return document.getElementById('calib-view-0').clientWidth;",
        &[],
    );
    browser.click(&browser.find("#calib-figures figure[data-view-index='0'] button"));
    let wide = browser.run(
        "const f = document.querySelector('#calib-figures figure[data-view-index=\"0\"]');
         return f.classList.contains('wide') && document.getElementById('calib-view-0').clientWidth;",
        &[],
    );
    assert!(
        wide.as_f64() > narrow.as_f64().map(|w| 1.5 * w),
        "{narrow} -> {wide}"
    );

    // Another residual scale redraws every view at it.
    browser.run(
        "const s = document.getElementById('calib-scale');
         s.value = '1000'; s.dispatchEvent(new Event('change'));",
        &[],
    );
    let scales = browser.run(
        "return [...document.querySelectorAll('#calib-figures canvas')].map(c => c.dataset.residualScale);",
        &[],
    );
    assert_eq!(scales, json!(vec!["1000"; files.len()]));
    assert_eq!(severe(&browser.log()), Vec::<&(String, String)>::new());

    browser.run(
        "const s = document.getElementById('calib-scale');
         s.value = 'auto'; s.dispatchEvent(new Event('change'));
         window.scrollTo(0, 0);",
        &[],
    );
    maybe_write_screenshot(
        "calibration-tab-desktop.png",
        &browser.screenshot(),
        DESKTOP,
    );

    // At phone width nothing sticks out sideways.
    assert_fits_a_phone(&browser, "the tab");
}

/// The figure of `view` shows, at a full inlier with no down-weighted point near it, the
/// inlier colour (calibrate.js's POINT_COLOUR.inlier, #00c8ff) over the photo.
fn assert_inlier_drawn(browser: &Browser, view: &Value) {
    let points = view["image_points"].as_array().expect("image_points");
    let xy = |p: &Value| {
        let v = &p["image_px"];
        (
            v[0].as_f64().expect("u") + 0.5,
            v[1].as_f64().expect("v") + 0.5,
        )
    };
    let outliers: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p["weight"].as_f64() < Some(1.0))
        .map(xy)
        .collect();
    let (x, y) = points
        .iter()
        .filter(|p| p["weight"].as_f64() == Some(1.0))
        .map(xy)
        .find(|&(x, y)| outliers.iter().all(|o| (o.0 - x).hypot(o.1 - y) > 40.0))
        .expect("an inlier far from every down-weighted point");
    let index = view["index"].as_u64().expect("an index");
    let rgb = browser.run(
        "const c = document.getElementById('calib-view-' + arguments[0]);
         return [...c.getContext('2d').getImageData(Math.floor(arguments[1]), Math.floor(arguments[2]), 1, 1).data];",
        &[json!(index), json!(x), json!(y)],
    );
    let channel = |k: usize| rgb[k].as_u64().expect("a channel");
    assert!(
        channel(0) < 60 && channel(1) > 170 && channel(2) > 220,
        "the inlier at ({x}, {y}) is {rgb}"
    );
}
