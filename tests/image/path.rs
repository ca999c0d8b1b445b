//! The image path end to end: rendered photos (made at test time by `qrpose_sim::render`)
//! through every backend, `estimate_image`, and the CLI, asserting corners and pose against
//! the ground truth.

use nalgebra::Vector3;
use qrpose::api::image::{ImageLimits, ImageRequest, PointsDto, estimate_image};
use qrpose::api::problem::ErrorCode;
use qrpose::detect::{
    Backend, Budget, Detector, DetectorChoice, Effort,
    backends::RxingDetector,
    decode::DecodeLimits,
    decode::decode_gray,
    detect_codes, detect_within,
    raster::downscale_half,
    refine::{RefineStatus, refine_corners},
};
use qrpose::geometry::{camera::Camera, euler::EulerXyz, frames::PixelPoint, marker::Marker};
use qrpose_sim::render::{EcLevel, Effects, Encoding, Rendered, Scene, render};
use serde_json::json;

/// Largest corner error allowed on the test renders, px (the benchmark's p90 target is 0.5,
/// its median target 0.2; a single render's worst corner is held to 0.35).
const CORNER_TOL_PX: f64 = 0.35;
/// Rotation error allowed on the test renders, degrees.
const ROTATION_TOL_DEG: f64 = 0.5;
/// Centre position error allowed, mm (at 350 mm).
const POSITION_TOL_MM: f64 = 1.0;

fn scene(payload: &str, centre_mm: [f64; 3], euler_deg: [f64; 3]) -> Scene {
    let marker = Marker::try_new(40.0).expect("valid size");
    let r = EulerXyz::from_degrees(euler_deg[0], euler_deg[1], euler_deg[2]).to_rotation();
    let centre = Vector3::new(centre_mm[0], centre_mm[1], centre_mm[2]);
    Scene {
        payload: payload.as_bytes().to_vec(),
        ec_level: EcLevel::M,
        marker,
        camera: Camera::from_pixels(900.0, 900.0, 319.5, 239.5).expect("valid camera"),
        width_px: 640,
        height_px: 480,
        pose: marker.pose_centred_at(r, centre),
    }
}

fn photo(scene: &Scene, seed: u64) -> Rendered {
    let effects = Effects {
        supersample: 3,
        blur_px: 0.9,
        noise: 2.0,
        lighting: 0.3,
        clutter: 10,
        encoding: Encoding::Jpeg(90),
        seed,
        ..Effects::default()
    };
    render(scene, &effects).expect("renders")
}

/// The bytes of a file in `tests/fixtures/`.
fn fixture(name: &str) -> Vec<u8> {
    let path = format!("{}/tests/fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read(&path).unwrap_or_else(|e| panic!("fixture {path}: {e}"))
}

fn max_corner_error_px(found: &[[f64; 2]; 4], truth: &[[f64; 2]; 4]) -> f64 {
    found
        .iter()
        .zip(truth)
        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
        .fold(0.0, f64::max)
}

#[test]
fn every_backend_finds_a_rendered_code_and_refines_its_corners() {
    let s = scene("backend test", [10.0, -5.0, 350.0], [15.0, -10.0, 25.0]);
    let r = photo(&s, 1);
    let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("decodes");
    for backend in [Backend::Rqrr, Backend::Rxing, Backend::ZxingCpp] {
        if !backend.is_built() {
            continue;
        }
        let codes = detect_codes(&image, DetectorChoice::Only(backend)).expect("built");
        assert_eq!(codes.len(), 1, "{}: one code", backend.as_str());
        let code = &codes[0];
        assert_eq!(code.candidate.text.as_deref(), Some("backend test"));
        // Every backend gives the module count (rxing's reader drops it; ours keeps it), so
        // that refinement does not have to guess it.
        assert_eq!(
            code.candidate.module_count,
            Some(r.truth.module_count),
            "{}",
            backend.as_str()
        );
        assert!(
            code.is_refined(),
            "{}: {:?}",
            backend.as_str(),
            code.refinement.status
        );
        let found = code.corners_px().map(|p| [p.u(), p.v()]);
        let err = max_corner_error_px(&found, &r.truth.corners_px);
        assert!(
            err < CORNER_TOL_PX,
            "{}: corner error {err} px",
            backend.as_str()
        );
        let raw = code.candidate.corners_px.map(|p| [p.u(), p.v()]);
        let raw_err = max_corner_error_px(&raw, &r.truth.corners_px);
        assert!(
            err < raw_err,
            "{}: refined {err} px, backend {raw_err} px",
            backend.as_str()
        );
        let finders = code.refinement.finder_corners_px.expect("finder corners");
        for (k, (f, t)) in finders.iter().zip(&r.truth.finder_corners_px).enumerate() {
            let e = (f.u() - t[0]).hypot(f.v() - t[1]);
            assert!(
                e < CORNER_TOL_PX,
                "{}: finder corner {k}: {e} px",
                backend.as_str()
            );
        }
    }
}

#[test]
fn auto_merges_codes_and_reads_both_of_two() {
    // Two codes side by side: render one, then the other onto the same background by
    // composing the two images (the renderer draws one symbol per scene).
    let left = photo(
        &scene("LEFT-CODE", [-45.0, 0.0, 350.0], [0.0, 10.0, 5.0]),
        2,
    );
    let right = photo(
        &scene("RIGHT-CODE", [45.0, 0.0, 350.0], [0.0, -10.0, -5.0]),
        3,
    );
    let (w, h) = (left.image.width(), left.image.height());
    let pixels: Vec<u8> = (0..w * h)
        .map(|i| {
            if i % w < w / 2 {
                left.image.pixels()[i]
            } else {
                right.image.pixels()[i]
            }
        })
        .collect();
    let image = qrpose::detect::decode::GrayImage::new(w, h, pixels).expect("same size");
    let codes = detect_codes(&image, DetectorChoice::Auto).expect("auto");
    let mut texts: Vec<_> = codes
        .iter()
        .filter_map(|c| c.candidate.text.clone())
        .collect();
    texts.sort();
    assert_eq!(texts, ["LEFT-CODE", "RIGHT-CODE"]);
    for code in &codes {
        let truth = if code.candidate.text.as_deref() == Some("LEFT-CODE") {
            &left
        } else {
            &right
        };
        let found = code.corners_px().map(|p| [p.u(), p.v()]);
        let err = max_corner_error_px(&found, &truth.truth.corners_px);
        assert!(err < CORNER_TOL_PX, "corner error {err} px");
    }
}

#[test]
fn merge_keeps_one_candidate_per_symbol_and_prefers_a_decoded_one() {
    use qrpose::detect::{Candidate, search::merge_candidates};
    use qrpose::geometry::frames::PixelPoint;
    let quad = |x: f64| {
        [
            PixelPoint::new(x, 0.0),
            PixelPoint::new(x + 50.0, 0.0),
            PixelPoint::new(x + 50.0, 50.0),
            PixelPoint::new(x, 50.0),
        ]
    };
    let undecoded = Candidate {
        corners_px: quad(0.0),
        payload: None,
        text: None,
        module_count: Some(21),
        backend: Backend::Rqrr,
    };
    let decoded = Candidate {
        corners_px: quad(2.0),
        payload: Some(b"A".to_vec()),
        text: Some("A".into()),
        module_count: None,
        backend: Backend::Rxing,
    };
    let other = Candidate {
        corners_px: quad(200.0),
        payload: Some(b"B".to_vec()),
        text: Some("B".into()),
        module_count: None,
        backend: Backend::Rxing,
    };
    let mut all = vec![undecoded];
    merge_candidates(&mut all, vec![decoded.clone(), other.clone()]);
    assert_eq!(all, vec![decoded.clone(), other]);
    merge_candidates(
        &mut all,
        vec![Candidate {
            payload: None,
            text: None,
            ..decoded.clone()
        }],
    );
    assert_eq!(
        all.len(),
        2,
        "an undecoded duplicate does not replace a decoded one"
    );
    assert_eq!(all[0], decoded);
}

fn request(points: Option<&str>) -> ImageRequest {
    serde_json::from_value(json!({
        "camera": {"fx_px": 900.0, "fy_px": 900.0, "cx_px": 319.5, "cy_px": 239.5},
        "marker": {"size_mm": 40.0},
        "points": points,
    }))
    .expect("valid request")
}

#[test]
fn estimate_image_returns_corners_and_pose_of_a_rendered_jpeg() {
    let s = scene("SKU-1", [-20.0, 15.0, 350.0], [-20.0, 15.0, 140.0]);
    let r = photo(&s, 4);
    for points in ["corners", "finders"] {
        let response = estimate_image(
            &r.encoded,
            &request(Some(points)),
            &ImageLimits::default(),
            None,
        )
        .expect("estimates");
        assert_eq!(
            (response.image.width_px, response.image.height_px),
            (640, 480)
        );
        assert_eq!(response.markers.len(), 1);
        let m = &response.markers[0];
        assert_eq!(m.payload.as_deref(), Some("SKU-1"));
        assert_eq!(m.payload_base64.as_deref(), Some("U0tVLTE="));
        let err = max_corner_error_px(&m.corners_px, &r.truth.corners_px);
        assert!(err < CORNER_TOL_PX, "{points}: corner error {err} px");
        let pose = m.pose.as_ref().expect("a pose");
        let expected = if points == "finders" {
            PointsDto::Finders
        } else {
            PointsDto::Corners
        };
        assert_eq!(m.points_used, expected);
        let p = &pose.position_mm;
        let centre = r.truth.position_mm;
        let pos_err =
            ((p.x - centre[0]).powi(2) + (p.y - centre[1]).powi(2) + (p.z - centre[2]).powi(2))
                .sqrt();
        assert!(
            pos_err < POSITION_TOL_MM,
            "{points}: position error {pos_err} mm"
        );
        let m_est = nalgebra::Matrix3::from_fn(|i, j| pose.rotation.matrix[i][j]);
        let m_true = nalgebra::Matrix3::from_fn(|i, j| r.truth.rotation_matrix[i][j]);
        let rot = nalgebra::Rotation3::from_matrix_unchecked(m_est.transpose() * m_true);
        assert!(
            rot.angle().to_degrees() < ROTATION_TOL_DEG,
            "{points}: rotation error {}°",
            rot.angle().to_degrees()
        );
    }
}

#[test]
fn corners_is_the_default_and_finders_is_refused_for_paper() {
    let s = scene("default points", [0.0, 0.0, 350.0], [10.0, 0.0, 0.0]);
    let r = photo(&s, 5);
    let response = estimate_image(&r.encoded, &request(None), &ImageLimits::default(), None)
        .expect("estimates");
    assert_eq!(response.markers[0].points_used, PointsDto::Corners);
    let err = max_corner_error_px(&response.markers[0].corners_px, &r.truth.corners_px);
    assert!(err < CORNER_TOL_PX, "corner error {err} px");
    let mut paper = request(Some("finders"));
    paper.solver.method = qrpose::api::request::MethodDto::Paper;
    let p = estimate_image(&r.encoded, &paper, &ImageLimits::default(), None).expect_err("refused");
    assert_eq!(
        (p.code, p.status, p.field.as_deref()),
        (ErrorCode::PointsNeedReprojection, 422, Some("/points"))
    );
    paper.points = None;
    let ok = estimate_image(&r.encoded, &paper, &ImageLimits::default(), None)
        .expect("paper on corners");
    assert_eq!(ok.markers[0].points_used, PointsDto::Corners);
    assert_eq!(
        ok.markers[0]
            .pose
            .as_ref()
            .map(|p| qrpose::estimate::Method::from(p.diagnostics.method).as_str()),
        Some("paper")
    );
}

#[test]
fn an_image_without_a_code_is_an_empty_success_and_bad_images_are_problems() {
    let blank = qrpose_sim::render::encode(
        &qrpose::detect::decode::GrayImage::new(64, 48, vec![200; 64 * 48]).expect("size"),
        Encoding::Jpeg(90),
    )
    .expect("encodes");
    let response = estimate_image(&blank, &request(None), &ImageLimits::default(), None)
        .expect("no code is fine");
    assert!(response.markers.is_empty());
    let cases = [
        (
            b"not an image".to_vec(),
            DecodeLimits::default(),
            ErrorCode::UndecodableImage,
            422,
        ),
        (
            blank[..blank.len() / 2].to_vec(),
            DecodeLimits::default(),
            ErrorCode::UndecodableImage,
            422,
        ),
        (
            blank.clone(),
            DecodeLimits {
                max_encoded_bytes: 100,
                ..DecodeLimits::default()
            },
            ErrorCode::PayloadTooLarge,
            413,
        ),
        (
            blank.clone(),
            DecodeLimits {
                max_pixels: 1000,
                ..DecodeLimits::default()
            },
            ErrorCode::ImageTooLarge,
            413,
        ),
    ];
    for (bytes, limits, code, status) in cases {
        let limits = ImageLimits {
            decode: limits,
            ..ImageLimits::default()
        };
        let p = estimate_image(&bytes, &request(None), &limits, None).expect_err("refused");
        assert_eq!((p.code, p.status), (code, status), "{}", p.detail);
    }
}

#[test]
fn asking_for_an_unbuilt_detector_is_a_clear_422() {
    let mut req = request(None);
    req.detector = qrpose::api::image::DetectorDto::ZxingCpp;
    let result = estimate_image(b"never decoded", &req, &ImageLimits::default(), None);
    if Backend::ZxingCpp.is_built() {
        assert_eq!(
            result.map(|_| ()).map_err(|p| p.code),
            Err(ErrorCode::UndecodableImage)
        );
    } else {
        let p = result.expect_err("not built");
        assert_eq!(
            (p.code, p.status, p.field.as_deref()),
            (ErrorCode::DetectorUnavailable, 422, Some("/detector"))
        );
    }
}

/// Regression: rqrr 0.11 panics in `detect_grids` on this zxing-cpp sample
/// (<https://github.com/WanzenBug/rqrr/issues/54>). The panic must be contained and count as
/// nothing found; `auto` still reads the code with another backend.
#[test]
fn rqrr_issue_54_panic_is_contained_as_no_detection() {
    let bytes = fixture("rqrr-issue-54-qrcode-6-7.png");
    let image = decode_gray(&bytes, &DecodeLimits::default()).expect("decodes");
    let rqrr = detect_codes(&image, DetectorChoice::Only(Backend::Rqrr)).expect("built");
    assert!(rqrr.is_empty(), "rqrr's panic is no detection");
    let auto = detect_codes(&image, DetectorChoice::Auto).expect("built");
    assert_eq!(auto.len(), 1);
    assert_eq!(auto[0].candidate.text.as_deref(), Some("1234567890"));
    // The symbol is axis-aligned-ish at 45°: its refined corners form a square of equal sides.
    let c = auto[0].corners_px();
    let sides: Vec<f64> = (0..4).map(|i| (c[i].0 - c[(i + 1) % 4].0).norm()).collect();
    let (lo, hi) = sides
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), s| (a.min(*s), b.max(*s)));
    assert!(hi - lo < 1.0, "sides {sides:?}");
}

fn qrpose() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_qrpose"))
}

#[test]
fn cli_render_then_estimate_image_round_trips_the_pose() {
    let dir = std::env::temp_dir().join(format!("qrpose-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("code.jpg");
    let flags = [
        "--payload",
        "CLI-1",
        "--marker-size-mm",
        "40",
        "--width-px",
        "640",
        "--height-px",
        "480",
        "--fx-px",
        "900",
        "--fy-px",
        "900",
        "--z-mm",
        "300",
        "--x-mm",
        "10",
        "--alpha-deg",
        "15",
        "--gamma-deg",
        "-30",
        "--blur-px",
        "0.7",
        "--noise",
        "1.5",
        "--seed",
        "7",
    ];
    let mut args = vec!["--out".as_ref(), path.as_os_str()];
    args.extend(flags.iter().map(std::ffi::OsStr::new));
    let truth = qrpose_sim::cli::render(&args).expect("qrpose-sim render");
    assert_eq!(truth["camera"]["cx_px"], json!(319.5));
    let out = qrpose()
        .args(["estimate", "--image"])
        .arg(&path)
        .args([
            "--fx-px",
            "900",
            "--fy-px",
            "900",
            "--cx-px",
            "319.5",
            "--cy-px",
            "239.5",
            "--marker-size-mm",
            "40",
        ])
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let response: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let marker = &response["markers"][0];
    assert_eq!(marker["payload"], json!("CLI-1"));
    for k in 0..4 {
        for a in 0..2 {
            let found = marker["corners_px"][k][a].as_f64().expect("number");
            let expected = truth["truth"]["corners_px"][k][a].as_f64().expect("number");
            assert!(
                (found - expected).abs() < CORNER_TOL_PX,
                "corner {k}: {found} vs {expected}"
            );
        }
    }
    let z = marker["pose"]["position_mm"]["z"].as_f64().expect("z");
    assert!((z - 300.0).abs() < POSITION_TOL_MM, "z = {z} mm");
    assert!(response["timing_ms"]["decode"].as_f64().is_some());
    let bad = qrpose()
        .args(["estimate", "--image"])
        .arg(&path)
        .args([
            "--fx-px", "900", "--fy-px", "900", "--cx-px", "319.5", "--cy-px", "239.5",
        ])
        .output()
        .expect("runs");
    assert_eq!(bad.status.code(), Some(2));
    let problem: serde_json::Value = serde_json::from_slice(&bad.stderr).expect("problem json");
    assert_eq!(problem["code"], json!("missing_field"));
    assert_eq!(problem["field"], json!("marker_size_mm"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A 1280 × 720 frame with one code of `module_px` px per module at `blur_px` blur.
fn hd_frame(payload: &str, distance_mm: f64, blur_px: f64, seed: u64) -> Rendered {
    let marker = Marker::try_new(50.0).expect("valid size");
    let r = EulerXyz::from_degrees(15.0, -20.0, 35.0).to_rotation();
    let centre = Vector3::new(30.0, 10.0, distance_mm);
    let scene = Scene {
        payload: payload.as_bytes().to_vec(),
        ec_level: EcLevel::M,
        marker,
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("valid camera"),
        width_px: 1280,
        height_px: 720,
        pose: marker.pose_centred_at(r, centre),
    };
    let effects = Effects {
        supersample: 3,
        blur_px,
        noise: 2.0,
        lighting: 0.2,
        clutter: 20,
        encoding: Encoding::Jpeg(85),
        seed,
        ..Effects::default()
    };
    render(&scene, &effects).expect("renders")
}

#[test]
fn auto_reads_a_large_code_in_an_hd_frame_and_refines_it_at_full_resolution() {
    // About 5 px per module: the quick pass reads it at half scale, then at full resolution
    // on a crop; the corners must still be refined to the full-resolution tolerance.
    let r = hd_frame("HD-FRAME-CODE", 400.0, 0.8, 11);
    let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("decodes");
    let codes = detect_codes(&image, DetectorChoice::Auto).expect("auto");
    assert_eq!(codes.len(), 1);
    assert_eq!(codes[0].candidate.text.as_deref(), Some("HD-FRAME-CODE"));
    assert!(codes[0].is_refined(), "{:?}", codes[0].refinement.status);
    let found = codes[0].corners_px().map(|p| [p.u(), p.v()]);
    let err = max_corner_error_px(&found, &r.truth.corners_px);
    assert!(err < CORNER_TOL_PX, "corner error {err} px");
}

#[test]
fn refinement_converges_from_the_corners_of_a_half_scale_read() {
    // rxing's whole-pixel corners on a half-scale copy, mapped back: 2-3 px off at about
    // 5 px per module. The scanning pass and one final pass leave most of a pixel; the
    // final passes that follow while the corners still move bring them to the accuracy of a
    // start at the true corners.
    let r = hd_frame("ROUGH-START", 400.0, 0.8, 5);
    let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("decodes");
    let half = downscale_half(&image).expect("halves");
    let found = RxingDetector::hybrid().detect(&half);
    assert_eq!(found.len(), 1, "rxing reads the half-scale copy");
    let rough = found[0]
        .corners_px
        .map(|p| PixelPoint::new(2.0 * p.u() + 0.5, 2.0 * p.v() + 0.5));
    let n = r.truth.module_count;
    assert_eq!(found[0].module_count, Some(n));
    let truth = r.truth.corners_px;
    let err = |c: &[PixelPoint; 4]| max_corner_error_px(&c.map(|p| [p.u(), p.v()]), &truth);
    let exact = truth.map(|t| PixelPoint::new(t[0], t[1]));
    let from_rough = refine_corners(&image, &rough, Some(n));
    let from_truth = refine_corners(&image, &exact, Some(n));
    let (e_start, e_rough, e_truth) = (
        err(&rough),
        err(&from_rough.corners_px),
        err(&from_truth.corners_px),
    );
    eprintln!("start {e_start} px, from rough {e_rough} px, from truth {e_truth} px");
    assert_eq!(from_rough.status, RefineStatus::Refined);
    assert!(e_start > 1.5, "a rough start: {e_start} px");
    // One final pass alone leaves about 0.1 px here.
    assert!(e_rough < 0.06, "from {e_start} px off: {e_rough} px");
}

/// Regression: a real photo (zxing-cpp sample qrcode-4/08.webp) that only the re-read
/// through the refined module grid decodes, and on which the refinement's passes do not
/// converge (the corners move 1 px, then 4 px): the pass that moved them further than the
/// one before is dropped, and the grid of the pass before still reads.
#[test]
fn a_diverging_refinement_keeps_the_pass_before_and_the_photo_still_reads() {
    let bytes = fixture("zxing-cpp-qrcode-4-08.webp");
    let image = decode_gray(&bytes, &DecodeLimits::default()).expect("decodes");
    // Only rqrr, the last pass on the symbol's region, finds it; the deadline is wall-clock
    // and this test build is barely optimised, so it gets room to reach that pass.
    let budget = Budget::new(Effort::Balanced, Some(std::time::Duration::from_secs(60)));
    let codes = detect_within(&image, DetectorChoice::Auto, &budget)
        .expect("built")
        .codes;
    let texts: Vec<_> = codes
        .iter()
        .filter_map(|c| c.candidate.text.as_deref())
        .collect();
    assert!(
        texts.contains(&"Google Print Ads - T.G.I.A.F. - January 31, 2008"),
        "{texts:?}"
    );
}

#[test]
fn reread_decodes_a_symbol_through_its_true_module_grid() {
    // 2.8 px per module under σ = 1 px blur: module centres through the exact grid must
    // decode (the path a found-but-unread symbol takes after refinement).
    let r = hd_frame("REREAD-ME", 850.0, 1.0, 12);
    let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("decodes");
    let corners = r
        .truth
        .corners_px
        .map(|p| qrpose::geometry::frames::PixelPoint::new(p[0], p[1]));
    let n = r.truth.module_count;
    let side_px = (corners[0].0 - corners[1].0).norm();
    assert!(
        side_px / (n as f64) < 3.0,
        "{} px per module",
        side_px / n as f64
    );
    let read = qrpose::detect::search::reread(&image, &corners, n).expect("reads");
    assert_eq!(read.payload, b"REREAD-ME");
    assert_eq!(read.text.as_deref(), Some("REREAD-ME"));
    // A grid one module off does not decode into anything.
    let off = corners.map(|p| qrpose::geometry::frames::PixelPoint::new(p.u() + 2.5, p.v()));
    assert_eq!(qrpose::detect::search::reread(&image, &off, n), None);
}

#[test]
fn sharpening_restores_contrast_of_blurred_modules_and_keeps_flat_areas() {
    use qrpose::detect::{decode::GrayImage, raster::sharpen};
    // Alternating 2 px bars blurred to low contrast (values 110 and 146), on a flat field.
    let (w, h) = (64, 16);
    let pixels: Vec<u8> = (0..w * h)
        .map(|i| {
            let x = i % w;
            if x < 32 {
                128
            } else if (x / 2) % 2 == 0 {
                110
            } else {
                146
            }
        })
        .collect();
    let image = GrayImage::new(w, h, pixels).expect("image");
    let sharp = sharpen(&image, 1.5, 2.0).expect("sharpens");
    let row = &sharp.pixels()[8 * w..9 * w];
    assert!(
        row[4..28].iter().all(|&v| v == 128),
        "flat stays flat: {row:?}"
    );
    let (lo, hi) = row[40..60]
        .iter()
        .fold((255, 0), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    assert!(hi - lo > 2 * (146 - 110), "contrast {lo}..{hi}");
}

#[cfg(feature = "zxing-cpp")]
mod zxing_cpp_backend {
    use super::*;
    use qrpose::detect::{Detector, backends::ZxingCppDetector};

    #[test]
    fn zxing_cpp_reads_a_rendered_code_with_its_version_and_refined_corners() {
        let r = hd_frame("ZXING-CPP-CODE", 450.0, 0.9, 13);
        let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("decodes");
        for detector in [ZxingCppDetector::fast(), ZxingCppDetector::thorough()] {
            let found = detector.detect(&image);
            assert_eq!(found.len(), 1, "{detector:?}");
            assert_eq!(found[0].text.as_deref(), Some("ZXING-CPP-CODE"));
            assert_eq!(found[0].module_count, Some(r.truth.module_count));
        }
        let codes = detect_codes(&image, DetectorChoice::Only(Backend::ZxingCpp)).expect("built");
        assert_eq!(codes.len(), 1);
        assert!(codes[0].is_refined(), "{:?}", codes[0].refinement.status);
        let found = codes[0].corners_px().map(|p| [p.u(), p.v()]);
        let err = max_corner_error_px(&found, &r.truth.corners_px);
        let raw = codes[0].candidate.corners_px.map(|p| [p.u(), p.v()]);
        let raw_err = max_corner_error_px(&raw, &r.truth.corners_px);
        assert!(err < CORNER_TOL_PX, "refined corner error {err} px");
        assert!(err < raw_err, "refined {err} px, zxing-cpp {raw_err} px");
    }

    #[test]
    fn auto_tries_zxing_cpp_first_when_it_is_built() {
        let r = hd_frame("AUTO-ZXING", 450.0, 0.9, 14);
        let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("decodes");
        let codes = detect_codes(&image, DetectorChoice::Auto).expect("auto");
        assert_eq!(codes.len(), 1);
        assert_eq!(codes[0].candidate.backend, Backend::ZxingCpp);
        assert_eq!(codes[0].candidate.text.as_deref(), Some("AUTO-ZXING"));
    }

    #[test]
    fn only_the_thorough_zxing_cpp_setting_reads_a_negative_code() {
        // Light-on-dark is read only by the thorough setting (it also tries the negative);
        // the fast one reads nothing there, which is why auto falls back to it.
        let r = hd_frame("NEGATIVE", 450.0, 0.9, 15);
        let image = decode_gray(&r.encoded, &DecodeLimits::default()).expect("decodes");
        let negative = qrpose::detect::raster::invert(&image).expect("inverts");
        let thorough = ZxingCppDetector::thorough().detect(&negative);
        assert!(
            thorough
                .iter()
                .any(|c| c.text.as_deref() == Some("NEGATIVE"))
        );
        let fast = ZxingCppDetector::fast().detect(&negative);
        assert!(fast.iter().all(|c| c.payload.is_none()), "{fast:?}");
    }
}
