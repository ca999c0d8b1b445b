//! Unit tests of `auto`'s second passes: built lazily, skipped without a variant, listed
//! cheapest first.

use super::passes::{SecondPass, look_closer, second_passes};
use super::*;
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
