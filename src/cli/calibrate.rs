//! `qrpose calibrate --marker-size-mm 100 [--model M] [--out FILE.yaml] PHOTOS…`: the camera
//! calibrated from 3 to 100 photos of one printed QR code; prints what `POST /v1/calibrate`
//! returns and, with `--out`, writes its `opencv_yaml` (the file a site file's
//! `cameras.ID.calibration` reads as it is; docs/calibration.md).
//!
//! `qrpose calibrate hand-eye --setup eye-in-hand --flange-poses POSES.json [camera flags |
//! --site FILE --camera-id ID] [--marker-size-mm S] PHOTOS…`: the camera's pose on the robot
//! from photos and the flange pose of each; prints what `POST /v1/calibrate/hand-eye`
//! returns (docs/hand-eye.md).

use super::estimate::{print_json, report_problem};
use clap::{Args, Subcommand};
use qrpose::api::calibrate::{CalibrateRequest, respond};
use qrpose::api::camera::{CameraDto, DistortionDto, DistortionModelDto};
use qrpose::api::hand_eye::{FlangeNoiseDto, HandEyeRequest, HandEyeSetupDto};
use qrpose::api::problem::{Problem, parse_json};
use qrpose::api::request::MarkerDto;
use qrpose::api::robot::RobotPoseDto;
use qrpose::app::ImageLimits;
use qrpose::detect::cancel::CancelFlag;
use qrpose_calib::handeye::{DEFAULT_FLANGE_ROTATION_STD_RAD, DEFAULT_FLANGE_TRANSLATION_STD_MM};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

/// Arguments of `calibrate`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct CalibrateArgs {
    /// `hand-eye`: the camera's pose on a robot instead of the camera's intrinsics.
    #[command(subcommand)]
    pub what: Option<CalibrateWhat>,
    /// Side of the printed QR code, mm: outer edge of one finder pattern to the outer edge
    /// of the other, quiet zone excluded.
    #[arg(long, value_name = "MM", required = true)]
    pub marker_size_mm: Option<f64>,
    /// The lens model to fit, as the site file names it.
    #[arg(long, value_enum, default_value_t)]
    pub model: DistortionModelDto,
    /// Also write the calibration as an OpenCV `FileStorage` YAML file here.
    #[arg(long, value_name = "FILE.yaml")]
    pub out: Option<PathBuf>,
    /// Indent the output.
    #[arg(long)]
    pub pretty: bool,
    /// The photos (JPEG, PNG or WebP), 3 to 100, from one camera at one resolution, each
    /// showing the printed code from another position and angle.
    #[arg(required = true, value_name = "PHOTOS")]
    pub photos: Vec<PathBuf>,
}

/// What else `calibrate` calibrates.
#[derive(Debug, Subcommand)]
pub enum CalibrateWhat {
    /// The camera's pose on a robot arm from 4 to 100 photos of a printed code and the
    /// flange pose of each: prints what `POST /v1/calibrate/hand-eye` returns.
    HandEye(HandEyeArgs),
}

/// Arguments of `calibrate hand-eye`.
#[derive(Debug, Args)]
pub struct HandEyeArgs {
    /// Where the camera is: on the flange, or standing still with the code on the flange.
    #[arg(long, value_enum)]
    pub setup: HandEyeSetupArg,
    /// A JSON file: the array of flange poses (T_robot←flange), one per photo in order, each
    /// `{"translation_mm": [...], "quaternion_wxyz" | "rotation_vector_rad" |
    /// "euler_zyx_deg": [...]}` (docs/hand-eye.md).
    #[arg(long, value_name = "POSES.json")]
    pub flange_poses: PathBuf,
    /// The controller's flange position noise (repeatability), mm per axis (default 0.2).
    #[arg(long, value_name = "MM")]
    pub flange_noise_mm: Option<f64>,
    /// The controller's flange rotation noise, degrees per axis (default 0.02).
    #[arg(long, value_name = "DEG")]
    pub flange_noise_deg: Option<f64>,
    /// Side of the printed code, mm; may be omitted when `--site` sizes its payload.
    #[arg(long, value_name = "MM")]
    pub marker_size_mm: Option<f64>,
    /// A site file (docs/site.md): `--camera-id` names its cameras, its rules size the code.
    #[arg(long, value_name = "FILE")]
    pub site: Option<PathBuf>,
    /// A camera of the site, instead of the intrinsics.
    #[arg(long, value_name = "ID", requires = "site")]
    pub camera_id: Option<String>,
    /// Focal length along u, px.
    #[arg(long)]
    pub fx_px: Option<f64>,
    /// Focal length along v, px.
    #[arg(long)]
    pub fy_px: Option<f64>,
    /// Principal point u, px.
    #[arg(long)]
    pub cx_px: Option<f64>,
    /// Principal point v, px.
    #[arg(long)]
    pub cy_px: Option<f64>,
    /// The lens model of the coefficients below.
    #[arg(long, value_enum)]
    pub distortion_model: Option<DistortionModelDto>,
    /// The distortion coefficients in the model's order (OpenCV's), comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        value_name = "K1,K2,…"
    )]
    pub distortion_coefficients: Vec<f64>,
    /// Indent the output.
    #[arg(long)]
    pub pretty: bool,
    /// The photos (JPEG, PNG or WebP), 4 to 100, in the order of the flange poses.
    #[arg(required = true, value_name = "PHOTOS")]
    pub photos: Vec<PathBuf>,
}

/// `--setup`'s values.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum HandEyeSetupArg {
    /// The camera rides on the flange.
    EyeInHand,
    /// The camera stands still; the flange holds the code.
    EyeToHand,
}

/// Reads every photo, or says which could not be read.
fn read_photos(paths: &[PathBuf]) -> Result<Vec<Vec<u8>>, ExitCode> {
    paths
        .iter()
        .map(|path| {
            std::fs::read(path).map_err(|e| {
                eprintln!("qrpose: cannot read {}: {e}", path.display());
                ExitCode::FAILURE
            })
        })
        .collect()
}

/// The camera the flags give, as a request's `camera`.
fn camera_of(args: &HandEyeArgs) -> Result<CameraDto, Problem> {
    let distortion = (args.distortion_model.is_some() || !args.distortion_coefficients.is_empty())
        .then(|| {
            DistortionDto::from_coefficients(
                args.distortion_model.unwrap_or_default(),
                &args.distortion_coefficients,
            )
        })
        .transpose()?;
    Ok(CameraDto {
        id: args.camera_id.clone(),
        fx_px: args.fx_px,
        fy_px: args.fy_px,
        cx_px: args.cx_px,
        cy_px: args.cy_px,
        distortion,
        ..CameraDto::default()
    })
}

/// The hand-eye request the flags and the poses file give.
fn hand_eye_request(args: &HandEyeArgs) -> Result<HandEyeRequest, ExitCode> {
    let poses = std::fs::read(&args.flange_poses).map_err(|e| {
        eprintln!("qrpose: cannot read {}: {e}", args.flange_poses.display());
        ExitCode::FAILURE
    })?;
    let flange_poses: Vec<RobotPoseDto> =
        parse_json(&poses).map_err(|p| report_problem(&p.with_field("/flange_poses")))?;
    Ok(HandEyeRequest {
        setup: match args.setup {
            HandEyeSetupArg::EyeInHand => HandEyeSetupDto::EyeInHand,
            HandEyeSetupArg::EyeToHand => HandEyeSetupDto::EyeToHand,
        },
        camera: camera_of(args).map_err(|p| report_problem(&p))?,
        marker: args.marker_size_mm.map(|size_mm| MarkerDto { size_mm }),
        flange_poses,
        flange_noise: match (args.flange_noise_mm, args.flange_noise_deg) {
            (None, None) => None,
            (mm, deg) => Some(FlangeNoiseDto {
                translation_mm: mm.unwrap_or(DEFAULT_FLANGE_TRANSLATION_STD_MM),
                rotation_deg: deg.unwrap_or(DEFAULT_FLANGE_ROTATION_STD_RAD.to_degrees()),
            }),
        },
    })
}

/// Runs `calibrate hand-eye`.
fn run_hand_eye(args: &HandEyeArgs) -> ExitCode {
    let site = match super::site::load_optional(args.site.as_deref()) {
        Ok(site) => site.map(Arc::new),
        Err(code) => return code,
    };
    let photos = match read_photos(&args.photos) {
        Ok(photos) => photos,
        Err(code) => return code,
    };
    let request = match hand_eye_request(args) {
        Ok(request) => request,
        Err(code) => return code,
    };
    match qrpose::api::hand_eye::respond(
        &request,
        &ImageLimits::default(),
        site.as_ref(),
        &photos,
        &CancelFlag::new(),
    ) {
        Ok(response) => print_json(&response, args.pretty),
        Err(problem) => report_problem(&problem),
    }
}

/// Runs `calibrate`.
pub fn run(args: &CalibrateArgs) -> ExitCode {
    if let Some(CalibrateWhat::HandEye(hand_eye)) = &args.what {
        return run_hand_eye(hand_eye);
    }
    let Some(size_mm) = args.marker_size_mm else {
        eprintln!("qrpose: calibrate needs --marker-size-mm");
        return ExitCode::from(2);
    };
    let photos = match read_photos(&args.photos) {
        Ok(photos) => photos,
        Err(code) => return code,
    };
    let request = CalibrateRequest {
        marker: MarkerDto { size_mm },
        model: args.model,
    };
    match respond(
        &request,
        &ImageLimits::default(),
        &photos,
        &CancelFlag::new(),
    ) {
        Ok(response) => {
            if let Some(out) = &args.out
                && let Err(e) = std::fs::write(out, &response.opencv_yaml)
            {
                eprintln!("qrpose: cannot write {}: {e}", out.display());
                return ExitCode::FAILURE;
            }
            print_json(&response, args.pretty)
        }
        Err(problem) => report_problem(&problem),
    }
}
