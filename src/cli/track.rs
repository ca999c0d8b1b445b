//! `qrpose track FRAMES…`: the stream's tracker over a list of frames (files in the order
//! given, or a directory's JPEG and PNG files sorted by name), one JSON line per frame: what
//! `GET /v1/stream` answers for it, for offline logs and tests.

use super::estimate::report_problem;
use clap::Args;
use qrpose::api::image::ImageQuery;
use qrpose::api::problem::{ErrorCode, Problem, parse_json};
use qrpose::api::refusal::problem_from_image_error;
use qrpose::api::robot::RobotPoseDto;
use qrpose::api::stream::{FrameDto, FrameIdDto, FrameProblem, StreamAnswer, TrackQuery};
use qrpose::app::{FrameIn, ImageLimits, TrackSession};
use qrpose::detect::cancel::CancelFlag;
use qrpose_site::transform::Rigid;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

/// The frame rate assumed for capture times when none is given, frames per second.
pub const DEFAULT_FPS: f64 = 30.0;

/// Arguments of `track`.
#[derive(Debug, Args)]
pub struct TrackArgs {
    /// The frames: image files in this order, or one directory (its `.jpg`, `.jpeg` and
    /// `.png` files, sorted by name).
    #[arg(required = true)]
    pub frames: Vec<PathBuf>,
    /// Frame rate, fps: frame k was captured at k × 1000 / fps ms.
    #[arg(long, default_value_t = DEFAULT_FPS)]
    pub fps: f64,
    /// A site file (docs/site.md): `--camera-id` names its cameras, and it sizes the codes.
    #[arg(long, value_name = "FILE")]
    pub site: Option<PathBuf>,
    /// A JSON file: the arm's pose (T_robot←flange) when each frame was captured, an array
    /// with one robot pose per frame in order (docs/pick.md, Streams).
    #[arg(long, value_name = "POSES.json")]
    pub flange_poses: Option<PathBuf>,
    /// The camera, marker, solver and detector: the query parameters of `GET /v1/stream`.
    #[command(flatten)]
    pub params: ImageQuery,
    /// The tracker's parameters.
    #[command(flatten)]
    pub tracker: TrackQuery,
}

/// The frames named by `paths`: the files, or a directory's images sorted by name.
fn frame_files(paths: &[PathBuf]) -> std::io::Result<Vec<PathBuf>> {
    if let [dir] = paths
        && dir.is_dir()
    {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)?
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| is_image_name(p))
            .collect();
        files.sort();
        return Ok(files);
    }
    Ok(paths.to_vec())
}

fn is_image_name(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| ["jpg", "jpeg", "png"].contains(&e.to_ascii_lowercase().as_str()))
}

/// Runs `track`.
pub fn run(args: &TrackArgs) -> ExitCode {
    if !(args.fps.is_finite() && args.fps > 0.0) {
        let problem = Problem::new(
            ErrorCode::MalformedQuery,
            format!("--fps must be a positive number, got {}", args.fps),
        )
        .with_field("fps");
        return report_problem(&problem);
    }
    let site = match super::site::load_optional(args.site.as_deref()) {
        Ok(site) => site.map(Arc::new),
        Err(code) => return code,
    };
    let setup = match args
        .tracker
        .setup(args.params.clone(), &ImageLimits::default(), site)
    {
        Ok(setup) => setup,
        Err(problem) => return report_problem(&problem),
    };
    let mut session = match TrackSession::new(setup) {
        Ok(session) => session,
        Err(e) => {
            let problem = Problem::new(ErrorCode::InvalidTrackerParameter, e.to_string());
            return report_problem(&problem);
        }
    };
    let files = match frame_files(&args.frames) {
        Ok(files) => files,
        Err(e) => {
            eprintln!("qrpose track: cannot list the frames: {e}");
            return ExitCode::FAILURE;
        }
    };
    let flanges = match flange_poses(args.flange_poses.as_deref(), files.len()) {
        Ok(flanges) => flanges,
        Err(code) => return code,
    };
    let mut stdout = std::io::stdout().lock();
    for ((index, file), flange) in (0u64..).zip(&files).zip(flanges) {
        let capture_time_ms = f64::from(u32::try_from(index).unwrap_or(u32::MAX)) * 1e3 / args.fps;
        let frame = FrameDto {
            index,
            id: Some(FrameIdDto::Text(file.display().to_string())),
            capture_time_ms,
            dropped_before: 0,
        };
        let line = match std::fs::read(file) {
            Ok(bytes) => answer_line(&mut session, &bytes, capture_time_ms, flange, frame),
            Err(e) => {
                eprintln!("qrpose track: cannot read {}: {e}", file.display());
                return ExitCode::FAILURE;
            }
        };
        match line.and_then(|l| writeln!(stdout, "{l}").map_err(|e| e.to_string())) {
            Ok(()) => {}
            Err(e) => {
                eprintln!("qrpose track: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    ExitCode::SUCCESS
}

/// The flange pose of each of `frames` frames from `path` (none: `None` for each).
fn flange_poses(path: Option<&Path>, frames: usize) -> Result<Vec<Option<Rigid>>, ExitCode> {
    let Some(path) = path else {
        return Ok(vec![None; frames]);
    };
    let bytes = std::fs::read(path).map_err(|e| {
        eprintln!("qrpose track: cannot read {}: {e}", path.display());
        ExitCode::FAILURE
    })?;
    let poses: Vec<RobotPoseDto> =
        parse_json(&bytes).map_err(|p| report_problem(&p.with_field("/flange_poses")))?;
    if poses.len() != frames {
        let problem = Problem::new(
            ErrorCode::FlangePosesMismatch,
            format!(
                "{frames} frames and {} flange poses: give one per frame",
                poses.len()
            ),
        )
        .with_field("/flange_poses");
        return Err(report_problem(&problem));
    }
    poses
        .iter()
        .enumerate()
        .map(|(k, pose)| pose.to_rigid(&format!("/flange_poses/{k}")).map(Some))
        .collect::<Result<_, _>>()
        .map_err(|p| report_problem(&p))
}

/// One frame's JSON line: its answer, or its problem (the session goes on).
fn answer_line(
    session: &mut TrackSession,
    bytes: &[u8],
    capture_time_ms: f64,
    flange: Option<Rigid>,
    frame: FrameDto,
) -> Result<String, String> {
    let input = FrameIn {
        bytes,
        capture_time_ms,
        prior: None,
        flange,
    };
    let json = match session.frame(&input, CancelFlag::new()) {
        Ok(answer) => serde_json::to_string(&StreamAnswer::from_answer(
            &answer,
            &session.setup().image,
            frame,
        )),
        Err(e) => serde_json::to_string(&FrameProblem {
            frame,
            problem: problem_from_image_error(&e),
        }),
    };
    json.map_err(|e| format!("cannot serialise an answer: {e}"))
}
