//! Each warning raised by a set built to raise it, and none on a good set.

mod support;

use qrpose_calib::warnings::{
    CORNER_CELL_MIN_POINTS, MAX_FOCAL_STD_FRACTION, MIN_NORMAL_SPREAD_RAD, RECOMMENDED_VIEWS,
};
use qrpose_calib::{ImageCorner, Options, View, Warning, calibrate};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use support::{
    GOOD_POSITIONS, IMAGE, ViewSpec, barrel_camera, good_set, observe, pose_at, qr_target_mm,
    set_of, tilted,
};

fn warnings_of(views: &[View], options: &Options) -> Vec<Warning> {
    calibrate(views, IMAGE, options)
        .expect("calibrates")
        .warnings
}

fn names(warnings: &[Warning]) -> Vec<&'static str> {
    warnings.iter().map(Warning::name).collect()
}

#[test]
fn a_good_set_raises_no_warning() {
    for seed in 0..3 {
        let set = good_set(&barrel_camera(), 0.2, 20 + seed);
        assert_eq!(
            names(&warnings_of(&set.views, &Options::default())),
            Vec::<&str>::new()
        );
    }
}

#[test]
fn four_views_raise_too_few_views() {
    let set = good_set(&barrel_camera(), 0.2, 1);
    let w = warnings_of(&set.views[..4], &Options::default());
    assert!(
        w.contains(&Warning::TooFewViews {
            used: 4,
            recommended: RECOMMENDED_VIEWS
        }),
        "{w:?}"
    );
}

#[test]
fn views_of_one_orientation_raise_single_angle_and_need_the_closed_form_fallback() {
    // Eight views whose target planes are parallel (tilted 30° the same way), spread over
    // the image, each spun differently about its own normal.
    let camera = barrel_camera();
    let target = qr_target_mm();
    let mut rng = StdRng::seed_from_u64(3);
    let views: Vec<View> = GOOD_POSITIONS[7..15]
        .iter()
        .map(|&(fu, fv)| {
            let r = tilted(30f64.to_radians(), 0.4, rng.gen_range(0.0..6.0));
            let pose = pose_at(&camera, fu * IMAGE.width(), fv * IMAGE.height(), 650.0, r);
            observe(&camera, &pose, &target, 0.2, &mut rng).expect("inside the image")
        })
        .collect();
    let w = warnings_of(&views, &Options::default());
    let names = names(&w);
    assert!(names.contains(&"single_angle"), "{w:?}");
    assert!(names.contains(&"closed_form_fallback"), "{w:?}");
    for warning in &w {
        if let Warning::SingleAngle {
            normal_spread_rad,
            min_spread_rad,
        } = warning
        {
            assert!(normal_spread_rad < min_spread_rad && *min_spread_rad == MIN_NORMAL_SPREAD_RAD);
        }
    }
}

#[test]
fn codes_seen_only_near_the_centre_leave_every_corner_uncovered() {
    let specs: Vec<ViewSpec> = [
        (0.4, 0.4),
        (0.6, 0.4),
        (0.6, 0.6),
        (0.4, 0.6),
        (0.5, 0.5),
        (0.45, 0.55),
    ]
    .iter()
    .cycle()
    .take(10)
    .map(|&at| ViewSpec {
        jitter: 0.03,
        depth_mm: (450.0, 700.0),
        ..ViewSpec::good(at)
    })
    .collect();
    let set = set_of(&barrel_camera(), &specs, 0.2, 9);
    let r = calibrate(&set.views, IMAGE, &Options::default()).expect("calibrates");
    assert!(
        r.warnings.contains(&Warning::CornersNotCovered {
            corners: ImageCorner::ALL.to_vec()
        }),
        "{:?}",
        r.warnings
    );
    let g = r.coverage.grid;
    for (row, col) in [(0, 0), (0, g - 1), (g - 1, 0), (g - 1, g - 1)] {
        assert!(r.coverage.count(row, col) < CORNER_CELL_MIN_POINTS);
    }
}

#[test]
fn slight_tilts_and_noisy_points_leave_the_focal_length_uncertain() {
    // Eight views tilted only 10-20° (still from different directions), 1 px of noise.
    let specs: Vec<ViewSpec> = GOOD_POSITIONS[..8]
        .iter()
        .map(|&at| ViewSpec {
            tilt_rad: (10f64.to_radians(), 20f64.to_radians()),
            ..ViewSpec::good(at)
        })
        .collect();
    let set = set_of(&barrel_camera(), &specs, 1.0, 0);
    let w = warnings_of(&set.views, &Options::default());
    let Some(Warning::FocalLengthUncertain {
        fx_std_fraction,
        max_fraction,
        ..
    }) = w.iter().find(|w| w.name() == "focal_length_uncertain")
    else {
        panic!("no focal_length_uncertain in {w:?}");
    };
    assert!(*fx_std_fraction > MAX_FOCAL_STD_FRACTION && *max_fraction == MAX_FOCAL_STD_FRACTION);
    assert!(!names(&w).contains(&"single_angle"), "{w:?}");
}

#[test]
fn an_iteration_budget_of_one_raises_not_converged() {
    let set = good_set(&barrel_camera(), 0.2, 2);
    let options = Options {
        max_iterations: 1,
        ..Options::default()
    };
    let w = warnings_of(&set.views, &options);
    assert!(names(&w).contains(&"not_converged"), "{w:?}");
}

#[test]
fn every_warning_has_a_stable_snake_case_name_and_a_message() {
    let all = [
        Warning::TooFewViews {
            used: 4,
            recommended: 6,
        },
        Warning::SingleAngle {
            normal_spread_rad: 0.1,
            min_spread_rad: 0.26,
        },
        Warning::CornersNotCovered {
            corners: vec![ImageCorner::TopLeft],
        },
        Warning::FocalLengthUncertain {
            fx_std_fraction: 0.01,
            fy_std_fraction: 0.01,
            max_fraction: 0.005,
        },
        Warning::ClosedFormFallback {
            assumed: qrpose_calib::ClosedFormAssumption::ZeroSkew,
        },
        Warning::NotConverged { iterations: 3 },
    ];
    assert_eq!(
        names(&all),
        [
            "too_few_views",
            "single_angle",
            "corners_not_covered",
            "focal_length_uncertain",
            "closed_form_fallback",
            "not_converged"
        ]
    );
    for w in &all {
        assert!(w.to_string().len() > 20, "{w}");
    }
    assert!(
        Warning::CornersNotCovered {
            corners: vec![ImageCorner::BottomRight]
        }
        .to_string()
        .contains("bottom_right")
    );
}
