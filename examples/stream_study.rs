//! The stream's tracker measured on rendered video with truth (docs/stream.md, "Measured"):
//! wrong poses, jitter, lag, coverage, identity, covariance consistency and detection cost,
//! each beside the single-frame answer of the same frames.
//!
//! ```sh
//! cargo run --release --example stream_study -- [approach|still|pan|all] [--frames N]
//! ```
//!
//! Each built-in video (`qrpose-sim render --sequence NAME`, docs/rendering.md) is run through
//! the application layer's `TrackSession` (what `GET /v1/stream` and `qrpose track` run),
//! frame by frame with its capture times; each code is sized by its payload through a site
//! made from the video's codes. The single-frame answer is the photo's answer to the same
//! bytes (`estimate_image`, what `POST /v1/pose/image` answers: the whole frame searched as
//! if it were the first); the tracked one the filtered pose of the code's track. The
//! session's own per-frame pose of a code (`markers[i].pose`, the tracker's input, read in
//! the tracks' regions on most frames) is printed beside them for the wrong-pose rate.
//!
//! A code's track is the first track any of its measurements went to; a read (the
//! session's or the photo's) is the code's when its corners are within 8 px of the code's
//! true corners.
//!
//! A site sizes by payload, so two codes that say the same get the first one's size (`pan`'s
//! `SHELF-TWIN` are 80 and 50 mm): a code sized otherwise is measured against its true
//! centre scaled by the site's size over its own, the pose a square of the site's size
//! makes with the same image (exact for a planar square: the image fixes the pose up to
//! scale; rotations are unchanged).
//!
//! - **wrong**: rotation more than 5° from truth, from the track's 5th frame on, on frames
//!   where the session read the code (single frames: those of the same code-frames the
//!   photo's answer read);
//! - **jitter** (`still`): spread over frames of the position (RMS distance from the mean,
//!   mm) and rotation (RMS angle from the mean, °), per code, filtered / single-frame;
//! - **lag** (moving videos): mean position error, filtered / single-frame, on the
//!   code-frames both answer;
//! - **resolved**: of the code-frames counted for **wrong**, those whose track said
//!   `ambiguity_resolved`, and the share of them more than 5° off (the flag promises the
//!   other planar branch at most 1 % likely);
//! - **coverage**: code-frames in view (whole symbol in the image) after the code's first
//!   read whose track answers within 5° (single frames: whose photo answer reads the code
//!   within 5°);
//! - **identity**: track ids per code over the video;
//! - **NEES**: mean of the filtered pose's normalised estimation error squared over its
//!   dimension, 6 (consistent: 0.5-2); the median too, and the mean over the code-frames
//!   whose track is within 5° (a wrong branch with a small covariance dominates the mean);
//! - **cost**: detection time of the frames searched in the tracks' regions, over the
//!   full-frame detection of the same bytes; then over every frame with live tracks (those
//!   whose whole frame is searched on the cadence, after a lost track or after a missed crop
//!   read included): the session's detection (`timing.detect_ms`, a crop read that fell
//!   back to the whole frame counted with it) over the photo's detection; the session's
//!   time less its answer's decoding and poses (detection and the tracker's update) over
//!   the same; and the whole frame's time, session over photo. A last line counts the
//!   frames with live tracks whose whole frame was searched, by reason.
//!
//! With more than one video, a last block, `all`, pools their code-frames.

use nalgebra::{Matrix3, Rotation3, Vector3, Vector6};
use qrpose::api::image::ImageQuery;
use qrpose::app::{
    DEFAULT_FULL_SEARCH_EVERY, FrameIn, ImageAnswer, ImageLimits, ImageSetup, MarkerAnswer, Search,
    TrackSession, TrackSetup, estimate_image,
};
use qrpose::detect::cancel::CancelFlag;
use qrpose_sim::render::encode;
use qrpose_sim::render::sequence::{BUILTIN_SEQUENCES, Sequence, builtin_sequence};
use qrpose_site::Site;
use qrpose_track::{TrackStatus, TrackerParams};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// A wrong pose: more than this far from the truth, degrees.
const WRONG_DEG: f64 = 5.0;
/// A read is a code's when its corners are this close to the true ones, px.
const MATCH_PX: f64 = 8.0;
/// Wrong poses count from a track's this-th frame on.
const SETTLED_FRAMES: u32 = 5;
/// The detection deadline of every read, ms: the server's cap, so that what is read does
/// not depend on how busy the machine is (unloaded, a 1280 × 720 frame takes a tenth of the
/// default deadline, about 65 ms, so the answers are those of the default).
const MAX_DETECT_MS: f64 = 5000.0;

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
    /// Code-frames from the track's 5th frame on that the session read.
    settled: usize,
    /// Of those, the ones the photo's answer read with a pose.
    settled_single: usize,
    wrong_single: usize,
    wrong_measured: usize,
    wrong_tracked: usize,
    in_view: usize,
    covered: usize,
    covered_single: usize,
    err_single_mm: Vec<f64>,
    err_tracked_mm: Vec<f64>,
    nees: Vec<f64>,
    /// NEES/6 of the code-frames whose track is within 5° of the truth.
    nees_right: Vec<f64>,
    ids_per_code: HashMap<usize, Vec<String>>,
    region_detect_ms: f64,
    region_full_ms: f64,
    region_frames: usize,
    /// Settled code-frames whose track said `ambiguity_resolved`, and of them those more
    /// than 5° off.
    resolved: usize,
    resolved_wrong: usize,
    /// Full-frame searches on frames with live tracks, by reason.
    full_reasons: std::collections::BTreeMap<String, usize>,
    live_frames: usize,
    /// Session: wall time less the answer's decoding and poses, ms.
    live_session_detect_ms: f64,
    /// Session: the answer's detection alone (`timing.detect_ms`), ms.
    live_session_detection_only_ms: f64,
    /// Photo: detection, ms.
    live_single_detect_ms: f64,
    live_session_ms: f64,
    live_single_ms: f64,
    /// Per code: single-frame and tracked positions (mm) and rotations.
    still: HashMap<usize, Series>,
}

impl Tally {
    /// Adds another video's code-frames (the still series stay per video).
    fn pool(&mut self, o: &Tally) {
        self.frames += o.frames;
        self.settled += o.settled;
        self.settled_single += o.settled_single;
        self.wrong_single += o.wrong_single;
        self.wrong_measured += o.wrong_measured;
        self.wrong_tracked += o.wrong_tracked;
        self.in_view += o.in_view;
        self.covered += o.covered;
        self.covered_single += o.covered_single;
        self.err_single_mm.extend(&o.err_single_mm);
        self.err_tracked_mm.extend(&o.err_tracked_mm);
        self.nees.extend(&o.nees);
        self.nees_right.extend(&o.nees_right);
        let base = self.ids_per_code.keys().max().map_or(0, |k| k + 1);
        for (code, ids) in &o.ids_per_code {
            self.ids_per_code.insert(base + code, ids.clone());
        }
        self.region_detect_ms += o.region_detect_ms;
        self.region_full_ms += o.region_full_ms;
        self.region_frames += o.region_frames;
        self.resolved += o.resolved;
        self.resolved_wrong += o.resolved_wrong;
        for (reason, n) in &o.full_reasons {
            *self.full_reasons.entry(reason.clone()).or_default() += n;
        }
        self.live_frames += o.live_frames;
        self.live_session_detect_ms += o.live_session_detect_ms;
        self.live_session_detection_only_ms += o.live_session_detection_only_ms;
        self.live_single_detect_ms += o.live_single_detect_ms;
        self.live_session_ms += o.live_session_ms;
        self.live_single_ms += o.live_single_ms;
    }
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

/// The marker of `answer` that is this code's read, with its index.
fn read_of<'a>(
    answer: &'a ImageAnswer,
    corners_px: &[[f64; 2]; 4],
) -> Option<(usize, &'a MarkerAnswer)> {
    answer.markers.iter().enumerate().find(|(_, m)| {
        let c = m.code.corners_px().map(|p| [p.u(), p.v()]);
        corners_close(&c, corners_px)
    })
}

/// The size the site gives each payload: the first code's that says it.
fn site_sizes(sequence: &Sequence) -> Vec<(String, f64)> {
    let mut sizes: Vec<(String, f64)> = Vec::new();
    for code in &sequence.spec().codes {
        if !sizes.iter().any(|(p, _)| p == &code.payload) {
            sizes.push((code.payload.clone(), code.size_mm));
        }
    }
    sizes
}

/// A site that sizes each code of the video by its payload.
fn site_of(sequence: &Sequence, sizes: &[(String, f64)]) -> Arc<Site> {
    let c = sequence.camera();
    let mut text = format!(
        "cameras:\n  cam:\n    intrinsics: {{fx_px: {}, fy_px: {}, cx_px: {}, cy_px: {}}}\nmarkers:\n  sizes:\n",
        c.fx(),
        c.fy(),
        c.cx(),
        c.cy()
    );
    for (payload, size_mm) in sizes {
        text.push_str(&format!(
            "    - {{payload: {payload:?}, size_mm: {size_mm}}}\n"
        ));
    }
    Arc::new(Site::parse(&text, Path::new("study-site.yaml")).expect("a valid site"))
}

fn setup_of(site: Arc<Site>) -> ImageSetup {
    let query = ImageQuery {
        camera_id: Some("cam".to_owned()),
        max_detect_ms: Some(MAX_DETECT_MS),
        ..ImageQuery::default()
    };
    query
        .setup(&ImageLimits::default(), Some(site))
        .expect("a valid setup")
}

fn run(name: &str, max_frames: Option<u32>) -> Tally {
    let spec = builtin_sequence(name).expect("a built-in video");
    let sequence = Sequence::new(spec).expect("a valid video");
    let sizes = site_sizes(&sequence);
    let setup = setup_of(site_of(&sequence, &sizes));
    let mut session = TrackSession::new(TrackSetup {
        image: setup.clone(),
        tracker: TrackerParams::default(),
        full_search_every: DEFAULT_FULL_SEARCH_EVERY,
    })
    .expect("a session");
    let mut tally = Tally::default();
    let mut track_of_code: HashMap<usize, String> = HashMap::new();
    let mut live = false;
    let frames = max_frames.map_or(sequence.frame_count(), |n| n.min(sequence.frame_count()));
    for k in 0..frames {
        let frame = sequence.render_frame(k).expect("renders");
        let jpeg = encode(&frame.image, sequence.encoding()).expect("encodes");
        let input = FrameIn {
            bytes: &jpeg,
            capture_time_ms: frame.truth.capture_time_ms,
            prior: None,
            flange: None,
        };
        let started = Instant::now();
        let answer = session.frame(&input, CancelFlag::new()).expect("an answer");
        let session_ms = started.elapsed().as_secs_f64() * 1e3;
        let started = Instant::now();
        let single = estimate_image(&setup, &jpeg, CancelFlag::new()).expect("an answer");
        let single_ms = started.elapsed().as_secs_f64() * 1e3;
        tally.frames += 1;
        if live {
            tally.live_frames += 1;
            let timing = &answer.image.timing;
            tally.live_session_detect_ms += session_ms - timing.decode_ms - timing.estimate_ms;
            tally.live_session_detection_only_ms += timing.detect_ms;
            tally.live_single_detect_ms += single.timing.detect_ms;
            tally.live_session_ms += session_ms;
            tally.live_single_ms += single_ms;
            if let Search::Full(reason) = answer.search {
                *tally.full_reasons.entry(format!("{reason:?}")).or_default() += 1;
            }
        }
        live = answer.tracks.iter().any(|t| t.status != TrackStatus::Lost);
        if answer.search == Search::Regions {
            tally.region_frames += 1;
            tally.region_detect_ms += answer.image.timing.detect_ms;
            tally.region_full_ms += single.timing.detect_ms;
        }
        for code in &frame.truth.codes {
            let truth_r = rotation_of(&code.truth.rotation_matrix);
            let site_size_mm = sizes
                .iter()
                .find(|(p, _)| p == &code.payload)
                .map_or(code.size_mm, |(_, s)| *s);
            let truth_c = Vector3::from(code.truth.position_mm) * (site_size_mm / code.size_mm);
            let read = read_of(&answer.image, &code.truth.corners_px);
            if let Some((i, _)) = read
                && let Some(Some(id)) = answer.track_ids.get(i)
            {
                track_of_code
                    .entry(code.code_index)
                    .or_insert_with(|| id.clone());
                let ids = tally.ids_per_code.entry(code.code_index).or_default();
                if !ids.contains(id) {
                    ids.push(id.clone());
                }
            }
            let Some(id) = track_of_code.get(&code.code_index) else {
                continue;
            };
            let track = answer
                .tracks
                .iter()
                .find(|t| &t.id == id && t.status != TrackStatus::Lost);
            let single_pose = read_of(&single, &code.truth.corners_px)
                .and_then(|(_, m)| m.pose.as_ref().ok())
                .map(|e| (e.pose.rotation(), e.centre_mm));
            if code.fully_in_view {
                tally.in_view += 1;
                if track.is_some_and(|t| angle_deg(&t.pose.rotation, &truth_r) <= WRONG_DEG) {
                    tally.covered += 1;
                }
                if single_pose.is_some_and(|(r, _)| angle_deg(&r, &truth_r) <= WRONG_DEG) {
                    tally.covered_single += 1;
                }
            }
            let (Some((_, m)), Some(track)) = (read, track) else {
                continue;
            };
            let p = &track.pose;
            let tracked_deg = angle_deg(&p.rotation, &truth_r);
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
                let nees = (e.transpose() * inv * e)[(0, 0)] / 6.0;
                tally.nees.push(nees);
                if tracked_deg <= WRONG_DEG {
                    tally.nees_right.push(nees);
                }
            }
            if track.frames_seen >= SETTLED_FRAMES {
                tally.settled += 1;
                tally.wrong_tracked += usize::from(tracked_deg > WRONG_DEG);
                if track.ambiguity_resolved {
                    tally.resolved += 1;
                    tally.resolved_wrong += usize::from(tracked_deg > WRONG_DEG);
                }
                if let Ok(measured) = &m.pose {
                    let deg = angle_deg(&measured.pose.rotation(), &truth_r);
                    tally.wrong_measured += usize::from(deg > WRONG_DEG);
                }
                if let Some((r, _)) = single_pose {
                    tally.settled_single += 1;
                    tally.wrong_single += usize::from(angle_deg(&r, &truth_r) > WRONG_DEG);
                }
            }
            let Some((single_r, single_c)) = single_pose else {
                continue;
            };
            tally.err_single_mm.push((single_c - truth_c).norm());
            tally.err_tracked_mm.push((p.centre_mm - truth_c).norm());
            let still = tally.still.entry(code.code_index).or_default();
            still.0.push(single_c);
            still.1.push(p.centre_mm);
            still.2.push(single_r);
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
    let mean_r = nalgebra::Rotation3::new(mean_log) * first;
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

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn report(name: &str, t: &Tally) {
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    println!("== {name}: {} frames", t.frames);
    println!(
        "wrong (> {WRONG_DEG}°, from a track's {SETTLED_FRAMES}th frame): tracked {:.2} % of {} code-frames vs single-frame {:.2} % of {} (the session's per-frame read {:.2} %)",
        pct(t.wrong_tracked, t.settled),
        t.settled,
        pct(t.wrong_single, t.settled_single),
        t.settled_single,
        pct(t.wrong_measured, t.settled),
    );
    println!(
        "resolved (the track said ambiguity_resolved, from its {SETTLED_FRAMES}th frame): {} code-frames, {} of them ({:.2} %) more than {WRONG_DEG}° off",
        t.resolved,
        t.resolved_wrong,
        pct(t.resolved_wrong, t.resolved)
    );
    println!(
        "coverage (in view after the first read, within {WRONG_DEG}°): tracked {:.1} % vs single-frame {:.1} % of {}",
        pct(t.covered, t.in_view),
        pct(t.covered_single, t.in_view),
        t.in_view
    );
    let max_ids = t.ids_per_code.values().map(Vec::len).max().unwrap_or(0);
    let split = t.ids_per_code.values().filter(|ids| ids.len() > 1).count();
    println!(
        "identity: at most {max_ids} track id(s) per code over {} codes ({split} with more than one)",
        t.ids_per_code.len()
    );
    println!(
        "position error: tracked {:.2} mm / single-frame {:.2} mm = {:.2} (medians {:.2} / {:.2} mm) over {} code-frames",
        mean(&t.err_tracked_mm),
        mean(&t.err_single_mm),
        mean(&t.err_tracked_mm) / mean(&t.err_single_mm),
        median(&t.err_tracked_mm),
        median(&t.err_single_mm),
        t.err_tracked_mm.len()
    );
    println!(
        "NEES / 6: mean {:.2}, median {:.2} over {} code-frames; mean {:.2} over the {} whose track is within {WRONG_DEG}°",
        mean(&t.nees),
        median(&t.nees),
        t.nees.len(),
        mean(&t.nees_right),
        t.nees_right.len()
    );
    let mut codes: Vec<_> = t.still.iter().collect();
    codes.sort_by_key(|(code, _)| **code);
    if name == "still" {
        for (code, (rp, tp, rr, tr)) in codes {
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
        "cost: {} frames searched in regions: detection {:.2} ms / full-frame {:.2} ms = {:.2}; {} frames with live tracks: detection {:.2} ms / full-frame detection {:.2} ms = {:.2}, detection and tracking {:.2} ms = {:.2}, whole frame {:.2} ms / {:.2} ms = {:.2}",
        t.region_frames,
        t.region_detect_ms / t.region_frames.max(1) as f64,
        t.region_full_ms / t.region_frames.max(1) as f64,
        t.region_detect_ms / t.region_full_ms.max(f64::MIN_POSITIVE),
        t.live_frames,
        t.live_session_detection_only_ms / t.live_frames.max(1) as f64,
        t.live_single_detect_ms / t.live_frames.max(1) as f64,
        t.live_session_detection_only_ms / t.live_single_detect_ms.max(f64::MIN_POSITIVE),
        t.live_session_detect_ms / t.live_frames.max(1) as f64,
        t.live_session_detect_ms / t.live_single_detect_ms.max(f64::MIN_POSITIVE),
        t.live_session_ms / t.live_frames.max(1) as f64,
        t.live_single_ms / t.live_frames.max(1) as f64,
        t.live_session_ms / t.live_single_ms.max(f64::MIN_POSITIVE)
    );
}

fn report_reasons(t: &Tally) {
    let reasons: Vec<String> = t
        .full_reasons
        .iter()
        .map(|(reason, n)| format!("{reason} {n}"))
        .collect();
    println!(
        "full-frame searches on frames with live tracks: {}",
        reasons.join(", ")
    );
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
    let mut pooled = Tally::default();
    for name in &names {
        let t = run(name, max_frames);
        report(name, &t);
        report_reasons(&t);
        pooled.pool(&t);
    }
    if names.len() > 1 {
        report("all", &pooled);
        report_reasons(&pooled);
    }
}
