//! The stream in the robot's frame (docs/pick.md, Streams): an arm carrying the camera
//! approaches a still product from 800 mm to 250 mm, with its flange pose on every frame.
//! Each track fuses its code's robot-frame poses, so the grasp planned from the track is
//! sharper than any one frame's: after 10 frames its error is at most half the single
//! frames' (medians over three approaches). `cargo test --release --test image approach --
//! --nocapture` prints the figures of docs/measurements/pick.md.

#[path = "../support/pick.rs"]
mod scene;

use nalgebra::Vector3;
use qrpose::api::image::ImageQuery;
use qrpose::api::stream::TrackQuery;
use qrpose::app::{FrameIn, ImageLimits, Site, TrackSession};
use qrpose::detect::cancel::CancelFlag;
use qrpose_sim::render::{Effects, Encoding};
use qrpose_site::transform::Rigid;
use std::path::Path;
use std::sync::Arc;

/// Frames per approach.
const FRAMES: usize = 20;
/// The frame after which the fused grasp is judged.
const JUDGED_FRAME: usize = 10;

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Per frame of one approach: the single frame's grasp position error and the track's, mm.
fn approach_errors(
    site: &Arc<Site>,
    tilt_deg: f64,
    azimuth_deg: f64,
    seed: u64,
) -> Vec<(f64, Option<f64>)> {
    let query = ImageQuery {
        camera_id: Some("wrist".to_owned()),
        method: Some(qrpose::api::request::MethodDto::Reprojection),
        ..ImageQuery::default()
    };
    let setup = TrackQuery::default()
        .setup(query, &ImageLimits::default(), Some(Arc::clone(site)))
        .expect("a stream setup");
    let mut session = TrackSession::new(setup).expect("a session");
    let truth: Vector3<f64> = scene::top_grasp_in_robot().translation.vector;
    scene::approach(FRAMES, tilt_deg, azimuth_deg)
        .iter()
        .enumerate()
        .filter_map(|(k, flange)| {
            let effects = Effects {
                supersample: 3,
                blur_px: 0.6,
                noise: 2.0,
                encoding: Encoding::Jpeg(90),
                seed: seed * 100 + k as u64,
                ..Effects::default()
            };
            let photo = scene::photo_with(flange, &effects);
            let input = FrameIn {
                bytes: &photo,
                capture_time_ms: k as f64 * 100.0,
                prior: None,
                flange: Some(Rigid::from(flange)),
            };
            let answer = session.frame(&input, CancelFlag::new()).expect("a frame");
            let marker = answer.image.markers.first()?;
            let single = marker.frames.object.as_ref()?.grasps[0].pose_in_robot?;
            let id = answer.track_ids.first()?.as_ref()?;
            let fused = answer
                .in_robot
                .get(id)
                .and_then(|t| t.object.as_ref()?.grasps[0].pose_in_robot);
            Some((
                (single.pose.translation_mm - truth).norm(),
                fused.map(|f| (f.pose.translation_mm - truth).norm()),
            ))
        })
        .collect()
}

#[test]
fn after_ten_frames_the_tracks_grasp_is_at_least_twice_as_sharp_as_one_frames() {
    let dir = std::env::temp_dir().join(format!("qrpose-approach-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    std::fs::write(dir.join("site.yaml"), scene::SITE).expect("writes the site");
    let site = Arc::new(Site::load(Path::new(&dir.join("site.yaml"))).expect("the site"));
    let mut singles = Vec::new();
    let mut fused_at_judged = Vec::new();
    let mut singles_at_judged = Vec::new();
    for (seed, (tilt, azimuth)) in [(25.0, 30.0), (35.0, 160.0), (20.0, 260.0)]
        .into_iter()
        .enumerate()
    {
        let errors = approach_errors(&site, tilt, azimuth, seed as u64);
        assert!(
            errors.len() >= JUDGED_FRAME,
            "frames read: {}",
            errors.len()
        );
        singles.extend(errors[..JUDGED_FRAME].iter().map(|(s, _)| *s));
        let (single, fused) = errors[JUDGED_FRAME - 1];
        singles_at_judged.push(single);
        fused_at_judged.push(fused.expect("a fused grasp"));
        println!(
            "approach tilt {tilt}° azimuth {azimuth}°: per frame (single, fused) mm {errors:.2?}"
        );
    }
    let single = median(singles);
    let fused = median(fused_at_judged.clone());
    println!(
        "grasp position error: single frames 1-{JUDGED_FRAME} median {single:.2} mm; frame {JUDGED_FRAME} alone median {:.2} mm; track after {JUDGED_FRAME} frames median {fused:.2} mm ({fused_at_judged:.2?})",
        median(singles_at_judged)
    );
    assert!(
        fused <= 0.5 * single,
        "fused {fused} mm against single {single} mm"
    );
}
