//! `qrpose estimate REQUEST.json|-`: one corners request in, the API's response out.
//! `qrpose estimate --image photo.jpg --fx-px … --marker-size-mm …`: one photo in, what
//! `POST /v1/pose/image` returns out; with `--annotate OUT`, also the photo with the
//! overlay of `POST /v1/pose/image/annotated` written to OUT.

use super::{EXIT_BAD_INPUT, EXIT_BROKEN_PIPE};
use clap::Args;
use qrpose::annotate::{OutputFormat, annotated_image};
use qrpose::api::{
    estimate_corners,
    image::{ImageQuery, answer},
    problem::{Problem, parse_json},
};
use qrpose::app::{ImageAnswer, ImageLimits, ImageSetup, Site};
use qrpose::detect::cancel::CancelFlag;
use qrpose::geometry::camera::Camera;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

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
    /// With `--image`: also write the photo with every code's outline, corners, payload and
    /// axes drawn on it, as `POST /v1/pose/image/annotated` returns it; PNG when OUT ends in
    /// `.png`, else JPEG.
    #[arg(long, value_name = "OUT", requires = "image")]
    pub annotate: Option<PathBuf>,
    /// A site file (docs/site.md): `camera.id` / `--camera-id` name its cameras, and a
    /// marker size omitted from the request comes from its rules for the payload.
    #[arg(long, value_name = "FILE")]
    pub site: Option<PathBuf>,
    /// With `--image`: the arm's pose when the photo was taken (T_robot←flange, as the
    /// controller reports it), a JSON object as in a request's `flange_pose`
    /// (`{"translation_mm": [...], "quaternion_wxyz": [...]}`; docs/pick.md).
    #[arg(long, value_name = "JSON", requires = "image")]
    pub flange_pose: Option<String>,
    /// With `--image`: the least probability of landing within tolerance for a grasp to be
    /// `graspable` (default 0.95).
    #[arg(long, value_name = "P", requires = "image")]
    pub min_grasp_probability: Option<f64>,
    /// The camera, marker, solver and detector of `--image`: the query parameters of
    /// `POST /v1/pose/image`, one flag each, under the same names (`fx_px` is `--fx-px`).
    #[command(flatten)]
    pub params: ImageQuery,
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

/// The setup of `estimate --image`: the flags as the query parameters, with the arm's pose
/// and the grasp bar as a request part would give them.
fn image_setup(args: &EstimateArgs, site: Option<Arc<Site>>) -> Result<ImageSetup, Problem> {
    let mut request = args
        .params
        .clone()
        .into_request()
        .map_err(ImageQuery::problem_in_query_terms)?;
    request.flange_pose = args
        .flange_pose
        .as_deref()
        .map(|json| parse_json(json.as_bytes()).map_err(|p| p.with_field("/flange_pose")))
        .transpose()?;
    request.min_grasp_probability = args.min_grasp_probability;
    request
        .setup(&ImageLimits::default(), site)
        .map_err(|problem| {
            // The picking flags are named by their request pointers; the rest as parameters.
            let picking = problem
                .field
                .as_deref()
                .is_some_and(|f| f.starts_with("/flange_pose") || f == "/min_grasp_probability");
            if picking {
                problem
            } else {
                ImageQuery::problem_in_query_terms(problem)
            }
        })
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
    let site = match super::site::load_optional(args.site.as_deref()) {
        Ok(site) => site.map(Arc::new),
        Err(code) => return code,
    };
    let setup = match image_setup(args, site) {
        Ok(setup) => setup,
        Err(problem) => return report_problem(&problem),
    };
    match answer(&setup, &bytes, CancelFlag::new()) {
        Ok((answer, response)) => {
            if let Some(out) = &args.annotate
                && let Err(code) = write_annotated(&bytes, &answer, &setup.pose.camera, out)
            {
                return code;
            }
            print_json(&response, args.pretty)
        }
        Err(problem) => report_problem(&problem),
    }
}

/// Writes the annotated photo of `--annotate`: the poses of `answer`, computed with
/// `camera`, drawn on the photo `bytes`.
fn write_annotated(
    bytes: &[u8],
    answer: &ImageAnswer,
    camera: &Camera,
    out: &Path,
) -> Result<(), ExitCode> {
    let format = OutputFormat::from_file_name(out);
    let image = annotated_image(bytes, answer, camera, format).map_err(|e| {
        eprintln!("qrpose: cannot annotate {}: {e}", out.display());
        ExitCode::FAILURE
    })?;
    std::fs::write(out, image).map_err(|e| {
        eprintln!("qrpose: cannot write {}: {e}", out.display());
        ExitCode::FAILURE
    })
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
    let site = match super::site::load_optional(args.site.as_deref()) {
        Ok(site) => site.map(Arc::new),
        Err(code) => return code,
    };
    match parse_json(&bytes).and_then(|request| estimate_corners(&request, site)) {
        Ok(response) => print_json(&response, args.pretty),
        Err(problem) => report_problem(&problem),
    }
}
