//! `qrpose-sim render --sequence NAME|FILE.json --out DIR`: rendered video with its truth
//! (docs/rendering.md). The frames go to DIR as `frame_00000.jpg`, … (JPEG at the
//! sequence's quality), or with `--y4m FILE` into one YUV4MPEG2 video; DIR also gets
//! `truth.jsonl` (one line per frame: index, capture time, camera pose, every code in view)
//! and `sequence.json` (the sequence as rendered, overrides applied, loadable again). A
//! summary goes to stdout as JSON.
//!
//! The camera and effect flags of `render`, when given, override the sequence's
//! (`--width-px`, `--fx-px`, …, `--distortion-coefficients`; `--supersample`, `--blur-px`,
//! `--noise`, `--lighting`, `--jpeg-quality`, `--seed`), as do `--frames` and `--fps`.

use super::RenderArgs;
use super::camera::camera_json;
use crate::cli::Failure;
use crate::cli::problem::{Problem, parse_json};
use crate::render::encode;
use crate::render::sequence::{
    BUILTIN_SEQUENCES, DistortionSpec, Frame, Sequence, SequenceSpec, Y4mColour, Y4mWriter,
    builtin_sequence,
};
use clap::Args;
use qrpose_core::geometry::camera::DistortionModel;
use serde_json::{Value, json};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The flags `--sequence` cannot be mixed with (the camera and effect flags override the
/// sequence's instead).
const SEQUENCE_CONFLICTS: [&str; 12] = [
    "scene",
    "random_scene",
    "clutter",
    "payload",
    "ec_level",
    "marker_size_mm",
    "x_mm",
    "y_mm",
    "z_mm",
    "alpha_deg",
    "beta_deg",
    "gamma_deg",
];

/// The flags of `render --sequence` (the rest of `render`'s flags are in [`RenderArgs`]).
#[derive(Debug, Args)]
pub struct SequenceArgs {
    /// Render a video instead of a photo: a built-in sequence (`approach`, `still`, `pan`)
    /// or a JSON sequence file (docs/rendering.md). Writes --out/frame_00000.jpg, … (or the
    /// --y4m video), --out/truth.jsonl (one line per frame: capture time, camera pose, every
    /// code in view) and --out/sequence.json; prints a summary. The camera and effect flags,
    /// when given, override the sequence's.
    #[arg(long, value_name = "NAME|FILE.json", conflicts_with_all = SEQUENCE_CONFLICTS)]
    pub sequence: Option<String>,
    /// With --sequence: write the frames into this YUV4MPEG2 file (4:2:0, `C420jpeg`, what
    /// Chromium's --use-file-for-fake-video-capture plays) instead of JPEG files.
    #[arg(long, value_name = "FILE.y4m", requires = "sequence")]
    pub y4m: Option<PathBuf>,
    /// With --y4m: the luma plane alone (`Cmono`; ffmpeg reads it, Chromium does not).
    #[arg(long, requires = "y4m")]
    pub y4m_mono: bool,
    /// With --sequence: the number of frames (after the path's last keyframe the camera
    /// stays there).
    #[arg(long, value_name = "N", requires = "sequence")]
    pub frames: Option<u32>,
    /// With --sequence: frames per second (the path keeps its timing).
    #[arg(long, requires = "sequence")]
    pub fps: Option<f64>,
}

/// Frames rendered at once (in parallel) before they are written in order.
const BATCH_FRAMES: u32 = 8;

/// The sequence a `--sequence` value names: a built-in, or else a JSON file.
fn load(value: &str) -> Result<SequenceSpec, Failure> {
    if let Some(spec) = builtin_sequence(value) {
        return Ok(spec);
    }
    let text = std::fs::read(Path::new(value)).map_err(|e| {
        Failure::Other(format!(
            "--sequence {value} is neither a built-in ({}) nor a readable file: {e}",
            BUILTIN_SEQUENCES.join(", ")
        ))
    })?;
    Ok(parse_json::<SequenceSpec>(&text)?)
}

/// The sequence with the flags given on the command line applied.
fn with_overrides(mut spec: SequenceSpec, args: &RenderArgs) -> SequenceSpec {
    let camera = &mut spec.camera;
    spec.width_px = args.width_px.unwrap_or(spec.width_px);
    spec.height_px = args.height_px.unwrap_or(spec.height_px);
    camera.fx_px = args.fx_px.unwrap_or(camera.fx_px);
    camera.fy_px = args.fy_px.unwrap_or(camera.fy_px);
    camera.cx_px = args.cx_px.or(camera.cx_px);
    camera.cy_px = args.cy_px.or(camera.cy_px);
    if let Some(coefficients) = &args.distortion_coefficients {
        camera.distortion = Some(DistortionSpec {
            model: DistortionModel::from(args.distortion_model.unwrap_or_default())
                .name()
                .to_owned(),
            coefficients: coefficients.clone(),
        });
    }
    let effects = &mut spec.effects;
    effects.supersample = args.supersample.unwrap_or(effects.supersample);
    effects.blur_px = args.blur_px.unwrap_or(effects.blur_px);
    effects.noise = args.noise.unwrap_or(effects.noise);
    effects.lighting = args.lighting.unwrap_or(effects.lighting);
    effects.jpeg_quality = args.jpeg_quality.unwrap_or(effects.jpeg_quality);
    spec.seed = args.seed.unwrap_or(spec.seed);
    spec.fps = args.video.fps.unwrap_or(spec.fps);
    if let Some(frames) = args.video.frames {
        spec.frames = Some(frames);
    }
    spec
}

/// The file name of frame `index`.
fn frame_name(index: u32) -> String {
    format!("frame_{index:05}.jpg")
}

/// Where the frames go: JPEG files in the output directory, or one `.y4m` video.
enum Sink {
    Jpeg,
    Y4m(Y4mWriter<BufWriter<File>>),
}

/// Writes one frame and returns its truth line.
fn write_frame(
    frame: &Frame,
    sequence: &Sequence,
    dir: &Path,
    sink: &mut Sink,
) -> Result<Value, String> {
    let mut line = serde_json::to_value(&frame.truth).map_err(|e| e.to_string())?;
    match sink {
        Sink::Jpeg => {
            let name = frame_name(frame.truth.index);
            let bytes = encode(&frame.image, sequence.encoding()).map_err(|e| e.to_string())?;
            std::fs::write(dir.join(&name), bytes)
                .map_err(|e| format!("cannot write {}: {e}", dir.join(&name).display()))?;
            if let Some(object) = line.as_object_mut() {
                object.insert("image".to_owned(), json!(name));
            }
        }
        Sink::Y4m(writer) => writer
            .write_frame(&frame.image)
            .map_err(|e| e.to_string())?,
    }
    Ok(line)
}

/// Renders every frame in batches, writing each batch in order; the count of code-frames
/// in view and of frames with at least one code entirely in view.
fn render_all(
    sequence: &Sequence,
    dir: &Path,
    sink: &mut Sink,
    truth: &mut impl Write,
) -> Result<(usize, u32), String> {
    let (mut code_frames, mut frames_with_codes) = (0, 0);
    let n = sequence.frame_count();
    let mut start = 0;
    while start < n {
        let end = start.saturating_add(BATCH_FRAMES).min(n);
        let frames = sequence
            .render_frames(start..end)
            .map_err(|e| e.to_string())?;
        for frame in &frames {
            let line = write_frame(frame, sequence, dir, sink)?;
            writeln!(truth, "{line}").map_err(|e| format!("cannot write the truth: {e}"))?;
            code_frames += frame.truth.codes.len();
            frames_with_codes += u32::from(frame.truth.codes.iter().any(|c| c.fully_in_view));
        }
        start = end;
    }
    Ok((code_frames, frames_with_codes))
}

/// Runs `render --sequence`.
pub(super) fn run(value: &str, args: &RenderArgs) -> Result<Value, Failure> {
    let spec = with_overrides(load(value)?, args);
    let sequence = Sequence::new(spec).map_err(|e| Problem::new("invalid_type", e.to_string()))?;
    write_all(&sequence, args).map_err(Failure::Other)
}

/// Writes the frames, `truth.jsonl` and `sequence.json`; the summary printed.
fn write_all(sequence: &Sequence, args: &RenderArgs) -> Result<Value, String> {
    let dir = args.out.as_path();
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let spec = sequence.spec();
    let spec_json = serde_json::to_string_pretty(spec).map_err(|e| e.to_string())?;
    let spec_path = dir.join("sequence.json");
    std::fs::write(&spec_path, spec_json + "\n")
        .map_err(|e| format!("cannot write {}: {e}", spec_path.display()))?;
    let colour = if args.video.y4m_mono {
        Y4mColour::Mono
    } else {
        Y4mColour::C420jpeg
    };
    let mut sink = match &args.video.y4m {
        Some(path) => {
            let file =
                File::create(path).map_err(|e| format!("cannot create {}: {e}", path.display()))?;
            let writer = Y4mWriter::new(
                BufWriter::new(file),
                spec.width_px,
                spec.height_px,
                spec.fps,
                colour,
            )
            .map_err(|e| e.to_string())?;
            Sink::Y4m(writer)
        }
        None => Sink::Jpeg,
    };
    let truth_path = dir.join("truth.jsonl");
    let truth_file = File::create(&truth_path)
        .map_err(|e| format!("cannot create {}: {e}", truth_path.display()))?;
    let mut truth = BufWriter::new(truth_file);
    let (code_frames, frames_with_codes) = render_all(sequence, dir, &mut sink, &mut truth)?;
    truth
        .flush()
        .map_err(|e| format!("cannot write {}: {e}", truth_path.display()))?;
    if let Sink::Y4m(writer) = sink {
        writer.finish().map_err(|e| e.to_string())?;
    }
    let frames = sequence.frame_count();
    Ok(json!({
        "sequence": spec.name,
        "frames": frames,
        "fps": spec.fps,
        "duration_ms": f64::from(frames) * 1000.0 / spec.fps,
        "image": {"width_px": spec.width_px, "height_px": spec.height_px},
        "camera": camera_json(sequence.camera()),
        "out": dir,
        "frames_written_as": match &args.video.y4m {
            Some(path) => json!({"y4m": path, "colour": format!("C{}", colour.token())}),
            None => json!({"jpeg": format!("{}/frame_NNNNN.jpg", dir.display())}),
        },
        "truth": truth_path,
        "spec": spec_path,
        "code_frames_in_view": code_frames,
        "frames_with_a_code_fully_in_view": frames_with_codes,
    }))
}
