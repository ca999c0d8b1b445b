//! Statuses and their timing, gating, time handling, parameters and predicted regions.

mod support;

use nalgebra::{Rotation3, Vector3};
use qrpose_core::estimate::estimate_pose;
use qrpose_core::geometry::{frames::PixelPoint, marker::CornerOrder, quad::ImageQuad};
use qrpose_track::{Measurement, Outcome, Param, TrackError, TrackStatus, Tracker, TrackerParams};
use rand::SeedableRng;
use rand::rngs::StdRng;
use support::Scene;

const FRAME_MS: f64 = 1000.0 / 30.0;

fn pose() -> (Rotation3<f64>, Vector3<f64>) {
    (
        Rotation3::new(Vector3::new(0.5, 0.2, 0.1)),
        Vector3::new(30.0, -20.0, 600.0),
    )
}

fn seen(scene: &Scene, payload: Option<&str>, rng: &mut StdRng) -> Measurement {
    let (r, c) = pose();
    scene.observe(&r, &c, payload, rng).expect("in view").1
}

#[test]
fn a_track_is_new_then_tracking_then_coasting_then_lost_once() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(1);
    let params = TrackerParams::default();
    let mut tracker = Tracker::new(params).expect("valid");
    let mut statuses = Vec::new();
    for i in 0..3 {
        let m = seen(&scene, Some("A"), &mut rng);
        let answer = tracker
            .update(f64::from(i) * FRAME_MS, &[m])
            .expect("finite");
        statuses.push(answer.tracks[0].status);
    }
    assert_eq!(
        statuses,
        [
            TrackStatus::New,
            TrackStatus::Tracking,
            TrackStatus::Tracking
        ]
    );
    let last_seen_ms = 2.0 * FRAME_MS;
    let mut lost_at = None;
    for i in 3..40 {
        let t = f64::from(i) * FRAME_MS;
        let answer = tracker.update(t, &[]).expect("finite");
        match answer.tracks.as_slice() {
            [] => break,
            [track] if track.status == TrackStatus::Lost => {
                assert!(lost_at.is_none(), "lost reported twice");
                lost_at = Some(t);
            }
            [track] => {
                assert_eq!(track.status, TrackStatus::Coasting);
                assert!(t - last_seen_ms <= params.coast_ms);
            }
            more => panic!("one track expected: {more:?}"),
        }
    }
    let lost_at = lost_at.expect("lost");
    assert!(lost_at - last_seen_ms > params.coast_ms);
    assert!(lost_at - last_seen_ms <= params.coast_ms + FRAME_MS);
    assert!(tracker.is_empty());
}

#[test]
fn a_coasting_track_seen_again_keeps_its_id_and_tracks() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(2);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    tracker
        .update(0.0, &[seen(&scene, Some("A"), &mut rng)])
        .expect("finite");
    let coasting = tracker.update(100.0, &[]).expect("finite");
    assert_eq!(coasting.tracks[0].status, TrackStatus::Coasting);
    let back = tracker
        .update(300.0, &[seen(&scene, Some("A"), &mut rng)])
        .expect("finite");
    assert_eq!(back.tracks.len(), 1);
    assert_eq!(back.tracks[0].id, "t1");
    assert_eq!(back.tracks[0].status, TrackStatus::Tracking);
    assert_eq!(back.tracks[0].frames_seen, 2);
    assert!(back.tracks[0].confirmed);
}

/// The frame's corners with corner `index` moved by `shift_px` to the right, and the
/// measurement made from them.
fn with_a_bad_corner(scene: &Scene, index: usize, shift_px: f64, rng: &mut StdRng) -> Measurement {
    let (r, c) = pose();
    let mut corners = scene.corners(&r, &c, rng).expect("in view");
    corners[index] = PixelPoint::new(corners[index].u() + shift_px, corners[index].v());
    let quad = ImageQuad::try_new(corners, CornerOrder::Paper).expect("still a quad");
    let e = estimate_pose(&quad, &scene.camera, &scene.marker, &scene.solver).expect("pose");
    Measurement::from_estimate(
        Some("A".into()),
        &scene.marker,
        &quad,
        &e,
        &scene.camera,
        scene.sigma_px,
    )
    .expect("measurement")
}

#[test]
fn an_outlier_is_not_fused_and_says_so_until_the_track_restarts_on_repeated_ones() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(3);
    let params = TrackerParams::default();
    let mut tracker = Tracker::new(params).expect("valid");
    let mut t = 0.0;
    for _ in 0..10 {
        tracker
            .update(t, &[seen(&scene, Some("A"), &mut rng)])
            .expect("finite");
        t += FRAME_MS;
    }
    let before = tracker.tracks()[0].pose;
    let answer = tracker
        .update(t, &[with_a_bad_corner(&scene, 0, 12.0, &mut rng)])
        .expect("finite");
    let a = &answer.assignments[0];
    assert_eq!(a.outcome, Outcome::GatedOut);
    assert_eq!(a.track_id.as_deref(), Some("t1"));
    assert!(a.innovation_d2.is_some_and(|d2| d2 > params.gate_chi2));
    let after = &answer.tracks[0];
    assert_eq!(after.status, TrackStatus::Coasting);
    assert!(
        (after.pose.centre_mm - before.centre_mm).norm() < 0.5,
        "not fused"
    );
    // A good frame is fused again; outliers in a row restart the track, same id.
    t += FRAME_MS;
    let good = tracker
        .update(t, &[seen(&scene, Some("A"), &mut rng)])
        .expect("finite");
    assert_eq!(good.assignments[0].outcome, Outcome::Fused);
    let mut outcomes = Vec::new();
    for _ in 0..params.restart_after_gated {
        t += FRAME_MS;
        let answer = tracker
            .update(t, &[with_a_bad_corner(&scene, 0, 12.0, &mut rng)])
            .expect("finite");
        outcomes.push(answer.assignments[0].outcome);
        assert_eq!(answer.tracks[0].id, "t1");
    }
    assert_eq!(outcomes.last(), Some(&Outcome::Restarted), "{outcomes:?}");
}

#[test]
fn repeated_and_earlier_times_predict_nothing_and_every_output_stays_finite() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(4);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    let times = [0.0, 33.0, 33.0, 20.0, -500.0, 66.0, 66.0, 1e-9, 100.0];
    for t in times {
        let answer = tracker
            .update(t, &[seen(&scene, Some("A"), &mut rng)])
            .expect("finite");
        let track = &answer.tracks[0];
        assert_eq!(track.id, "t1", "one track throughout");
        assert_ne!(track.status, TrackStatus::Lost);
        assert!(track.time_ms >= t.min(100.0) && track.time_ms.is_finite());
        let p = &track.pose;
        for x in p
            .covariance
            .iter()
            .chain(p.centre_mm.iter())
            .chain(p.velocity_mm_s.iter())
        {
            assert!(x.is_finite());
        }
    }
    assert_eq!(
        Ok(tracker.tracks()[0].frames_seen),
        u32::try_from(times.len())
    );
    assert_eq!(
        tracker.tracks()[0].time_ms,
        100.0,
        "the latest time is kept"
    );
}

#[test]
fn a_time_that_is_not_finite_is_refused_and_changes_nothing() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(5);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    tracker
        .update(0.0, &[seen(&scene, Some("A"), &mut rng)])
        .expect("finite");
    let before = tracker.clone();
    for t in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let err = tracker.update(t, &[]).expect_err("refused");
        assert!(matches!(err, TrackError::NonFiniteTime(_)));
        assert!(tracker.predict_regions(t, &scene.camera).is_err());
    }
    assert_eq!(tracker, before);
}

#[test]
fn parameters_out_of_range_are_refused_naming_the_parameter() {
    let cases: [(Param, TrackerParams); 7] = [
        (
            Param::AccelPsd,
            TrackerParams {
                accel_psd_mm2_s3: 0.0,
                ..Default::default()
            },
        ),
        (
            Param::AngularAccelPsd,
            TrackerParams {
                angular_accel_psd_rad2_s3: f64::NAN,
                ..Default::default()
            },
        ),
        (
            Param::SteadyNoiseFactor,
            TrackerParams {
                steady_noise_factor: 2.0,
                ..Default::default()
            },
        ),
        (
            Param::GateChi2,
            TrackerParams {
                gate_chi2: -1.0,
                ..Default::default()
            },
        ),
        (
            Param::CoastMs,
            TrackerParams {
                coast_ms: f64::INFINITY,
                ..Default::default()
            },
        ),
        (
            Param::AmbiguityProbability,
            TrackerParams {
                ambiguity_probability: 0.5,
                ..Default::default()
            },
        ),
        (
            Param::MaxTracks,
            TrackerParams {
                max_tracks: 0,
                ..Default::default()
            },
        ),
    ];
    for (param, params) in cases {
        let err = Tracker::new(params).expect_err("refused");
        assert_eq!(err.param, param, "{err}");
        assert!(err.to_string().contains(param.name()), "{err}");
    }
    assert!(Tracker::new(TrackerParams::default()).is_ok());
}

#[test]
fn a_new_code_beyond_max_tracks_starts_no_track() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(6);
    let params = TrackerParams {
        max_tracks: 1,
        ..Default::default()
    };
    let mut tracker = Tracker::new(params).expect("valid");
    let (r, c) = pose();
    let other = scene
        .observe(
            &r,
            &(c + Vector3::new(-150.0, 0.0, 0.0)),
            Some("B"),
            &mut rng,
        )
        .expect("in view")
        .1;
    let answer = tracker
        .update(0.0, &[seen(&scene, Some("A"), &mut rng), other])
        .expect("finite");
    let outcomes: Vec<Outcome> = answer.assignments.iter().map(|a| a.outcome).collect();
    assert_eq!(outcomes, [Outcome::Created, Outcome::TrackLimit]);
    assert_eq!(answer.tracks.len(), 1);
}

#[test]
fn predicted_regions_hold_the_next_corners_in_qr_order_with_their_uncertainty() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(7);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    // The code moves right at 300 mm/s.
    let (r, c0) = pose();
    let at = |t_ms: f64| c0 + Vector3::new(0.3 * t_ms, 0.0, 0.0);
    let mut t = 0.0;
    tracker
        .update(
            t,
            &[scene
                .observe(&r, &at(t), Some("A"), &mut rng)
                .expect("in view")
                .1],
        )
        .expect("finite");
    let first = tracker
        .predict_regions(t + FRAME_MS, &scene.camera)
        .expect("finite");
    assert!(!first[0].confident, "one frame is not enough to coast on");
    for _ in 0..15 {
        t += FRAME_MS;
        let m = scene
            .observe(&r, &at(t), Some("A"), &mut rng)
            .expect("in view")
            .1;
        tracker.update(t, &[m]).expect("finite");
    }
    let next = t + FRAME_MS;
    let regions = tracker
        .predict_regions(next, &scene.camera)
        .expect("finite");
    assert_eq!(regions.len(), 1);
    let region = &regions[0];
    assert_eq!(
        (region.track_id.as_str(), region.payload.as_str()),
        ("t1", "A")
    );
    assert!(region.confident);
    // The prediction mixes in the at-rest model (the code may stop: crate::imm), which
    // lags a moving code by a frame's motion at its small probability: 3.1 px here, under
    // 3 px (this test's bound then) with the two moving models alone.
    assert!(
        region.corner_sigma_px > 0.0 && region.corner_sigma_px < 3.5,
        "{}",
        region.corner_sigma_px
    );
    let pose = scene.marker.pose_centred_at(r, at(next));
    let truth = CornerOrder::Qr.from_paper(
        scene
            .marker
            .object_points()
            .map(|m| scene.camera.project(&pose.transform(&m)).expect("in view")),
    );
    for (p, q) in region.corners_px.iter().zip(&truth) {
        let miss = (p.0 - q.0).norm();
        assert!(miss < 4.0 * region.corner_sigma_px + 1.0, "{miss} px");
    }
    // qr order: top-left is left of top-right and above bottom-left.
    let [tl, tr, _, bl] = region.corners_px;
    assert!(tl.u() < tr.u() && tl.v() < bl.v());
    let [u0, v0, u1, v1] = region.bounds_px(3.0);
    assert!(u0 < tl.u() && v0 < tl.v() && u1 > tr.u() && v1 > bl.v());
}

#[test]
fn a_coasting_track_whose_prediction_grows_too_uncertain_is_lost_before_coast_ms() {
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(8);
    let params = TrackerParams {
        max_position_sigma_mm: 5.0,
        ..Default::default()
    };
    let mut tracker = Tracker::new(params).expect("valid");
    for i in 0..5 {
        let m = seen(&scene, Some("A"), &mut rng);
        tracker
            .update(f64::from(i) * FRAME_MS, &[m])
            .expect("finite");
    }
    let mut t = 4.0 * FRAME_MS;
    let lost_after_ms = loop {
        t += FRAME_MS;
        let answer = tracker.update(t, &[]).expect("finite");
        if answer.tracks[0].status == TrackStatus::Lost {
            break t - 4.0 * FRAME_MS;
        }
        assert!(t < 1000.0, "never lost");
    };
    assert!(
        lost_after_ms < params.coast_ms,
        "lost after {lost_after_ms} ms"
    );
}

#[test]
fn the_track_settles_the_planar_ambiguity_that_single_frames_leave_open() {
    // 1 m away and tilted 35°: most single frames are flagged ambiguous and some pick the
    // mirror pose.
    let scene = Scene::standard();
    let mut rng = StdRng::seed_from_u64(9);
    let r = Rotation3::new(Vector3::new(0.0, 35f64.to_radians(), 0.0));
    let c = Vector3::new(40.0, 20.0, 1000.0);
    let mut tracker = Tracker::new(TrackerParams::default()).expect("valid");
    let (mut flagged, mut single_wrong, mut filtered_wrong) = (0, 0, 0);
    let mut last = None;
    for i in 0..60 {
        let (e, m) = scene.observe(&r, &c, Some("A"), &mut rng).expect("in view");
        flagged += usize::from(e.diagnostics.ambiguity.is_some_and(|a| a.ambiguous));
        let answer = tracker
            .update(f64::from(i) * FRAME_MS, &[m])
            .expect("finite");
        let track = answer.tracks[0].clone();
        if i >= 4 {
            single_wrong += usize::from(
                qrpose_track::so3::angle_between(&e.pose.rotation(), &r) > 5f64.to_radians(),
            );
            filtered_wrong += usize::from(
                qrpose_track::so3::angle_between(&track.pose.rotation, &r) > 5f64.to_radians(),
            );
        }
        last = Some(track);
    }
    let last = last.expect("a track");
    assert!(flagged > 30, "{flagged} of 60 frames flagged");
    assert!(single_wrong > 0, "some single frames pick the mirror pose");
    assert_eq!(filtered_wrong, 0);
    assert!(last.ambiguity_resolved);
    assert!(
        last.branch_probability > 0.99,
        "{}",
        last.branch_probability
    );
}
