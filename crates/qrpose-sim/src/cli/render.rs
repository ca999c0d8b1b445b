//! `qrpose-sim render`: a synthetic photo of a QR code at a given pose and camera, and its
//! ground truth (corners px in qr order, finder corners, pose, camera) as JSON on stdout;
//! or of several codes, from a JSON scene file (`--scene`) or drawn at random
//! (`--random-scene`), with the ground truth of every code under `codes`; or a rendered
//! video (`--sequence`, module `sequence`): frames, their truth, and the sequence file; or
//! photos of products from a camera on a robot's flange (`--pick-scene`, `--pick-study`,
//! module `pick`).

mod camera;
mod hand_eye;
mod pick;
mod sequence;

use super::Failure;
use super::problem::{Problem, parse_json};
use crate::render::{
    CodePlacement, EcLevel, Effects, Encoding, MultiScene, Scene, SceneRanges, random_scene,
    render, render_scene,
};
use camera::{CameraSpec, DistortionSpec, LensModel, camera, camera_json};
use clap::Args;
use qrpose_core::geometry::{euler::EulerXyz, marker::Marker};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// The single-code flags that `--scene` replaces (`--random-scene` keeps the image size).
const SINGLE_CODE_FLAGS: [&str; 15] = [
    "payload",
    "ec_level",
    "marker_size_mm",
    "fx_px",
    "fy_px",
    "cx_px",
    "cy_px",
    "distortion_model",
    "distortion_coefficients",
    "x_mm",
    "y_mm",
    "z_mm",
    "alpha_deg",
    "beta_deg",
    "gamma_deg",
];

/// Default image size, px.
const DEFAULT_SIZE_PX: [u32; 2] = [1280, 720];
/// Default focal length, px.
const DEFAULT_FOCAL_PX: f64 = 1000.0;
/// Default JPEG quality.
const DEFAULT_JPEG_QUALITY: u8 = 90;

/// Arguments of `render`.
#[derive(Debug, Args)]
#[command(after_long_help = SCENE_HELP)]
pub struct RenderArgs {
    /// Output image; `.png` writes PNG, anything else JPEG at --jpeg-quality. With
    /// --sequence, --pick-scene or --pick-study, the output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    // --sequence and its flags: a rendered video instead of a photo.
    #[command(flatten)]
    pub video: sequence::SequenceArgs,
    // --pick-scene / --pick-study: photos of products from a camera on a robot's flange.
    #[command(flatten)]
    pub pick: pick::PickArgs,
    /// Render the codes of a JSON scene file instead of one code from the flags below
    /// (format in the long help, `--help`); the effect flags still apply. The JSON printed
    /// lists every code under "codes".
    #[arg(long, value_name = "FILE.json", conflicts_with_all = SINGLE_CODE_FLAGS)]
    pub scene: Option<PathBuf>,
    /// Render the photos of a hand-eye session (docs/hand-eye.md): a camera on a robot
    /// arm, its mount, the code's pose, the flange poses (given, or drawn by a generator)
    /// and their reported noisy values. --out is the directory (created if missing); writes
    /// photo-000.jpg, … (board-000.jpg, … with "checkerboard") and truth.json, and prints
    /// the same JSON. The effect flags apply.
    #[arg(
        long,
        value_name = "SESSION.json",
        conflicts_with_all = ["scene", "random_scene", "sequence"],
        conflicts_with_all = SINGLE_CODE_FLAGS
    )]
    pub hand_eye: Option<PathBuf>,
    /// Render a random scene drawn from this seed: 2-6 codes of 30-120 mm, 0.3-2 m away,
    /// tilted up to 35° from the line of sight, never overlapping (quiet zones included),
    /// seen by a camera with fx = fy in 950-1050 px and the principal point at the centre,
    /// in a --width-px × --height-px frame. The same seed gives the same scene; --seed
    /// still drives noise, clutter and lighting. The JSON printed lists every code under
    /// "codes".
    #[arg(
        long,
        value_name = "SEED",
        conflicts_with = "scene",
        conflicts_with_all = SINGLE_CODE_FLAGS
    )]
    pub random_scene: Option<u64>,
    /// The symbol's content (UTF-8 text).
    #[arg(long, default_value = "qrpose")]
    pub payload: String,
    /// Error correction level: L, M, Q or H.
    #[arg(long, default_value = "M")]
    pub ec_level: String,
    /// Side of the symbol, mm (finder edge to finder edge, quiet zone excluded).
    #[arg(long, default_value_t = 50.0)]
    pub marker_size_mm: f64,
    /// Image width, px [default: 1280, or the sequence's].
    #[arg(long)]
    pub width_px: Option<u32>,
    /// Image height, px [default: 720, or the sequence's].
    #[arg(long)]
    pub height_px: Option<u32>,
    /// Horizontal focal length, px [default: 1000, or the sequence's].
    #[arg(long)]
    pub fx_px: Option<f64>,
    /// Vertical focal length, px [default: 1000, or the sequence's].
    #[arg(long)]
    pub fy_px: Option<f64>,
    /// Principal point, px (default: the image centre, (width − 1) / 2).
    #[arg(long, allow_negative_numbers = true)]
    pub cx_px: Option<f64>,
    /// Principal point, px (default: (height − 1) / 2).
    #[arg(long, allow_negative_numbers = true)]
    pub cy_px: Option<f64>,
    /// Lens model of --distortion-coefficients: `plumb_bob` (default), `rational_polynomial`
    /// or `equidistant` (fisheye), as docs/calibration.md defines them.
    #[arg(long, value_enum, requires = "distortion_coefficients")]
    pub distortion_model: Option<LensModel>,
    /// Lens distortion coefficients in OpenCV's order, comma-separated: plumb_bob k1,k2,p1,p2,k3;
    /// rational_polynomial k1,k2,p1,p2,k3,k4,k5,k6; equidistant k1,k2,k3,k4. A fisheye pixel
    /// 90° or more off the axis shows the background.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub distortion_coefficients: Option<Vec<f64>>,
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
    /// Supersampling per pixel axis (anti-aliasing), 1-16 [default: 4, or the sequence's].
    #[arg(long)]
    pub supersample: Option<u32>,
    /// Gaussian lens blur σ, px [default: 0, or the sequence's].
    #[arg(long)]
    pub blur_px: Option<f64>,
    /// Sensor noise σ, grey levels [default: 0, or the sequence's].
    #[arg(long)]
    pub noise: Option<f64>,
    /// Uneven lighting: illumination drop across the image, 0-0.9 [default: 0, or the
    /// sequence's].
    #[arg(long)]
    pub lighting: Option<f64>,
    /// Number of random background shapes.
    #[arg(long, default_value_t = 0)]
    pub clutter: u32,
    /// JPEG quality, 1-100 [default: 90, or the sequence's].
    #[arg(long)]
    pub jpeg_quality: Option<u8>,
    /// Seed of every random choice (noise, clutter, lighting direction) [default: 0, or the
    /// sequence's].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Indent the JSON.
    #[arg(long)]
    pub pretty: bool,
}

/// The long help: the scene file's format.
const SCENE_HELP: &str = r#"Scene file (--scene): every field but "codes" and each code's "payload", "size_mm" and
"position_mm" may be left out; defaults are those of the flags.
  {
    "width_px": 1280, "height_px": 720,
    "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5,
               "distortion": {"model": "plumb_bob", "coefficients": [-0.1, 0.02, 0, 0, 0]}},
    "codes": [
      {"payload": "LEFT", "ec_level": "M", "size_mm": 50,
       "position_mm": [-120, 0, 500],
       "rotation_euler_xyz_deg": {"alpha": 0, "beta": 20, "gamma": 10}},
      {"payload": "RIGHT", "size_mm": 40, "position_mm": [120, 20, 450]}
    ]
  }
position_mm is the code's centre in the camera frame (x right, y down, z forward), the
rotation R = Rx(alpha)·Ry(beta)·Rz(gamma), as --x-mm … --gamma-deg. The camera's
"distortion" (none when left out) is as --distortion-model and --distortion-coefficients. Codes are drawn in order,
a later one over an earlier one; each code's ground truth is where it was placed, hidden or
not, so keep codes apart (their quiet zones too) unless occlusion is what is wanted."#;

/// The JSON scene file of `--scene`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default = "default_width_px")]
    width_px: u32,
    #[serde(default = "default_height_px")]
    height_px: u32,
    #[serde(default)]
    camera: CameraSpec,
    codes: Vec<CodeSpec>,
}

fn default_width_px() -> u32 {
    1280
}

fn default_height_px() -> u32 {
    720
}

/// One code of a scene file, and of the `codes` printed.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CodeSpec {
    payload: String,
    #[serde(default = "default_ec_level")]
    ec_level: String,
    size_mm: f64,
    position_mm: [f64; 3],
    #[serde(default)]
    rotation_euler_xyz_deg: EulerSpec,
}

fn default_ec_level() -> String {
    "M".to_owned()
}

/// R = Rx(alpha)·Ry(beta)·Rz(gamma), degrees.
#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct EulerSpec {
    #[serde(default)]
    alpha: f64,
    #[serde(default)]
    beta: f64,
    #[serde(default)]
    gamma: f64,
}

fn problem(detail: impl Into<String>, field: &str) -> Problem {
    Problem::new("invalid_type", detail).with_field(field)
}

fn parse_ec_level(text: &str, field: &str) -> Result<EcLevel, Problem> {
    match text.to_ascii_uppercase().as_str() {
        "L" => Ok(EcLevel::L),
        "M" => Ok(EcLevel::M),
        "Q" => Ok(EcLevel::Q),
        "H" => Ok(EcLevel::H),
        other => Err(problem(format!("unknown ec level {other}"), field)),
    }
}

fn scene(args: &RenderArgs) -> Result<Scene, Problem> {
    let [width_px, height_px] = image_size(args);
    let spec = CameraSpec {
        fx_px: args.fx_px.unwrap_or(DEFAULT_FOCAL_PX),
        fy_px: args.fy_px.unwrap_or(DEFAULT_FOCAL_PX),
        cx_px: args.cx_px,
        cy_px: args.cy_px,
        distortion: args
            .distortion_coefficients
            .as_ref()
            .map(|coefficients| DistortionSpec {
                model: args.distortion_model.unwrap_or_default(),
                coefficients: coefficients.clone(),
            }),
    };
    let camera = camera(&spec, width_px, height_px, "distortion_coefficients")?;
    let marker = Marker::try_new(args.marker_size_mm).map_err(|e| {
        Problem::new("invalid_marker_size", e.to_string()).with_field("marker_size_mm")
    })?;
    let ec_level = parse_ec_level(&args.ec_level, "ec_level")?;
    let r = EulerXyz::from_degrees(args.alpha_deg, args.beta_deg, args.gamma_deg).to_rotation();
    let centre = nalgebra::Vector3::new(args.x_mm, args.y_mm, args.z_mm);
    Ok(Scene {
        payload: args.payload.as_bytes().to_vec(),
        ec_level,
        marker,
        camera,
        width_px,
        height_px,
        pose: marker.pose_centred_at(r, centre),
    })
}

/// The scene of a scene file, with its codes as written.
fn file_scene(file: SceneFile) -> Result<(MultiScene, Vec<CodeSpec>), Problem> {
    let camera = camera(
        &file.camera,
        file.width_px,
        file.height_px,
        "/camera/distortion/coefficients",
    )?;
    let mut codes = Vec::with_capacity(file.codes.len());
    for (i, c) in file.codes.iter().enumerate() {
        let marker = Marker::try_new(c.size_mm).map_err(|e| {
            Problem::new("invalid_marker_size", e.to_string())
                .with_field(format!("/codes/{i}/size_mm"))
        })?;
        let ec_level = parse_ec_level(&c.ec_level, &format!("/codes/{i}/ec_level"))?;
        let e = &c.rotation_euler_xyz_deg;
        let r = EulerXyz::from_degrees(e.alpha, e.beta, e.gamma).to_rotation();
        codes.push(CodePlacement {
            payload: c.payload.as_bytes().to_vec(),
            ec_level,
            marker,
            pose: marker.pose_centred_at(r, nalgebra::Vector3::from(c.position_mm)),
        });
    }
    let scene = MultiScene {
        camera,
        width_px: file.width_px,
        height_px: file.height_px,
        codes,
    };
    Ok((scene, file.codes))
}

/// A placed code as a scene file would write it (centre and Euler angles of its pose).
fn spec_of(code: &CodePlacement) -> CodeSpec {
    let centre = code.pose.transform(&code.marker.centre()).0;
    let [alpha, beta, gamma] = EulerXyz::from_rotation(&code.pose.rotation()).to_degrees();
    CodeSpec {
        payload: String::from_utf8_lossy(&code.payload).into_owned(),
        ec_level: format!("{:?}", code.ec_level),
        size_mm: code.marker.size_mm(),
        position_mm: [centre.x, centre.y, centre.z],
        rotation_euler_xyz_deg: EulerSpec { alpha, beta, gamma },
    }
}

/// Reads and parses a scene file.
fn read_scene_file(path: &Path) -> Result<(MultiScene, Vec<CodeSpec>), Failure> {
    let text = std::fs::read(path)
        .map_err(|e| Failure::Other(format!("cannot read {}: {e}", path.display())))?;
    Ok(file_scene(parse_json::<SceneFile>(&text)?)?)
}

/// `render --scene` and `render --random-scene`: several codes, every one under `codes`.
fn run_multi(args: &RenderArgs, effects: &Effects) -> Result<Value, Failure> {
    let (scene, specs, source) = if let Some(path) = &args.scene {
        let (scene, specs) = read_scene_file(path)?;
        (scene, specs, json!({"file": path}))
    } else {
        let seed = args.random_scene.unwrap_or_default();
        let [width_px, height_px] = image_size(args);
        let ranges = SceneRanges {
            width_px,
            height_px,
            quiet_zone_modules: effects.quiet_zone_modules,
            ..SceneRanges::default()
        };
        let scene =
            random_scene(seed, &ranges).map_err(|e| Problem::new("invalid_type", e.to_string()))?;
        let specs = scene.codes.iter().map(spec_of).collect();
        (scene, specs, json!({"random_seed": seed}))
    };
    let rendered =
        render_scene(&scene, effects).map_err(|e| Problem::new("invalid_type", e.to_string()))?;
    write_image(&args.out, &rendered.encoded)?;
    let codes: Vec<_> = scene
        .codes
        .iter()
        .zip(specs)
        .zip(&rendered.truth)
        .map(|((code, spec), truth)| {
            json!({
                "payload": spec.payload,
                "ec_level": code.ec_level,
                "size_mm": spec.size_mm,
                "position_mm": spec.position_mm,
                "rotation_euler_xyz_deg": spec.rotation_euler_xyz_deg,
                "truth": truth,
            })
        })
        .collect();
    Ok(json!({
        "image": {"path": args.out, "width_px": scene.width_px, "height_px": scene.height_px},
        "scene": source,
        "camera": camera_json(&scene.camera),
        "effects": effects,
        "codes": codes,
    }))
}

/// Writes the encoded image to `path`.
fn write_image(path: &Path, encoded: &[u8]) -> Result<(), Failure> {
    std::fs::write(path, encoded)
        .map_err(|e| Failure::Other(format!("cannot write {}: {e}", path.display())))
}

/// The image size of a photo: the flags, or 1280 × 720.
fn image_size(args: &RenderArgs) -> [u32; 2] {
    [
        args.width_px.unwrap_or(DEFAULT_SIZE_PX[0]),
        args.height_px.unwrap_or(DEFAULT_SIZE_PX[1]),
    ]
}

/// Runs `render`: the JSON to print.
pub(super) fn run(args: &RenderArgs) -> Result<Value, Failure> {
    if let Some(value) = &args.video.sequence {
        return sequence::run(value, args);
    }
    let png = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let defaults = Effects::default();
    let effects = Effects {
        supersample: args.supersample.unwrap_or(defaults.supersample),
        blur_px: args.blur_px.unwrap_or(defaults.blur_px),
        noise: args.noise.unwrap_or(defaults.noise),
        lighting: args.lighting.unwrap_or(defaults.lighting),
        clutter: args.clutter,
        encoding: if png {
            Encoding::Png
        } else {
            Encoding::Jpeg(args.jpeg_quality.unwrap_or(DEFAULT_JPEG_QUALITY))
        },
        seed: args.seed.unwrap_or(defaults.seed),
        ..defaults
    };
    if args.pick.requested() {
        return pick::run(args, &effects);
    }
    if let Some(session) = &args.hand_eye {
        return hand_eye::run(session, &args.out, &effects);
    }
    if args.scene.is_some() || args.random_scene.is_some() {
        return run_multi(args, &effects);
    }
    let scene = scene(args)?;
    let rendered =
        render(&scene, &effects).map_err(|e| Problem::new("invalid_type", e.to_string()))?;
    write_image(&args.out, &rendered.encoded)?;
    Ok(json!({
        "image": {"path": args.out, "width_px": scene.width_px, "height_px": scene.height_px},
        "payload": args.payload,
        "camera": camera_json(&scene.camera),
        "marker": {"size_mm": scene.marker.size_mm()},
        "rotation_euler_xyz_deg": {"alpha": args.alpha_deg, "beta": args.beta_deg, "gamma": args.gamma_deg},
        "effects": effects,
        "truth": rendered.truth,
    }))
}
