//! The stream's tracker measured on rendered video with truth (issue 24, "Measured"):
//! wrong poses, jitter, lag, coverage, identity, covariance consistency and detection cost,
//! each beside the single-frame answer of the same frames.
//!
//! ```sh
//! cargo run --release --example stream_study -- [approach|still|pan|all] [--frames N]
//! ```
//!
//! Each built-in video (`qrpose render --sequence NAME`, docs/rendering.md) is run through
//! the application layer's `TrackSession` (what `GET /v1/stream` and `qrpose track` run),
//! frame by frame with its capture times; each code is sized by its payload through a site
//! made from the video's codes. The single-frame answer is the per-frame pose of the same
//! frame (`markers[i].pose`); the tracked one the filtered pose of the code's track.
//!
//! A code's track is the first track any of its measurements went to; a measurement is the
//! code's when its corners are within 8 px of the code's true corners.
//!
//! - **wrong**: rotation more than 5° from truth, from the track's 5th frame on, on frames
//!   where the code was read (single frames: the same code-frames);
//! - **jitter** (`still`): spread over frames of the position (RMS distance from the mean,
//!   mm) and rotation (RMS angle from the mean, °), per code, filtered / single-frame;
//! - **lag** (moving videos): mean position error, filtered / single-frame;
//! - **coverage**: code-frames in view (whole symbol in the image) after the code's first
//!   read whose track answers within 5°;
//! - **identity**: track ids per code over the video;
//! - **NEES**: mean of the filtered pose's normalised estimation error squared over its
//!   dimension, 6 (consistent: 0.5-2);
//! - **cost**: detection time of the frames searched in the tracks' regions, over the
//!   full-frame detection of the same bytes.

use nalgebra::{Matrix3, Rotation3, Vector3, Vector6};
use qrpose::api::image::ImageQuery;
use qrpose::app::{
    DEFAULT_FULL_SEARCH_EVERY, FrameIn, ImageLimits, ImageSetup, Search, TrackSession, TrackSetup,
};
use qrpose::detect::cancel::CancelFlag;
use qrpose::render::encode;
use qrpose::render::sequence::{BUILTIN_SEQUENCES, Sequence, builtin_sequence};
use qrpose_site::Site;
use qrpose_track::{TrackStatus, TrackerParams};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// A wrong pose: more than this far from the truth, degrees.
const WRONG_DEG: f64 = 5.0;
/// A measurement is a code's when its corners are this close to the true ones, px.
const MATCH_PX: f64 = 8.0;
/// Wrong poses count from a track's this-th frame on.
const SETTLED_FRAMES: u32 = 5;

/// One code's single-frame and tracked positions (mm) and rotations over the frames.
type Series = (
    Vec<Vector3<f64>>,
    Vec<Vector3<f64>>,
    Vec<Rotation3<f64>>,
    Vec<Rotation3<f64>>,
);

#[derive(Default)]
struct Tally {
    frames: usize,
    settled: usize,
    wrong_single: usize,
    wrong_tracked: usize,
    in_view: usize,
    covered: usize,
    err_single_mm: Vec<f64>,
    err_tracked_mm: Vec<f64>,
    nees: Vec<f64>,
    ids_per_code: HashMap<usize, Vec<String>>,
    region_detect_ms: f64,
    region_full_ms: f64,
    region_frames: usize,
    /// Per code: single-frame and tracked positions (mm) and rotations.
    still: HashMap<usize, Series>,
}

fn angle_deg(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    (a * b.inverse()).angle().to_degrees()
}

fn rotation_of(m: &[[f64; 3]; 3]) -> Rotation3<f64> {
    Rotation3::from_matrix_unchecked(Matrix3::from_fn(|i, j| m[i][j]))
}

fn corners_close(a: &[[f64; 2]; 4], b: &[[f64; 2]; 4]) -> bool {
    a.iter()
        .zip(b)
        .all(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]) <= MATCH_PX)
}

/// A site that sizes each code of the video by its payload.
fn site_of(sequence: &Sequence) -> Arc<Site> {
    let c = sequence.camera();
    let mut text = format!(
        "cameras:\n  cam:\n    intrinsics: {{fx_px: {}, fy_px: {}, cx_px: {}, cy_px: {}}}\nmarkers:\n  sizes:\n",
        c.fx(),
        c.fy(),
        c.cx(),
        c.cy()
    );
    for code in &sequence.spec().codes {
        text.push_str(&format!(
            "    - {{payload: {:?}, size_mm: {}}}\n",
            code.payload, code.size_mm
        ));
    }
    Arc::new(Site::parse(&text, Path::new("study-site.yaml")).expect("a valid site"))
}

fn setup_of(site: Arc<Site>) -> ImageSetup {
    let query = ImageQuery {
        camera_id: Some("cam".to_owned()),
        ..ImageQuery::default()
    };
    query
        .setup(&ImageLimits::default(), Some(site))
        .expect("a valid setup")
}

fn run(name: &str, max_frames: Option<u32>) -> Tally {
    let spec = builtin_sequence(name).expect("a built-in video");
    let sequence = Sequence::new(spec).expect("a valid video");
    let setup = setup_of(site_of(&sequence));
    let mut session = TrackSession::new(TrackSetup {
        image: setup.clone(),
        tracker: TrackerParams::default(),
        full_search_every: DEFAULT_FULL_SEARCH_EVERY,
    })
    .expect("a session");
    let mut tally = Tally::default();
    let mut track_of_code: HashMap<usize, String> = HashMap::new();
    let frames = max_frames.map_or(sequence.frame_count(), |n| n.min(sequence.frame_count()));
    for k in 0..frames {
        let frame = sequence.render_frame(k).expect("renders");
        let jpeg = encode(&frame.image, sequence.encoding()).expect("encodes");
        let input = FrameIn {
            bytes: &jpeg,
            capture_time_ms: frame.truth.capture_time_ms,
            prior: None,
        };
        let answer = session.frame(&input, CancelFlag::new()).expect("an answer");
        tally.frames += 1;
        if answer.search == Search::Regions {
            let full =
                qrpose::app::estimate_image(&setup, &jpeg, CancelFlag::new()).expect("an answer");
            tally.region_frames += 1;
            tally.region_detect_ms += answer.image.timing.detect_ms;
            tally.region_full_ms += full.timing.detect_ms;
        }
        for code in &frame.truth.codes {
            let truth_r = rotation_of(&code.truth.rotation_matrix);
            let truth_c = Vector3::from(code.truth.position_mm);
            let read = answer.image.markers.iter().zip(&answer.track_ids).find(|(m, _)| {
                let c = m.code.corners_px().map(|p| [p.u(), p.v()]);
                corners_close(&c, &code.truth.corners_px)
            });
            if let Some((m, Some(id))) = read {
                track_of_code
                    .entry(code.code_index)
                    .or_insert_with(|| id.clone());
                let ids = tally.ids_per_code.entry(code.code_index).or_default();
                if !ids.contains(id) {
                    ids.push(id.clone());
                }
                let _ = m;
            }
            let Some(id) = track_of_code.get(&code.code_index) else {
                continue;
            };
            let track = answer
                .tracks
                .iter()
                .find(|t| &t.id == id && t.status != TrackStatus::Lost);
            if code.fully_in_view {
                tally.in_view += 1;
                if track.is_some_and(|t| angle_deg(&t.pose.rotation, &truth_r) <= WRONG_DEG) {
                    tally.covered += 1;
                }
            }
            let (Some((m, _)), Some(track)) = (read, track) else {
                continue;
            };
            let Ok(raw) = &m.pose else { continue };
            let raw_r = raw.pose.rotation();
            let raw_c = raw.centre_mm;
            let p = &track.pose;
            tally.err_single_mm.push((raw_c - truth_c).norm());
            tally.err_tracked_mm.push((p.centre_mm - truth_c).norm());
            let dtheta = qrpose_track::so3::log(&(truth_r * p.rotation.inverse()));
            let e = Vector6::new(
                dtheta.x,
                dtheta.y,
                dtheta.z,
                truth_c.x - p.centre_mm.x,
                truth_c.y - p.centre_mm.y,
                truth_c.z - p.centre_mm.z,
            );
            if let Some(inv) = p.covariance.try_inverse() {
                tally.nees.push((e.transpose() * inv * e)[(0, 0)] / 6.0);
            }
            if track.frames_seen >= SETTLED_FRAMES {
                tally.settled += 1;
                tally.wrong_single += usize::from(angle_deg(&raw_r, &truth_r) > WRONG_DEG);
                tally.wrong_tracked += usize::from(angle_deg(&p.rotation, &truth_r) > WRONG_DEG);
            }
            let still = tally.still.entry(code.code_index).or_default();
            still.0.push(raw_c);
            still.1.push(p.centre_mm);
            still.2.push(raw_r);
            still.3.push(p.rotation);
        }
    }
    tally
}

fn spread(positions: &[Vector3<f64>], rotations: &[Rotation3<f64>]) -> (f64, f64) {
    let n = positions.len().max(1) as f64;
    let mean = positions.iter().sum::<Vector3<f64>>() / n;
    let pos = (positions
        .iter()
        .map(|p| (p - mean).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    let Some(first) = rotations.first() else {
        return (pos, 0.0);
    };
    let mean_log = rotations
        .iter()
        .map(|r| qrpose_track::so3::log(&(r * first.inverse())))
        .sum::<Vector3<f64>>()
        / n;
    let mean_r = qrpose_track::so3::exp(&mean_log) * first;
    let rot = (rotations
        .iter()
        .map(|r| angle_deg(r, &mean_r).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    (pos, rot)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn main() {
    let mut args = std::env::args().skip(1);
    let mut names: Vec<String> = Vec::new();
    let mut max_frames = None;
    while let Some(a) = args.next() {
        if a == "--frames" {
            max_frames = args.next().and_then(|n| n.parse().ok());
        } else if a == "all" {
            names.extend(BUILTIN_SEQUENCES.iter().map(|s| (*s).to_owned()));
        } else {
            names.push(a);
        }
    }
    if names.is_empty() {
        names.extend(BUILTIN_SEQUENCES.iter().map(|s| (*s).to_owned()));
    }
    for name in names {
        let t = run(&name, max_frames);
        let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
        println!("== {name}: {} frames", t.frames);
        println!(
            "wrong (> {WRONG_DEG}°, from a track's {SETTLED_FRAMES}th frame): tracked {:.2} % vs single-frame {:.2} % of {} code-frames",
            pct(t.wrong_tracked, t.settled),
            pct(t.wrong_single, t.settled),
            t.settled
        );
        println!(
            "coverage (in view after the first read, track within {WRONG_DEG}°): {:.1} % of {}",
            pct(t.covered, t.in_view),
            t.in_view
        );
        let max_ids = t.ids_per_code.values().map(Vec::len).max().unwrap_or(0);
        println!(
            "identity: at most {max_ids} track id(s) per code over {} codes",
            t.ids_per_code.len()
        );
        println!(
            "position error: tracked {:.2} mm / single-frame {:.2} mm = {:.2}",
            mean(&t.err_tracked_mm),
            mean(&t.err_single_mm),
            mean(&t.err_tracked_mm) / mean(&t.err_single_mm)
        );
        println!(
            "NEES / 6: {:.2} over {} code-frames",
            mean(&t.nees),
            t.nees.len()
        );
        if name == "still" {
            for (code, (rp, tp, rr, tr)) in &t.still {
                let (sp, sr) = spread(rp, rr);
                let (fp, fr) = spread(tp, tr);
                println!(
                    "jitter code {code}: position {fp:.3} / {sp:.3} mm = {:.2}, rotation {fr:.3} / {sr:.3}° = {:.2}",
                    fp / sp,
                    fr / sr
                );
            }
        }
        println!(
            "cost: {} frames searched in regions: {:.2} ms / full-frame {:.2} ms = {:.2}",
            t.region_frames,
            t.region_detect_ms / t.region_frames.max(1) as f64,
            t.region_full_ms / t.region_frames.max(1) as f64,
            t.region_detect_ms / t.region_full_ms.max(f64::MIN_POSITIVE)
        );
    }
}
