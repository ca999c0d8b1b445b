//! `qrpose estimate REQUEST.json|-`: one corners request in, the API's response out.
//! `qrpose estimate --image photo.jpg --fx-px … --marker-size-mm …`: one photo in, what
//! `POST /v1/pose/image` returns out.

use super::{EXIT_BAD_INPUT, EXIT_BROKEN_PIPE};
use clap::Args;
use qrpose::api::{
    estimate_corners,
    image::{ImageQuery, estimate_image},
    problem::{ErrorCode, Problem, parse_json},
};
use qrpose::detect::decode::DecodeLimits;
use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `estimate`.
#[derive(Debug, Args)]
pub struct EstimateArgs {
    /// A `/v1/pose/corners` request body (JSON file), or `-` for standard input.
    #[arg(required_unless_present = "image", conflicts_with = "image")]
    pub request: Option<PathBuf>,
    /// Indent the output.
    #[arg(long)]
    pub pretty: bool,
    /// A photo (JPEG, PNG or WebP): find every QR code, print what `POST /v1/pose/image`
    /// returns.
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// The camera, marker, solver and detector of `--image`.
    #[command(flatten)]
    pub params: ImageParams,
}

/// The query parameters of `POST /v1/pose/image`, as flags.
#[derive(Debug, Args, Default)]
pub struct ImageParams {
    /// Horizontal focal length, px.
    #[arg(long)]
    pub fx_px: Option<f64>,
    /// Vertical focal length, px.
    #[arg(long)]
    pub fy_px: Option<f64>,
    /// Principal point, horizontal, px (integer = pixel centre).
    #[arg(long, allow_negative_numbers = true)]
    pub cx_px: Option<f64>,
    /// Principal point, vertical, px.
    #[arg(long, allow_negative_numbers = true)]
    pub cy_px: Option<f64>,
    /// Lens focal length, mm (with --pixel-size-um instead of --fx-px/--fy-px).
    #[arg(long)]
    pub focal_length_mm: Option<f64>,
    /// Pixel pitch, µm.
    #[arg(long)]
    pub pixel_size_um: Option<f64>,
    /// Radial distortion k1 (OpenCV's meaning).
    #[arg(long, allow_negative_numbers = true)]
    pub k1: Option<f64>,
    /// Radial distortion k2.
    #[arg(long, allow_negative_numbers = true)]
    pub k2: Option<f64>,
    /// Radial distortion k3.
    #[arg(long, allow_negative_numbers = true)]
    pub k3: Option<f64>,
    /// Tangential distortion p1.
    #[arg(long, allow_negative_numbers = true)]
    pub p1: Option<f64>,
    /// Tangential distortion p2.
    #[arg(long, allow_negative_numbers = true)]
    pub p2: Option<f64>,
    /// Side of the QR symbol, mm (finder edge to finder edge, quiet zone excluded).
    #[arg(long)]
    pub marker_size_mm: Option<f64>,
    /// Solver: paper, depth-newton or reprojection (default).
    #[arg(long)]
    pub method: Option<String>,
    /// Detector: auto (default), rqrr, rxing, zxing-cpp.
    #[arg(long)]
    pub detector: Option<String>,
    /// Points to solve from: corners or finders.
    #[arg(long)]
    pub points: Option<String>,
    /// Iteration limit of the solver.
    #[arg(long)]
    pub max_iterations: Option<u64>,
    /// Corner noise σ for the covariance, px.
    #[arg(long)]
    pub corner_sigma_px: Option<f64>,
}

/// Parses an enumerated flag as its JSON string form, naming the flag on failure.
fn parse_variant<T: serde::de::DeserializeOwned>(
    value: Option<&String>,
    flag: &str,
) -> Result<Option<T>, Problem> {
    value
        .map(|v| {
            serde_json::from_value(serde_json::Value::String(v.clone())).map_err(|e| {
                Problem::new(ErrorCode::UnknownVariant, format!("--{flag}: {e}")).with_field(flag)
            })
        })
        .transpose()
}

impl ImageParams {
    /// The query these flags stand for.
    ///
    /// # Errors
    /// `unknown_variant` for a bad --method, --detector or --points.
    pub fn to_query(&self) -> Result<ImageQuery, Problem> {
        Ok(ImageQuery {
            fx_px: self.fx_px,
            fy_px: self.fy_px,
            cx_px: self.cx_px,
            cy_px: self.cy_px,
            focal_length_mm: self.focal_length_mm,
            pixel_size_um: self.pixel_size_um,
            k1: self.k1,
            k2: self.k2,
            k3: self.k3,
            p1: self.p1,
            p2: self.p2,
            marker_size_mm: self.marker_size_mm,
            method: parse_variant(self.method.as_ref(), "method")?,
            detector: parse_variant(self.detector.as_ref(), "detector")?,
            points: parse_variant(self.points.as_ref(), "points")?,
            max_iterations: self.max_iterations,
            corner_sigma_px: self.corner_sigma_px,
            ..ImageQuery::default()
        })
    }
}

fn read_input(path: &PathBuf) -> std::io::Result<Vec<u8>> {
    if path.as_os_str() == "-" {
        let mut buf = Vec::new();
        std::io::stdin().read_to_end(&mut buf)?;
        Ok(buf)
    } else {
        std::fs::read(path)
    }
}

/// Prints a problem document on stderr and returns the bad-input exit code.
pub fn report_problem(problem: &Problem) -> ExitCode {
    match serde_json::to_string_pretty(problem) {
        Ok(json) => eprintln!("{json}"),
        Err(_) => eprintln!("{}: {}", problem.title, problem.detail),
    }
    ExitCode::from(EXIT_BAD_INPUT)
}

/// Prints a value as JSON on stdout.
pub fn print_json<T: serde::Serialize>(value: &T, pretty: bool) -> ExitCode {
    let json = if pretty {
        serde_json::to_string_pretty(value)
    } else {
        serde_json::to_string(value)
    };
    match json {
        Ok(json) => {
            // `println!` panics when stdout is gone (`qrpose estimate … | head -c 10`);
            // a closed pipe is the reader's choice, so stop quietly with its exit code.
            let mut stdout = std::io::stdout().lock();
            match writeln!(stdout, "{json}").and_then(|()| stdout.flush()) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                    ExitCode::from(EXIT_BROKEN_PIPE)
                }
                Err(e) => {
                    eprintln!("qrpose: cannot write the response: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Err(e) => {
            eprintln!("qrpose: cannot serialise the response: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs `estimate --image`.
fn run_image(path: &PathBuf, args: &EstimateArgs) -> ExitCode {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("qrpose: cannot read {}: {e}", path.display());
            return ExitCode::FAILURE;
        }
    };
    let result = args
        .params
        .to_query()
        .and_then(ImageQuery::into_request)
        .and_then(|request| estimate_image(&bytes, &request, &DecodeLimits::default()));
    match result {
        Ok(response) => print_json(&response, args.pretty),
        Err(problem) => report_problem(&problem),
    }
}

/// Runs `estimate`.
pub fn run(args: &EstimateArgs) -> ExitCode {
    if let Some(image) = &args.image {
        return run_image(image, args);
    }
    let Some(request) = &args.request else {
        eprintln!("qrpose: give a request file or --image");
        return ExitCode::FAILURE;
    };
    let bytes = match read_input(request) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("qrpose: cannot read {}: {e}", request.display());
            return ExitCode::FAILURE;
        }
    };
    match parse_json(&bytes).and_then(|request| estimate_corners(&request)) {
        Ok(response) => print_json(&response, args.pretty),
        Err(problem) => report_problem(&problem),
    }
}
