//! Accuracy benchmark of the image path on a seeded rendered set.
//!
//! ```sh
//! cargo run --release --example accuracy_images -- --count 200 --out target/accuracy
//! cargo run --release --features zxing-cpp --example accuracy_images -- --count 200 --out target/accuracy
//! ```
//!
//! Renders `--count` photos (sizes 30-100 mm, distance 120-1200 mm with at least
//! `MIN_MODULE_PX` px per module on every side of the projected symbol (`--module-rule
//! distance`: only at a fronto-parallel view, the first set's rule), tilt up to 40°, any
//! in-plane rotation, blur σ 0.4-1.4 px, noise σ 1-4 grey levels, uneven lighting, clutter, JPEG quality 70-95, 1280×720 and
//! 1920×1080 cameras), writes each as `DIR/NNNN.jpg` with `DIR/NNNN.json` (ground truth and
//! camera), runs every backend built, and prints detected %, payload correct %, corner error
//! (median, p90; raw backend corners and refined) and pose error (rotation °, centre
//! position mm; median, p90) for `points = corners` and `points = finders`. Per-image rows go
//! to `DIR/ours.json` for `scripts/accuracy_images.py`.

use nalgebra::{Rotation3, Unit, Vector3};
use qrpose::detect::{Backend, DetectedCode, DetectorChoice, decode, detect_codes};
use qrpose::estimate::{ValidSolver, estimate_planar_points, estimate_pose};
use qrpose::geometry::{
    camera::Camera,
    euler::angle_between,
    frames::{MarkerToCamera, PixelPoint},
    marker::{CornerOrder, Marker},
    quad::ImageQuad,
};
use qrpose_sim::render::{EcLevel, Effects, Encoding, Scene, ground_truth, render};
use rand::{Rng, SeedableRng, rngs::StdRng};
use rayon::prelude::*;
use serde_json::json;
use std::path::PathBuf;

const MIN_MODULE_PX: f64 = 2.0;

struct Args {
    count: usize,
    seed: u64,
    out: PathBuf,
    /// Keep only views whose projected modules are ≥ MIN_MODULE_PX on every side of the
    /// symbol (the default); `--module-rule distance` keeps the first rule, which limited
    /// the distance so that a fronto-parallel module is ≥ MIN_MODULE_PX, and let tilt
    /// shrink modules below it.
    projected_rule: bool,
}

fn parse_args() -> Args {
    let mut args = Args {
        count: 200,
        seed: 1,
        out: PathBuf::from("target/accuracy"),
        projected_rule: true,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--count" => args.count = it.next().and_then(|v| v.parse().ok()).unwrap_or(200),
            "--seed" => args.seed = it.next().and_then(|v| v.parse().ok()).unwrap_or(1),
            "--out" => args.out = it.next().map(PathBuf::from).unwrap_or(args.out),
            "--module-rule" => args.projected_rule = it.next().as_deref() != Some("distance"),
            _ => eprintln!("ignoring {a}"),
        }
    }
    args
}

struct Case {
    scene: Scene,
    effects: Effects,
    payload: String,
}

fn random_payload(rng: &mut StdRng) -> String {
    const CHARS: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-abcdefghijklmnopqrstuvwxyz";
    let len = rng.gen_range(6..40);
    let body: String = (0..len)
        .map(|_| char::from(CHARS[rng.gen_range(0..CHARS.len())]))
        .collect();
    format!("SKU-{body}")
}

fn make_case(seed: u64, projected_rule: bool) -> Option<Case> {
    let mut rng = StdRng::seed_from_u64(seed);
    let hd = rng.gen_bool(0.5);
    let (w, h, f) = if hd {
        (1920u32, 1080u32, 1400.0)
    } else {
        (1280u32, 720u32, 1000.0)
    };
    let camera =
        Camera::from_pixels(f, f, f64::from(w) / 2.0 - 0.5, f64::from(h) / 2.0 - 0.5).ok()?;
    let payload = random_payload(&mut rng);
    let ec_level = EcLevel::M;
    let (n, _) = qrpose_sim::render::symbol_modules(payload.as_bytes(), ec_level).ok()?;
    for _ in 0..200 {
        let size_mm = rng.gen_range(30.0..100.0);
        let max_distance = (size_mm / n as f64 * f / MIN_MODULE_PX).min(1200.0);
        if max_distance <= 120.0 {
            continue;
        }
        let distance = rng.gen_range(120.0..max_distance);
        let tilt = rng.gen_range(0.0f64..40.0).to_radians();
        let tilt_axis_angle = rng.gen_range(0.0..std::f64::consts::TAU);
        let axis = Unit::new_normalize(Vector3::new(
            tilt_axis_angle.cos(),
            tilt_axis_angle.sin(),
            0.0,
        ));
        let gamma = rng.gen_range(-180.0f64..180.0).to_radians();
        let r = Rotation3::from_axis_angle(&axis, tilt)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), gamma);
        // Marker centre on a random ray inside the central 80 % of the image.
        let u = rng.gen_range(0.1..0.9) * f64::from(w);
        let v = rng.gen_range(0.1..0.9) * f64::from(h);
        let ray = Vector3::new((u - camera.cx()) / f, (v - camera.cy()) / f, 1.0).normalize();
        let centre = ray * distance;
        let marker = Marker::try_new(size_mm).ok()?;
        let scene = Scene {
            payload: payload.as_bytes().to_vec(),
            ec_level,
            marker,
            camera,
            width_px: w,
            height_px: h,
            pose: marker.pose_centred_at(r, centre),
        };
        let Ok(truth) = ground_truth(&scene) else {
            continue;
        };
        // The symbol and 2 modules of quiet zone inside the image.
        let margin = 2.0 * size_mm / n as f64 * f / distance;
        let inside = truth.corners_px.iter().all(|p| {
            p[0] > margin
                && p[1] > margin
                && p[0] < f64::from(w) - margin
                && p[1] < f64::from(h) - margin
        });
        if !inside {
            continue;
        }
        let side = |a: usize, b: usize| {
            let (p, q) = (truth.corners_px[a], truth.corners_px[b]);
            (p[0] - q[0]).hypot(p[1] - q[1])
        };
        let min_module_px = [side(0, 1), side(1, 2), side(2, 3), side(3, 0)]
            .into_iter()
            .fold(f64::INFINITY, f64::min)
            / n as f64;
        if projected_rule && min_module_px < MIN_MODULE_PX {
            continue;
        }
        let effects = Effects {
            supersample: 4,
            blur_px: rng.gen_range(0.4..1.4),
            noise: rng.gen_range(1.0..4.0),
            lighting: rng.gen_range(0.0..0.5),
            clutter: 25,
            dark_level: rng.gen_range(15.0..50.0),
            light_level: rng.gen_range(180.0..240.0),
            quiet_zone_modules: 4.0,
            encoding: Encoding::Jpeg(rng.gen_range(70..=95)),
            seed,
        };
        return Some(Case {
            scene,
            effects,
            payload,
        });
    }
    None
}

fn to_points(c: &[[f64; 2]]) -> Vec<PixelPoint> {
    c.iter().map(|p| PixelPoint::new(p[0], p[1])).collect()
}

struct Eval {
    detected: bool,
    payload_ok: bool,
    raw_corner_err: Vec<f64>,
    corner_err: Vec<f64>,
    finder_err: Vec<f64>,
    rot_corners: Option<f64>,
    pos_corners: Option<f64>,
    rot_finders: Option<f64>,
    pos_finders: Option<f64>,
    refined: bool,
}

fn pose_error(
    est: &qrpose::estimate::PoseEstimate,
    truth: &MarkerToCamera,
    marker: &Marker,
) -> (f64, f64) {
    let rot = angle_between(&est.pose.rotation(), &truth.rotation()).to_degrees();
    let centre = truth.transform(&marker.centre()).0.coords;
    (rot, (est.centre_mm - centre).norm())
}

fn evaluate(case: &Case, truth: &qrpose_sim::render::GroundTruth, codes: &[DetectedCode]) -> Eval {
    let tc = to_points(&truth.corners_px);
    let centre = |c: &[PixelPoint]| {
        PixelPoint::new(
            c.iter().map(|p| p.u()).sum::<f64>() / c.len() as f64,
            c.iter().map(|p| p.v()).sum::<f64>() / c.len() as f64,
        )
    };
    let tcen = centre(&tc);
    let best = codes.iter().min_by(|a, b| {
        let da = (centre(a.corners_px()).0 - tcen.0).norm();
        let db = (centre(b.corners_px()).0 - tcen.0).norm();
        da.total_cmp(&db)
    });
    let mut e = Eval {
        detected: false,
        payload_ok: false,
        raw_corner_err: vec![],
        corner_err: vec![],
        finder_err: vec![],
        rot_corners: None,
        pos_corners: None,
        rot_finders: None,
        pos_finders: None,
        refined: false,
    };
    let Some(code) = best else { return e };
    let side = (tc[0].0 - tc[1].0).norm();
    if (centre(code.corners_px()).0 - tcen.0).norm() > 0.5 * side {
        return e;
    }
    e.detected = true;
    e.refined = code.is_refined();
    e.payload_ok = code.candidate.text.as_deref() == Some(case.payload.as_str());
    for (k, t) in tc.iter().enumerate() {
        e.raw_corner_err
            .push((code.candidate.corners_px[k].0 - t.0).norm());
        e.corner_err.push((code.corners_px()[k].0 - t.0).norm());
    }
    let s = &case.scene;
    let params = ValidSolver::default();
    if let Ok(quad) = ImageQuad::try_new(*code.corners_px(), CornerOrder::Qr)
        && let Ok(est) = estimate_pose(&quad, &s.camera, &s.marker, &params)
    {
        let (r, p) = pose_error(&est, &s.pose, &s.marker);
        e.rot_corners = Some(r);
        e.pos_corners = Some(p);
    }
    if let (Some(fc), Some(n)) = (
        code.refinement.finder_corners_px,
        code.refinement.module_count,
    ) {
        let tf = to_points(&truth.finder_corners_px);
        for k in 0..12 {
            e.finder_err.push((fc[k].0 - tf[k].0).norm());
        }
        let model: Vec<_> = qrpose::detect::refine::finder_model_points(n)
            .iter()
            .map(|m| qrpose_sim::render::marker_point(m.u, m.v, &s.marker, n))
            .collect();
        if let Ok(est) = estimate_planar_points(&model, &fc, &s.camera, &s.marker, &params) {
            let (r, p) = pose_error(&est, &s.pose, &s.marker);
            e.rot_finders = Some(r);
            e.pos_finders = Some(p);
        }
    } else {
        e.rot_finders = e.rot_corners;
        e.pos_finders = e.pos_corners;
    }
    e
}

#[allow(clippy::cast_possible_truncation)] // an index within 0..len
fn pct(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let args = parse_args();
    if let Err(e) = std::fs::create_dir_all(&args.out) {
        eprintln!("cannot create {}: {e}", args.out.display());
        std::process::exit(1);
    }
    let cases: Vec<(usize, Case)> = (0..args.count)
        .filter_map(|i| {
            make_case(args.seed * 1_000_003 + i as u64, args.projected_rule).map(|c| (i, c))
        })
        .collect();
    eprintln!(
        "rendering {} images into {}",
        cases.len(),
        args.out.display()
    );
    let rendered: Vec<_> = cases
        .par_iter()
        .filter_map(|(i, case)| {
            let r = render(&case.scene, &case.effects).ok()?;
            let name = format!("{i:04}");
            let c = &case.scene.camera;
            let meta = json!({
                "payload": case.payload,
                "marker_size_mm": case.scene.marker.size_mm(),
                "camera": {"fx_px": c.fx(), "fy_px": c.fy(), "cx_px": c.cx(), "cy_px": c.cy()},
                "width_px": case.scene.width_px, "height_px": case.scene.height_px,
                "effects": case.effects,
                "truth": r.truth,
            });
            std::fs::write(args.out.join(format!("{name}.jpg")), &r.encoded).ok()?;
            std::fs::write(args.out.join(format!("{name}.json")), meta.to_string()).ok()?;
            Some((name, case, r))
        })
        .collect();
    let mut backends: Vec<(&str, DetectorChoice)> = vec![
        ("auto", DetectorChoice::Auto),
        ("rqrr", DetectorChoice::Only(Backend::Rqrr)),
        ("rxing", DetectorChoice::Only(Backend::Rxing)),
    ];
    if Backend::ZxingCpp.is_built() {
        backends.push(("zxing-cpp", DetectorChoice::Only(Backend::ZxingCpp)));
    }
    let mut rows = Vec::new();
    println!(
        "| detector | images | detected % | payload ok % | refined % | raw corner err median / p90 px | refined corner err median / p90 px | finder corner err median / p90 px | rotation err corners median / p90 ° | rotation err finders median / p90 ° | position err corners median / p90 mm | position err finders median / p90 mm |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, choice) in &backends {
        let evals: Vec<(String, Eval)> = rendered
            .par_iter()
            .map(|(file, case, r)| {
                let image = decode::decode_gray(&r.encoded, &decode::DecodeLimits::default());
                let codes = image
                    .ok()
                    .and_then(|img| detect_codes(&img, *choice).ok())
                    .unwrap_or_default();
                (file.clone(), evaluate(case, &r.truth, &codes))
            })
            .collect();
        let n = evals.len() as f64;
        let detected = evals.iter().filter(|(_, e)| e.detected).count() as f64;
        let payload = evals.iter().filter(|(_, e)| e.payload_ok).count() as f64;
        let refined = evals.iter().filter(|(_, e)| e.refined).count() as f64;
        let mut raw: Vec<f64> = evals
            .iter()
            .flat_map(|(_, e)| e.raw_corner_err.clone())
            .collect();
        let mut cor: Vec<f64> = evals
            .iter()
            .flat_map(|(_, e)| e.corner_err.clone())
            .collect();
        let mut fin: Vec<f64> = evals
            .iter()
            .flat_map(|(_, e)| e.finder_err.clone())
            .collect();
        let mut rc: Vec<f64> = evals.iter().filter_map(|(_, e)| e.rot_corners).collect();
        let mut rf: Vec<f64> = evals.iter().filter_map(|(_, e)| e.rot_finders).collect();
        let mut pc: Vec<f64> = evals.iter().filter_map(|(_, e)| e.pos_corners).collect();
        let mut pf: Vec<f64> = evals.iter().filter_map(|(_, e)| e.pos_finders).collect();
        println!(
            "| {name} | {} | {:.1} | {:.1} | {:.1} | {:.3} / {:.3} | {:.3} / {:.3} | {:.3} / {:.3} | {:.3} / {:.3} | {:.3} / {:.3} | {:.2} / {:.2} | {:.2} / {:.2} |",
            evals.len(),
            100.0 * detected / n,
            100.0 * payload / n,
            100.0 * refined / n.max(1.0),
            pct(&mut raw, 0.5),
            pct(&mut raw, 0.9),
            pct(&mut cor, 0.5),
            pct(&mut cor, 0.9),
            pct(&mut fin, 0.5),
            pct(&mut fin, 0.9),
            pct(&mut rc, 0.5),
            pct(&mut rc, 0.9),
            pct(&mut rf, 0.5),
            pct(&mut rf, 0.9),
            pct(&mut pc, 0.5),
            pct(&mut pc, 0.9),
            pct(&mut pf, 0.5),
            pct(&mut pf, 0.9),
        );
        for (file, e) in &evals {
            rows.push(json!({
                "image": file, "detector": name, "detected": e.detected, "payload_ok": e.payload_ok,
                "refined": e.refined, "raw_corner_err_px": e.raw_corner_err, "corner_err_px": e.corner_err,
                "finder_err_px": e.finder_err,
                "rotation_err_deg": {"corners": e.rot_corners, "finders": e.rot_finders},
                "position_err_mm": {"corners": e.pos_corners, "finders": e.pos_finders},
            }));
        }
    }
    if let Err(e) = std::fs::write(
        args.out.join("ours.json"),
        serde_json::Value::from(rows).to_string(),
    ) {
        eprintln!("cannot write ours.json: {e}");
    }
}
