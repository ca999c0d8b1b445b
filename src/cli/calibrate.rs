//! `qrpose calibrate --marker-size-mm 100 [--model M] [--out FILE.yaml] PHOTOS…`: the camera
//! calibrated from 3 to 100 photos of one printed QR code; prints what `POST /v1/calibrate`
//! returns and, with `--out`, writes its `opencv_yaml` (the file a site file's
//! `cameras.ID.calibration` reads as it is; docs/calibration.md).

use super::estimate::{print_json, report_problem};
use clap::Args;
use qrpose::api::calibrate::{CalibrateRequest, respond};
use qrpose::api::camera::DistortionModelDto;
use qrpose::api::request::MarkerDto;
use qrpose::app::ImageLimits;
use qrpose::detect::cancel::CancelFlag;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Side of the printed QR code, mm: outer edge of one finder pattern to the outer edge
    /// of the other, quiet zone excluded.
    #[arg(long, value_name = "MM")]
    pub marker_size_mm: f64,
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

/// Runs `calibrate`.
pub fn run(args: &CalibrateArgs) -> ExitCode {
    let mut photos = Vec::with_capacity(args.photos.len());
    for path in &args.photos {
        match std::fs::read(path) {
            Ok(bytes) => photos.push(bytes),
            Err(e) => {
                eprintln!("qrpose: cannot read {}: {e}", path.display());
                return ExitCode::FAILURE;
            }
        }
    }
    let request = CalibrateRequest {
        marker: MarkerDto {
            size_mm: args.marker_size_mm,
        },
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
