//! `qrpose-sim render --hand-eye SESSION.json --out DIR`: the photos of a hand-eye session
//! (module [`crate::render::hand_eye`], docs/hand-eye.md) and their truth. Writes
//! DIR/photo-000.jpg, … (and DIR/board-000.jpg, … with `checkerboard`), and DIR/truth.json:
//! the session as rendered (camera, marker, setup, mount, target, noise, seed, effects) and
//! per photo the true and reported flange poses, the code's pose in the camera and its
//! corners in px (qr order: TL, TR, BR, BL); the same JSON is printed.
//!
//! Effects (blur, noise, lighting, clutter, JPEG quality) come from the render flags; photo
//! k draws its noise, clutter and lighting from the effects' seed · 1000 + k, its board the
//! same.

use super::camera::{CameraSpec, camera, camera_json};
use super::{parse_ec_level, write_image};
use crate::cli::Failure;
use crate::cli::problem::{Problem, parse_json};
use crate::render::hand_eye::{
    FlangeNoise, Setup, Transform, ViewGenerator, marker_to_camera, session_poses,
};
use crate::render::{BoardScene, Checkerboard, Effects, Scene, render, render_checkerboard};
use qrpose_core::geometry::marker::Marker;
use rayon::prelude::*;
use serde::Deserialize;
use serde_json::{Value, json};
use std::path::Path;

/// The session file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SessionFile {
    setup: Setup,
    #[serde(default = "default_width_px")]
    width_px: u32,
    #[serde(default = "default_height_px")]
    height_px: u32,
    #[serde(default)]
    camera: CameraSpec,
    marker: MarkerSpec,
    /// T_flange←camera (eye-in-hand) or T_robot←camera.
    mount: Transform,
    /// T_robot←marker (eye-in-hand) or T_flange←marker, marker frame at the symbol's centre.
    target: Transform,
    /// The true flange poses; drawn by `generator` when left out.
    #[serde(default)]
    flange_poses: Option<Vec<Transform>>,
    #[serde(default)]
    generator: ViewGenerator,
    #[serde(default)]
    flange_noise: FlangeNoise,
    #[serde(default)]
    seed: u64,
    /// Also render a checkerboard of the code's size at the same poses.
    #[serde(default)]
    checkerboard: Option<BoardSpec>,
}

fn default_width_px() -> u32 {
    1280
}

fn default_height_px() -> u32 {
    720
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MarkerSpec {
    size_mm: f64,
    #[serde(default = "default_payload")]
    payload: String,
    #[serde(default = "default_ec_level")]
    ec_level: String,
}

fn default_payload() -> String {
    "qrpose hand-eye".to_owned()
}

fn default_ec_level() -> String {
    "M".to_owned()
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BoardSpec {
    squares: u32,
    /// Light border, mm (default: the code's quiet zone, 4 modules of a 33-module symbol).
    #[serde(default)]
    border_mm: Option<f64>,
}

fn bad(code: &'static str, detail: impl Into<String>, field: &str) -> Problem {
    Problem::new(code, detail).with_field(field)
}

fn isometry(t: &Transform, field: &str) -> Result<nalgebra::Isometry3<f64>, Problem> {
    t.to_isometry()
        .ok_or_else(|| bad("invalid_type", "a zero or non-finite transform", field))
}

/// Renders the session of `path` into `out` with `effects`: the truth JSON.
pub(super) fn run(path: &Path, out: &Path, effects: &Effects) -> Result<Value, Failure> {
    let text = std::fs::read(path)
        .map_err(|e| Failure::Other(format!("cannot read {}: {e}", path.display())))?;
    let file: SessionFile = parse_json(&text)?;
    let cam = camera(
        &file.camera,
        file.width_px,
        file.height_px,
        "/camera/distortion/coefficients",
    )?;
    let marker = Marker::try_new(file.marker.size_mm)
        .map_err(|e| bad("invalid_marker_size", e.to_string(), "/marker/size_mm"))?;
    let ec_level = parse_ec_level(&file.marker.ec_level, "/marker/ec_level")?;
    let mount = isometry(&file.mount, "/mount")?;
    let target = isometry(&file.target, "/target")?;
    let given = file
        .flange_poses
        .as_ref()
        .map(|poses| {
            poses
                .iter()
                .enumerate()
                .map(|(i, p)| isometry(p, &format!("/flange_poses/{i}")))
                .collect::<Result<Vec<_>, _>>()
        })
        .transpose()?;
    let poses = session_poses(
        file.setup,
        &mount,
        &target,
        given.as_deref(),
        &file.generator,
        &file.flange_noise,
        &cam,
        [file.width_px, file.height_px],
        &marker,
        file.seed,
    )
    .map_err(|e| Problem::new("invalid_type", e.to_string()).with_field("/generator"))?;
    std::fs::create_dir_all(out)
        .map_err(|e| Failure::Other(format!("cannot create {}: {e}", out.display())))?;
    let board = file.checkerboard.as_ref().map(|b| Checkerboard {
        squares: b.squares,
        size_mm: marker.size_mm(),
        border_mm: b.border_mm.unwrap_or(marker.size_mm() * 4.0 / 33.0),
    });
    let rendered: Vec<Result<Value, Failure>> = poses
        .codes
        .par_iter()
        .enumerate()
        .map(|(k, code)| {
            let pose = marker_to_camera(code, &marker);
            let view_effects = Effects {
                seed: effects.seed.wrapping_mul(1000).wrapping_add(k as u64),
                ..*effects
            };
            let scene = Scene {
                payload: file.marker.payload.as_bytes().to_vec(),
                ec_level,
                marker,
                camera: cam,
                width_px: file.width_px,
                height_px: file.height_px,
                pose,
            };
            let photo = render(&scene, &view_effects).map_err(|e| {
                Failure::Refused(Problem::new("invalid_type", format!("view {k}: {e}")))
            })?;
            let name = format!("photo-{k:03}.jpg");
            write_image(&out.join(&name), &photo.encoded)?;
            let board_json = match board {
                Some(board) => {
                    let b = render_checkerboard(
                        &BoardScene {
                            board,
                            camera: cam,
                            width_px: file.width_px,
                            height_px: file.height_px,
                            pose,
                        },
                        &view_effects,
                    )
                    .map_err(|e| {
                        Failure::Refused(Problem::new("invalid_type", format!("board {k}: {e}")))
                    })?;
                    let board_name = format!("board-{k:03}.jpg");
                    write_image(&out.join(&board_name), &b.encoded)?;
                    json!({"photo": board_name, "truth": b.truth})
                }
                None => Value::Null,
            };
            Ok(json!({
                "index": k,
                "photo": name,
                "flange_pose_true": Transform::from_isometry(&poses.flanges[k]),
                "flange_pose_reported": Transform::from_isometry(&poses.reported[k]),
                "code_in_camera": Transform::from_isometry(code),
                "corners_px": photo.truth.corners_px,
                "finder_corners_px": photo.truth.finder_corners_px,
                "board": board_json,
            }))
        })
        .collect();
    let views = rendered.into_iter().collect::<Result<Vec<_>, _>>()?;
    let truth = json!({
        "setup": file.setup,
        "image": {"width_px": file.width_px, "height_px": file.height_px},
        "camera": camera_json(&cam),
        "marker": {"size_mm": marker.size_mm(), "payload": file.marker.payload},
        "mount": Transform::from_isometry(&mount),
        "target": Transform::from_isometry(&target),
        "flange_noise": file.flange_noise,
        "seed": file.seed,
        "effects": effects,
        "views": views,
    });
    let text = serde_json::to_vec_pretty(&truth).map_err(|e| Failure::Other(e.to_string()))?;
    let truth_path = out.join("truth.json");
    std::fs::write(&truth_path, text)
        .map_err(|e| Failure::Other(format!("cannot write {}: {e}", truth_path.display())))?;
    Ok(truth)
}
