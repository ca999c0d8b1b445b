//! Where a stream looks: on frames with live tracks the detector reads the
//! tracks' regions, and the whole frame every `full_search_every` frames, so a code entering
//! the view is found within that many frames; a code its region misses while it is predicted
//! with confidence is `coasting`, not dropped. Run through `app::TrackSession`, the layer the
//! WebSocket and `qrpose track` call.

use nalgebra::Vector3;
use qrpose::api::image::ImageQuery;
use qrpose::app::{
    FrameIn, FullReason, ImageLimits, Search, TrackAnswer, TrackSession, TrackSetup,
};
use qrpose::detect::cancel::CancelFlag;
use qrpose::geometry::{camera::Camera, euler::EulerXyz, marker::Marker};
use qrpose_sim::render::{CodePlacement, EcLevel, Effects, Encoding, MultiScene, render_scene};
use qrpose_track::{TrackStatus, TrackerParams};

const FPS: f64 = 30.0;

fn placement(payload: &str, centre: [f64; 3]) -> CodePlacement {
    let marker = Marker::try_new(50.0).expect("a size");
    let r = EulerXyz::from_degrees(10.0, -25.0, 5.0).to_rotation();
    CodePlacement {
        payload: payload.as_bytes().to_vec(),
        ec_level: EcLevel::M,
        marker,
        pose: marker.pose_centred_at(r, Vector3::from(centre)),
    }
}

/// A 1280 × 720 frame of `codes` (payloads `A` at the left, `B` at the right), JPEG.
fn frame(codes: &[&str], seed: u64) -> Vec<u8> {
    let placements = codes
        .iter()
        .map(|p| match *p {
            "A" => placement("A", [-150.0, 0.0, 500.0]),
            _ => placement("B", [150.0, 20.0, 550.0]),
        })
        .collect();
    frame_of(placements, seed)
}

/// A 1280 × 720 JPEG frame of `codes`.
fn frame_of(codes: Vec<CodePlacement>, seed: u64) -> Vec<u8> {
    try_frame_of(codes, seed).expect("renders")
}

/// A 1280 × 720 JPEG frame of `codes`; `None` when one is not wholly in view (the renderer
/// draws only whole codes).
fn try_frame_of(codes: Vec<CodePlacement>, seed: u64) -> Option<Vec<u8>> {
    let scene = MultiScene {
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a camera"),
        width_px: 1280,
        height_px: 720,
        codes,
    };
    let effects = Effects {
        blur_px: 0.5,
        noise: 1.0,
        encoding: Encoding::Jpeg(90),
        seed,
        ..Effects::default()
    };
    render_scene(&scene, &effects).ok().map(|r| r.encoded)
}

fn session(full_search_every: u32) -> TrackSession {
    let query = ImageQuery {
        fx_px: Some(1000.0),
        fy_px: Some(1000.0),
        cx_px: Some(639.5),
        cy_px: Some(359.5),
        marker_size_mm: Some(50.0),
        ..ImageQuery::default()
    };
    let image = query
        .setup(&ImageLimits::default(), None)
        .expect("a valid setup");
    TrackSession::new(TrackSetup {
        image,
        tracker: TrackerParams::default(),
        full_search_every,
    })
    .expect("a session")
}

fn run(session: &mut TrackSession, jpeg: &[u8], k: u32) -> TrackAnswer {
    let input = FrameIn {
        bytes: jpeg,
        capture_time_ms: f64::from(k) * 1000.0 / FPS,
        prior: None,
        flange: None,
    };
    session.frame(&input, CancelFlag::new()).expect("an answer")
}

fn status_of(answer: &TrackAnswer, payload: &str) -> Option<TrackStatus> {
    answer
        .tracks
        .iter()
        .find(|t| t.payload == payload)
        .map(|t| t.status)
}

#[test]
fn a_code_entering_the_view_is_found_within_the_full_search_cadence() {
    const EVERY: u32 = 4;
    let mut s = session(EVERY);
    let only_a = frame(&["A"], 1);
    let both = frame(&["A", "B"], 2);
    let mut searches = Vec::new();
    for k in 0..3 {
        searches.push(run(&mut s, &only_a, k).search);
    }
    assert_eq!(
        searches[0],
        Search::Full(FullReason::NoTracks),
        "the first frame searches everything"
    );
    assert!(
        searches[1..].contains(&Search::Regions),
        "with a live track the regions are read: {searches:?}"
    );
    let mut found_at = None;
    for k in 3..3 + EVERY {
        let answer = run(&mut s, &both, k);
        if status_of(&answer, "B").is_some() {
            found_at = Some(k);
            break;
        }
    }
    let found_at = found_at.expect("B is found");
    assert!(found_at < 3 + EVERY, "B found at frame {found_at}");
}

#[test]
fn a_confident_track_missed_by_its_region_coasts_and_is_not_dropped() {
    let mut s = session(1000);
    let with_a = frame(&["A", "B"], 3);
    for k in 0..6 {
        let answer = run(&mut s, &with_a, k);
        assert!(status_of(&answer, "A").is_some(), "frame {k}");
    }
    // A is gone (covered), B stays: A's region reads nothing.
    let without_a = frame(&["B"], 4);
    let answer = run(&mut s, &without_a, 6);
    assert_eq!(
        answer.search,
        Search::Regions,
        "a confident track's miss does not make the frame search everything"
    );
    assert_eq!(
        status_of(&answer, "A"),
        Some(TrackStatus::Coasting),
        "{:?}",
        answer.tracks
    );
    assert_eq!(status_of(&answer, "B"), Some(TrackStatus::Tracking));
}

#[test]
fn a_code_leaving_the_view_makes_no_frame_search_everything() {
    // Every region a crop read misses counts as not confident here, so before the rule
    // (a region predicted partly outside the image is not searched for) each frame after A
    // left would have searched the whole frame, and so would the frame after A was lost.
    let mut s = session(1000);
    s = TrackSession::new(TrackSetup {
        tracker: TrackerParams {
            confident_corner_sigma_px: 1e-3,
            ..TrackerParams::default()
        },
        ..s.setup().clone()
    })
    .expect("a session");
    // A moves left at 30 mm a frame (0.9 m/s at 500 mm) until it reaches the image's edge,
    // then is not drawn (the renderer draws whole codes only; a code cut by the edge is
    // not read either). B stays.
    let a_at = |k: u32| placement("A", [-150.0 - 30.0 * f64::from(k), 0.0, 500.0]);
    let b = || placement("B", [150.0, 20.0, 550.0]);
    let mut searches = Vec::new();
    let mut a_lost_at = None;
    for k in 0..30 {
        let seed = 10 + u64::from(k);
        let jpeg =
            try_frame_of(vec![a_at(k), b()], seed).unwrap_or_else(|| frame_of(vec![b()], seed));
        let answer = run(&mut s, &jpeg, k);
        searches.push(answer.search);
        if k < 4 {
            assert!(status_of(&answer, "A").is_some(), "frame {k}");
        }
        assert_eq!(
            status_of(&answer, "B"),
            Some(if k == 0 {
                TrackStatus::New
            } else {
                TrackStatus::Tracking
            }),
            "frame {k}"
        );
        if a_lost_at.is_none() && status_of(&answer, "A") == Some(TrackStatus::Lost) {
            a_lost_at = Some(k);
        }
    }
    let lost = a_lost_at.expect("A's track is lost once it has left");
    assert_eq!(searches[0], Search::Full(FullReason::NoTracks));
    assert!(
        searches[1..].iter().all(|s| *s == Search::Regions),
        "A lost at frame {lost}; searches {searches:?}"
    );
}
