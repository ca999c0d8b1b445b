//! `qrpose render`: a synthetic photo of a QR code at a given pose and camera, and its
//! ground truth (corners px in qr order, finder corners, pose, camera) as JSON on stdout.

use super::estimate::{print_json, report_problem};
use clap::Args;
use qrpose::api::problem::{ErrorCode, Problem};
use qrpose::geometry::{camera::Camera, euler::EulerXyz, marker::Marker};
use qrpose::render::{EcLevel, Effects, Encoding, Scene, render};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Output image; `.png` writes PNG, anything else JPEG at --jpeg-quality.
    #[arg(long)]
    pub out: PathBuf,
    /// The symbol's content (UTF-8 text).
    #[arg(long, default_value = "qrpose")]
    pub payload: String,
    /// Error correction level: L, M, Q or H.
    #[arg(long, default_value = "M")]
    pub ec_level: String,
    /// Side of the symbol, mm (finder edge to finder edge, quiet zone excluded).
    #[arg(long, default_value_t = 50.0)]
    pub marker_size_mm: f64,
    /// Image width, px.
    #[arg(long, default_value_t = 1280)]
    pub width_px: u32,
    /// Image height, px.
    #[arg(long, default_value_t = 720)]
    pub height_px: u32,
    /// Horizontal focal length, px.
    #[arg(long, default_value_t = 1000.0)]
    pub fx_px: f64,
    /// Vertical focal length, px.
    #[arg(long, default_value_t = 1000.0)]
    pub fy_px: f64,
    /// Principal point, px (default: the image centre, (width − 1) / 2).
    #[arg(long, allow_negative_numbers = true)]
    pub cx_px: Option<f64>,
    /// Principal point, px (default: (height − 1) / 2).
    #[arg(long, allow_negative_numbers = true)]
    pub cy_px: Option<f64>,
    /// Marker centre in the camera frame, x (right), mm.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub x_mm: f64,
    /// Marker centre, y (down), mm.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub y_mm: f64,
    /// Marker centre, z (forward), mm.
    #[arg(long, default_value_t = 400.0)]
    pub z_mm: f64,
    /// Rotation R = Rx(alpha)·Ry(beta)·Rz(gamma), degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub alpha_deg: f64,
    /// See --alpha-deg.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub beta_deg: f64,
    /// See --alpha-deg.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub gamma_deg: f64,
    /// Supersampling per pixel axis (anti-aliasing), 1-16.
    #[arg(long, default_value_t = 4)]
    pub supersample: u32,
    /// Gaussian lens blur σ, px.
    #[arg(long, default_value_t = 0.0)]
    pub blur_px: f64,
    /// Sensor noise σ, grey levels.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
    /// Uneven lighting: illumination drop across the image, 0-0.9.
    #[arg(long, default_value_t = 0.0)]
    pub lighting: f64,
    /// Number of random background shapes.
    #[arg(long, default_value_t = 0)]
    pub clutter: u32,
    /// JPEG quality, 1-100.
    #[arg(long, default_value_t = 90)]
    pub jpeg_quality: u8,
    /// Seed of every random choice (noise, clutter, lighting direction).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Indent the JSON.
    #[arg(long)]
    pub pretty: bool,
}

fn problem(detail: impl Into<String>, field: &str) -> Problem {
    Problem::new(ErrorCode::InvalidType, detail).with_field(field)
}

fn scene(args: &RenderArgs) -> Result<Scene, Problem> {
    let cx = args.cx_px.unwrap_or(f64::from(args.width_px) / 2.0 - 0.5);
    let cy = args.cy_px.unwrap_or(f64::from(args.height_px) / 2.0 - 0.5);
    let camera = Camera::from_pixels(args.fx_px, args.fy_px, cx, cy)
        .map_err(|e| Problem::new(ErrorCode::InvalidCameraParameter, e.to_string()))?;
    let marker = Marker::try_new(args.marker_size_mm).map_err(|e| {
        Problem::new(ErrorCode::InvalidMarkerSize, e.to_string()).with_field("marker_size_mm")
    })?;
    let ec_level = match args.ec_level.to_ascii_uppercase().as_str() {
        "L" => EcLevel::L,
        "M" => EcLevel::M,
        "Q" => EcLevel::Q,
        "H" => EcLevel::H,
        other => return Err(problem(format!("unknown ec level {other}"), "ec_level")),
    };
    let r = EulerXyz::from_degrees(args.alpha_deg, args.beta_deg, args.gamma_deg).to_rotation();
    let centre = nalgebra::Vector3::new(args.x_mm, args.y_mm, args.z_mm);
    Ok(Scene {
        payload: args.payload.as_bytes().to_vec(),
        ec_level,
        marker,
        camera,
        width_px: args.width_px,
        height_px: args.height_px,
        pose: marker.pose_centred_at(r, centre),
    })
}

/// Runs `render`.
pub fn run(args: &RenderArgs) -> ExitCode {
    let png = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let effects = Effects {
        supersample: args.supersample,
        blur_px: args.blur_px,
        noise: args.noise,
        lighting: args.lighting,
        clutter: args.clutter,
        encoding: if png {
            Encoding::Png
        } else {
            Encoding::Jpeg(args.jpeg_quality)
        },
        seed: args.seed,
        ..Effects::default()
    };
    let scene = match scene(args) {
        Ok(s) => s,
        Err(p) => return report_problem(&p),
    };
    let rendered = match render(&scene, &effects) {
        Ok(r) => r,
        Err(e) => return report_problem(&Problem::new(ErrorCode::InvalidType, e.to_string())),
    };
    if let Err(e) = std::fs::write(&args.out, &rendered.encoded) {
        eprintln!("qrpose: cannot write {}: {e}", args.out.display());
        return ExitCode::FAILURE;
    }
    let c = &scene.camera;
    let truth = json!({
        "image": {"path": args.out, "width_px": args.width_px, "height_px": args.height_px},
        "payload": args.payload,
        "camera": {"fx_px": c.fx(), "fy_px": c.fy(), "cx_px": c.cx(), "cy_px": c.cy()},
        "marker": {"size_mm": scene.marker.size_mm()},
        "rotation_euler_xyz_deg": {"alpha": args.alpha_deg, "beta": args.beta_deg, "gamma": args.gamma_deg},
        "effects": effects,
        "truth": rendered.truth,
    });
    print_json(&truth, args.pretty)
}
