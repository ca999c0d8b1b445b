//! Unit tests of `auto`'s second passes: built lazily, skipped without a variant, listed
//! cheapest first.

use super::passes::{SecondPass, look_closer, second_passes};
use super::*;
use crate::test_frames::DrawnCode;
use std::borrow::Cow;
use std::cell::Cell;
use std::time::Duration;

fn tiny() -> GrayImage {
    GrayImage::new(4, 4, vec![128; 16]).expect("a size")
}

/// A second pass builds its variant only after the deadline check: a spent deadline
/// builds nothing (on a 1080p frame the double-scale sharpened variant alone cost tens
/// of ms that no pass report showed), and a pass that runs is logged once.
#[test]
fn a_second_pass_builds_its_variant_only_when_it_may_run() {
    let image = tiny();
    let built = Cell::new(0);
    let image = &image;
    let built = &built;
    let pass = || {
        SecondPass::new("probe", detector_for(Backend::Rxing).ok(), 1.0, move || {
            built.set(built.get() + 1);
            Some(Cow::Borrowed(image))
        })
        .expect("rxing is always built")
    };
    let mut spent = PassLog::new(Duration::ZERO);
    assert!(
        pass()
            .run("whole ", &mut spent, |_, _, _| Vec::new())
            .is_none()
    );
    assert_eq!(built.get(), 0, "nothing is built after the deadline");
    assert!(spent.budget_exhausted && spent.passes.is_empty());

    let mut roomy = PassLog::new(Duration::from_secs(60));
    let read = pass().run("whole ", &mut roomy, |_, variant, scale| {
        assert_eq!((variant.width(), scale), (4, 1.0));
        Vec::new()
    });
    assert_eq!(read, Some(Vec::new()));
    assert_eq!(built.get(), 1);
    let names: Vec<&str> = roomy.passes.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["whole probe"]);
}

/// A variant that does not exist (nothing to stretch) skips its pass without a report.
#[test]
fn a_pass_without_a_variant_is_skipped_silently() {
    let mut log = PassLog::new(Duration::from_secs(60));
    let pass = SecondPass::new("stretched", detector_for(Backend::Rxing).ok(), 1.0, || None)
        .expect("rxing is always built");
    let read = pass.run("region 0 ", &mut log, |_, _, _| unreachable!("no variant"));
    assert_eq!(read, Some(Vec::new()));
    assert!(log.passes.is_empty() && !log.budget_exhausted);
}

/// The passes offered for a small frame, in order, without building any variant.
#[test]
fn second_passes_are_listed_cheapest_first() {
    let image = tiny();
    let names: Vec<&str> = second_passes(&image, Backend::Rxing)
        .iter()
        .map(|p| p.name)
        .collect();
    assert_eq!(
        names,
        [
            "global-histogram",
            "denoised",
            "stretched",
            "inverted",
            "sharpened",
            "double",
            "double sharpened"
        ]
    );
    let closer: Vec<&str> = look_closer(&image, Backend::Rxing)
        .iter()
        .map(|p| p.name)
        .collect();
    assert_eq!(closer.last(), Some(&"rqrr"));
}

/// Step 2 reads a region's crop at double scale only up to REGION_DOUBLE_MAX_SIDE_PX: on a
/// larger crop the doubled copies cost 20-50 ms each on 12 MP photos and read no new code
/// of the benchmark sets. Never the negative.
#[test]
fn a_large_regions_crop_is_not_read_at_double_scale() {
    let names = |w: usize, h: usize| -> Vec<&'static str> {
        let crop = GrayImage::new(w, h, vec![128; w * h]).expect("a size");
        region_passes(&crop, Backend::Rxing)
            .iter()
            .map(|p| p.name)
            .collect()
    };
    let side = REGION_DOUBLE_MAX_SIDE_PX;
    let small = names(side, side / 2);
    assert!(small.contains(&"double") && small.contains(&"double sharpened"));
    let large = names(side + 1, side / 2);
    assert!(!large.iter().any(|n| n.starts_with("double")), "{large:?}");
    assert_eq!(large.last(), Some(&"rqrr"));
    assert!(!small.contains(&"inverted") && !large.contains(&"inverted"));
}

/// The zxing-cpp build looks closer at a region with the default build's passes first, in
/// the same order (so it reads every region the default build reads), then with the image
/// variants read by zxing-cpp, logged under its name.
#[cfg(feature = "zxing-cpp")]
#[test]
fn the_zxing_cpp_build_looks_closer_with_the_default_passes_first() {
    let image = tiny();
    let listed = |best| -> Vec<(&'static str, Option<Backend>)> {
        look_closer(&image, best)
            .iter()
            .map(|p| (p.name, p.backend))
            .collect()
    };
    let default = listed(Backend::Rxing);
    let zxing = listed(Backend::ZxingCpp);
    assert_eq!(zxing.get(..default.len()), Some(default.as_slice()));
    let more = zxing.get(default.len()..).unwrap_or_default();
    assert!(!more.is_empty());
    assert!(
        more.iter().all(|(_, b)| *b == Some(Backend::ZxingCpp)),
        "{more:?}"
    );
}

/// A 1280 × 720 frame of grey 200, dark (40) where `dark(x, y)`.
fn frame_with(dark: impl Fn(usize, usize) -> bool) -> GrayImage {
    let (w, h) = (1280, 720);
    let pixels = (0..w * h)
        .map(|i| if dark(i % w, i / w) { 40 } else { 200 })
        .collect();
    GrayImage::new(w, h, pixels).expect("a size")
}

/// Whether module (mx, my) is dark in a finder pattern whose top-left module is (0, 0).
fn finder_dark(mx: usize, my: usize) -> bool {
    let ring = mx.min(my).min(6 - mx.min(6)).min(6 - my.min(6));
    mx < 7 && my < 7 && ring != 1
}

/// The names of the passes in `log` after the zxing-cpp build's own first read: a build with
/// the `zxing-cpp` feature reads the whole frame with zxing-cpp first (module docs, step 1)
/// and then runs the default build's passes, which the tests below check.
fn default_build_passes(log: &PassLog) -> Vec<&str> {
    let names: Vec<&str> = log.passes.iter().map(|p| p.name.as_str()).collect();
    if cfg!(feature = "zxing-cpp") {
        assert_eq!(names.first(), Some(&"zxing-cpp full"), "{names:?}");
        names[1..].to_vec()
    } else {
        names
    }
}

/// The names of the passes `balanced` ran on `image` ([`default_build_passes`]).
fn balanced_passes(image: &GrayImage) -> Vec<String> {
    let mut log = PassLog::new(Duration::from_secs(60));
    let _ = find_candidates(image, Effort::Balanced, &mut log);
    default_build_passes(&log)
        .into_iter()
        .map(str::to_owned)
        .collect()
}

/// A frame whose whole-frame reads see no symbol, no triple and no finder pattern gets no
/// whole-frame sharpened read and no crop pass (before the evidence gate it paid the
/// sharpened read, 5 ms at 1280 × 720, more than all the other passes together): only the
/// sharpened reads of its busiest tiles, at most [`sharpened::TILE_PROBES`] small crops.
#[test]
fn a_frame_without_evidence_runs_only_the_whole_frame_reads_and_tile_probes() {
    // Stripes: sharp texture, but nothing finder-like.
    let image = frame_with(|x, y| (x / 37 + y / 53) % 2 == 0 && (x % 37) < 20);
    let passes = balanced_passes(&image);
    let (first, rest) = passes.split_at(3.min(passes.len()));
    assert_eq!(
        first,
        ["rxing full", "rxing half", "rxing half global-histogram"],
        "{passes:?}"
    );
    assert!(
        (1..=sharpened::TILE_PROBES).contains(&rest.len()),
        "{passes:?}"
    );
    for (k, pass) in rest.iter().enumerate() {
        assert_eq!(pass, &format!("sharpened tile {k}"), "{passes:?}");
    }
}

/// A frame without evidence and without fine detail (a smooth ramp: no tile reaches
/// [`sharpened::TILE_MIN_DETAIL`]) stops after the whole-frame reads.
#[test]
fn a_smooth_frame_without_evidence_stops_after_the_whole_frame_reads() {
    let (w, h) = (1280, 720);
    let pixels = (0..w * h)
        .map(|i| (60 + (i % w) * 120 / w + (i / w) * 40 / h) as u8)
        .collect();
    let image = GrayImage::new(w, h, pixels).expect("a size");
    let passes = balanced_passes(&image);
    assert_eq!(
        passes,
        ["rxing full", "rxing half", "rxing half global-histogram"],
        "{passes:?}"
    );
}

/// Three finder patterns of a 21-module symbol with nothing readable between them: step 1
/// finds the triple but cannot read it, and that evidence sends `balanced` to the crop
/// passes of step 2 on its region (and nothing on the rest of the frame).
#[test]
fn a_frame_with_an_unread_triple_runs_the_crop_passes() {
    let (module_px, x0, y0) = (5, 500, 250);
    let image = frame_with(|x, y| {
        let (Some(dx), Some(dy)) = (x.checked_sub(x0), y.checked_sub(y0)) else {
            return false;
        };
        let (mx, my) = (dx / module_px, dy / module_px);
        finder_dark(mx, my)
            || (mx >= 14 && finder_dark(mx - 14, my))
            || (my >= 14 && finder_dark(mx, my - 14))
    });
    let passes = balanced_passes(&image);
    assert!(
        passes.iter().any(|p| p.starts_with("region 0 ")),
        "{passes:?}"
    );
    assert!(
        !passes.iter().any(|p| p.starts_with("whole ")),
        "{passes:?}"
    );
}

/// A frame whose full-resolution read decodes its code and leaves no finder pattern or
/// triple unexplained is done after that read: the reduced levels would only read the same
/// code again (the speed benchmark's one-code frame).
#[test]
fn a_frame_read_whole_at_full_resolution_stops_after_that_read() {
    let code = DrawnCode::new("ONE-CODE", 6, 400, 200);
    let image = frame_with(|x, y| code.dark(x, y));
    let mut log = PassLog::new(Duration::from_secs(60));
    let found = find_candidates(&image, Effort::Balanced, &mut log);
    let texts: Vec<_> = found.iter().filter_map(|c| c.text.as_deref()).collect();
    assert_eq!(texts, ["ONE-CODE"]);
    assert_eq!(default_build_passes(&log), ["rxing full"]);
}

/// A frame of at most [`WHOLE_FRAME_MAX_PIXELS`] is read as one crop whatever step 1 saw:
/// a light-on-dark code, which shows step 1 no finder pattern, is read there by step 3's
/// negative (the evidence gate once skipped it and lost four of zxing-cpp's test images).
#[test]
fn a_small_frame_without_evidence_still_gets_every_pass() {
    // Light modules (200) on a dark ground (40).
    let image = DrawnCode::new("LIGHT-ON-DARK", 6, 150, 100).frame(480, 360, 200, 40);
    assert!(image.pixels().len() <= WHOLE_FRAME_MAX_PIXELS);
    let mut log = PassLog::new(Duration::from_secs(60));
    let found = find_candidates(&image, Effort::Balanced, &mut log);
    let texts: Vec<_> = found.iter().filter_map(|c| c.text.as_deref()).collect();
    let passes = default_build_passes(&log);
    assert_eq!(texts, ["LIGHT-ON-DARK"], "{passes:?}");
    assert_eq!(passes.first(), Some(&"rxing full"), "{passes:?}");
    assert!(passes.contains(&"whole inverted"), "{passes:?}");
}

/// A located symbol without a payload is re-read through its module grid as a pass of its
/// own (`re-read`, counting what it decoded), once per place: its time is in the log like
/// every other pass's.
#[test]
fn the_re_read_of_a_located_symbol_is_a_logged_pass_once_per_place() {
    let code = DrawnCode::new("RE-READ", 6, 400, 200);
    let image = frame_with(|x, y| code.dark(x, y));
    // Whole-pixel corners about a pixel off, in qr order, as a backend locates them.
    let (lo_u, lo_v) = (code.x0 as f64 - 0.5, code.y0 as f64 - 0.5);
    let side = (code.modules * code.module_px) as f64;
    let corners = [(0.0, 0.0), (side, 0.0), (side, side), (0.0, side)]
        .map(|(du, dv)| PixelPoint::new((lo_u + du + 1.0).round(), (lo_v + dv - 1.0).round()));
    let located = Candidate {
        corners_px: corners,
        payload: None,
        text: None,
        module_count: Some(code.modules),
        backend: Backend::Rxing,
    };
    let mut finds = Finds {
        image: &image,
        found: Vec::new(),
        regions: Vec::new(),
        tried: Vec::new(),
        patterns: Vec::new(),
        aside: Vec::new(),
    };
    let mut log = PassLog::new(Duration::from_secs(60));
    finds.add(vec![located.clone()], &mut log);
    let passes: Vec<(&str, usize)> = log
        .passes
        .iter()
        .map(|p| (p.name.as_str(), p.decoded))
        .collect();
    assert_eq!(passes, [("re-read", 1)]);
    let texts: Vec<_> = finds
        .found
        .iter()
        .filter_map(|c| c.text.as_deref())
        .collect();
    assert_eq!(texts, ["RE-READ"]);

    finds.add(vec![located], &mut log);
    assert_eq!(log.passes.len(), 1, "the same place is not re-read twice");
}
