//! Detection restricted to given regions (`qrpose_detect::detect_in_regions`, the stream's
//! search where the tracks predict their codes) on a rendered frame: regions around the true
//! corners read every code as accurately as the whole-frame search, an empty region reads
//! nothing, a region partly outside the frame is clipped, and a spent or cancelled budget
//! stops between regions.

use nalgebra::Vector3;
use qrpose_core::geometry::{camera::Camera, euler::EulerXyz, frames::PixelPoint, marker::Marker};
use qrpose_detect::decode::{DecodeLimits, GrayImage, decode_gray};
use qrpose_detect::pipeline::{Options, Setup, locate_markers_in_regions};
use qrpose_detect::{
    Budget, CancelFlag, Detection, DetectorChoice, Effort, SearchRegion, detect_in_regions,
    detect_within,
};
use qrpose_sim::render::{
    CodePlacement, EcLevel, Effects, Encoding, GroundTruth, MultiScene, render_scene,
};
use std::time::Duration;

/// Largest corner error of a code read in a region, px (as the image-path tests of the
/// whole-frame search).
const CORNER_TOL_PX: f64 = 0.35;
/// A region's corners may differ from the whole frame's by this much, px: the same
/// refinement from whole-pixel corners that may differ by a pixel.
const SAME_CORNERS_PX: f64 = 0.05;

fn code(payload: &str, centre_mm: [f64; 3], euler_deg: [f64; 3]) -> CodePlacement {
    let marker = Marker::try_new(50.0).expect("valid size");
    let r = EulerXyz::from_degrees(euler_deg[0], euler_deg[1], euler_deg[2]).to_rotation();
    CodePlacement {
        payload: payload.as_bytes().to_vec(),
        ec_level: EcLevel::M,
        marker,
        pose: marker.pose_centred_at(r, Vector3::new(centre_mm[0], centre_mm[1], centre_mm[2])),
    }
}

fn camera() -> Camera {
    Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("valid camera")
}

/// Three 50 mm codes 450 mm away, turned differently, the left one near the frame's left
/// edge; 1280 × 720, blurred, noisy, cluttered, JPEG; the decoded frame and the truth.
fn frame() -> (GrayImage, Vec<GroundTruth>) {
    let scene = MultiScene {
        camera: camera(),
        width_px: 1280,
        height_px: 720,
        codes: vec![
            code("LEFT-CODE", [-235.0, -40.0, 450.0], [10.0, 20.0, 15.0]),
            code("MIDDLE-CODE", [0.0, 30.0, 450.0], [-15.0, 0.0, -30.0]),
            code("RIGHT-CODE", [200.0, -20.0, 450.0], [0.0, -20.0, 100.0]),
        ],
    };
    let effects = Effects {
        supersample: 3,
        blur_px: 0.7,
        noise: 1.5,
        lighting: 0.2,
        clutter: 8,
        encoding: Encoding::Jpeg(90),
        seed: 5,
        ..Effects::default()
    };
    let rendered = render_scene(&scene, &effects).expect("renders");
    let image = decode_gray(&rendered.encoded, &DecodeLimits::default()).expect("decodes");
    (image, rendered.truth)
}

fn corners(truth: &GroundTruth) -> [PixelPoint; 4] {
    truth.corners_px.map(|[u, v]| PixelPoint::new(u, v))
}

/// The region a tracker would give: the true corners with a margin of a quarter of the
/// code's longer side.
fn around(truth: &GroundTruth) -> SearchRegion {
    let c = corners(truth);
    let side_px = (0..4)
        .map(|i| (c[i].0 - c[(i + 1) % 4].0).norm())
        .fold(0.0, f64::max);
    SearchRegion::Quad {
        corners_px: c,
        margin_px: 0.25 * side_px,
    }
}

/// The largest corner error of the code reading `payload`, px; `None` when none does.
fn corner_error_px(detection: &Detection, payload: &str, truth: &GroundTruth) -> Option<f64> {
    let code = detection
        .codes
        .iter()
        .find(|c| c.candidate.text.as_deref() == Some(payload))?;
    let error = code
        .corners_px()
        .iter()
        .zip(corners(truth))
        .map(|(p, t)| (p.0 - t.0).norm())
        .fold(0.0, f64::max);
    Some(error)
}

const PAYLOADS: [&str; 3] = ["LEFT-CODE", "MIDDLE-CODE", "RIGHT-CODE"];

#[test]
fn regions_around_the_codes_read_them_as_accurately_as_the_whole_frame() {
    let (image, truth) = frame();
    let whole = detect_within(&image, DetectorChoice::Auto, &Budget::default()).expect("auto");
    let regions: Vec<SearchRegion> = truth.iter().map(around).collect();
    let crops = detect_in_regions(&image, &regions, &Budget::default());
    assert_eq!(crops.codes.len(), 3, "{:?}", crops.log.passes);
    for (payload, t) in PAYLOADS.iter().zip(&truth) {
        let full = corner_error_px(&whole, payload, t).expect("the whole frame reads it");
        let crop = corner_error_px(&crops, payload, t).expect("its region reads it");
        assert!(crop < CORNER_TOL_PX, "{payload}: {crop} px");
        assert!(
            crop <= full + SAME_CORNERS_PX,
            "{payload}: {crop} px, whole frame {full} px"
        );
        assert!(crops.codes.iter().all(|c| c.is_refined()));
    }
    assert!(
        crops
            .log
            .passes
            .iter()
            .all(|p| p.name.starts_with("track crop ")),
        "{:?}",
        crops.log.passes
    );
    let first_reads: Vec<&str> = crops.log.passes.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(
        first_reads,
        [
            "track crop 0 rxing",
            "track crop 1 rxing",
            "track crop 2 rxing"
        ]
    );
    // Overlapping regions find a code once.
    let twice = detect_in_regions(&image, &[regions[1], regions[1]], &Budget::default());
    assert_eq!(twice.codes.len(), 1);
}

#[test]
fn a_region_over_an_empty_part_of_the_frame_reads_nothing() {
    let (image, _) = frame();
    let empty = SearchRegion::Rect {
        min_px: PixelPoint::new(0.0, 0.0),
        max_px: PixelPoint::new(110.0, 110.0),
    };
    let detection = detect_in_regions(&image, &[empty], &Budget::default());
    assert!(detection.codes.is_empty(), "{:?}", detection.codes);
    // It looked closer before giving up, on the crop only.
    assert!(detection.log.passes.len() > 1);
    assert!(
        detection
            .log
            .passes
            .iter()
            .all(|p| p.name.starts_with("track crop 0 "))
    );
    let none = detect_in_regions(&image, &[], &Budget::default());
    assert!(none.codes.is_empty() && none.log.passes.is_empty());
}

#[test]
fn a_region_partly_outside_the_frame_is_clipped_and_one_wholly_outside_is_skipped() {
    let (image, truth) = frame();
    let left = corners(&truth[0]);
    assert!(
        left.iter().any(|p| p.u() < 150.0),
        "the code is near the edge"
    );
    let overhanging = SearchRegion::Quad {
        corners_px: left,
        margin_px: 200.0,
    };
    let outside = SearchRegion::Rect {
        min_px: PixelPoint::new(-400.0, 100.0),
        max_px: PixelPoint::new(-20.0, 300.0),
    };
    let detection = detect_in_regions(&image, &[outside, overhanging], &Budget::default());
    let texts: Vec<Option<&str>> = detection
        .codes
        .iter()
        .map(|c| c.candidate.text.as_deref())
        .collect();
    assert_eq!(texts, [Some("LEFT-CODE")]);
    assert_eq!(detection.log.passes[0].name, "track crop 1 rxing");
}

#[test]
fn a_cancelled_or_spent_budget_stops_between_regions() {
    let (image, truth) = frame();
    let regions: Vec<SearchRegion> = truth.iter().map(around).collect();
    let flag = CancelFlag::new();
    flag.cancel();
    let cancelled = Budget::default().cancelled_by(flag);
    let detection = detect_in_regions(&image, &regions, &cancelled);
    // The first read always runs (the least an answer costs), nothing after it.
    assert_eq!(detection.log.passes.len(), 1, "{:?}", detection.log.passes);
    assert!(detection.log.cancelled && !detection.log.budget_exhausted);
    assert!(detection.codes.len() <= 1);
    let spent = Budget::new(Effort::Balanced, Some(Duration::ZERO));
    let detection = detect_in_regions(&image, &regions, &spent);
    assert_eq!(detection.log.passes.len(), 1, "{:?}", detection.log.passes);
    assert!(detection.log.budget_exhausted && !detection.log.cancelled);
}

#[test]
fn the_pipeline_solves_the_codes_read_in_regions() {
    let (image, truth) = frame();
    let regions: Vec<SearchRegion> = truth.iter().map(around).collect();
    let setup = Setup {
        camera: camera(),
        sizes: Marker::try_new(50.0).expect("valid size"),
        solver: Default::default(),
    };
    let located = locate_markers_in_regions(&image, &setup, &regions, &Options::default());
    assert_eq!(located.markers.len(), 3);
    for (m, t) in located.markers.iter().zip(&truth) {
        let pose = m.pose.as_ref().expect("a pose");
        let error_mm = (pose.centre_mm - Vector3::from(t.position_mm)).norm();
        assert!(error_mm < 2.0, "{:?}: {error_mm} mm", m.code.candidate.text);
    }
}
