//! Small blurred codes that show `auto` only two of their three finder patterns:
//! `balanced` reads them on a crop around the pair
//! (`crates/qrpose-detect/src/search/pairs.rs`), not by reading the whole frame again.

use nalgebra::{Matrix3, Rotation3, Vector3};
use qrpose::detect::decode::{DecodeLimits, GrayImage, decode_gray};
use qrpose::detect::{Budget, Detection, DetectorChoice, Effort, detect_within};
use qrpose::geometry::{camera::Camera, marker::Marker};
use qrpose_sim::render::{EcLevel, Effects, Encoding, Scene, render};
use std::time::Duration;

use crate::multicode;

/// A deadline no pass here comes near.
const ROOMY: Duration = Duration::from_secs(60);

fn detect(image: &GrayImage, effort: Effort) -> Detection {
    let budget = Budget::new(effort, Some(ROOMY));
    detect_within(image, DetectorChoice::Auto, &budget).expect("auto")
}

fn texts(detection: &Detection) -> Vec<String> {
    detection
        .codes
        .iter()
        .filter_map(|c| c.candidate.text.clone())
        .collect()
}

/// The passes that decoded something.
fn decoded_by(detection: &Detection) -> Vec<&str> {
    detection
        .log
        .passes
        .iter()
        .filter(|p| p.decoded > 0)
        .map(|p| p.name.as_str())
        .collect()
}

/// Image 0048 of the rendered accuracy set (`cargo run --release --example accuracy_images
/// -- --count 200`, its `0048.json`): a 45 mm code of 25 modules at 0.76 m, 2.3 px per
/// module, blur σ 1.33 px, JPEG 91, in a 1280 × 720 frame with clutter.
fn accuracy_set_0048() -> GrayImage {
    let marker = Marker::try_new(45.376_547_477_088_35).expect("valid size");
    let r = Rotation3::from_matrix_unchecked(Matrix3::new(
        0.086_593_395_866_976_95,
        -0.995_592_378_971_439_5,
        -0.036_019_421_514_157_74,
        0.995_575_213_526_677_4,
        0.085_154_402_401_811_21,
        0.039_733_134_320_122_02,
        -0.036_490_793_407_864_985,
        -0.039_300_670_294_283_09,
        0.998_560_904_157_019_6,
    ));
    let scene = Scene {
        payload: b"SKU-rHdksPPoE0owyj".to_vec(),
        ec_level: EcLevel::M,
        marker,
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("valid camera"),
        width_px: 1280,
        height_px: 720,
        pose: marker.pose_centred_at(
            r,
            Vector3::new(
                263.286_701_014_377_8,
                -135.951_917_733_916_25,
                764.636_508_481_019,
            ),
        ),
    };
    let effects = Effects {
        supersample: 4,
        blur_px: 1.334_204_326_376_326_1,
        noise: 1.795_944_409_838_665_4,
        lighting: 0.141_157_614_086_213_52,
        clutter: 25,
        dark_level: 36.561_363_759_080_5,
        light_level: 204.642_100_691_763_55,
        quiet_zone_modules: 4.0,
        encoding: Encoding::Jpeg(91),
        seed: 1_000_051,
    };
    let jpeg = render(&scene, &effects).expect("renders").encoded;
    decode_gray(&jpeg, &DecodeLimits::default()).expect("decodes")
}

/// Step 1 sees none of its finder patterns and the sharpened read two, no triple; `balanced`
/// read 99.0 % of the accuracy set without the pair's crop (this frame one of the two
/// misses, read then only by `thorough`'s whole-frame double-scale sharpened pass), 99.5 %
/// with it.
#[test]
fn balanced_reads_a_small_blurred_code_from_a_pair_of_its_finder_patterns() {
    let image = accuracy_set_0048();
    assert!(texts(&detect(&image, Effort::Fast)).is_empty());
    let balanced = detect(&image, Effort::Balanced);
    assert_eq!(texts(&balanced), ["SKU-rHdksPPoE0owyj"]);
    let by = decoded_by(&balanced);
    assert!(
        by.iter().all(|name| name.starts_with("sharpened pair")),
        "{by:?}"
    );
    assert!(
        balanced
            .log
            .passes
            .iter()
            .all(|p| !p.name.starts_with("whole")),
        "no whole-frame variant runs"
    );
}

/// Frame 37 of `scripts/multicode_bench.py` (six codes; blur σ 0.648 px, noise 1.741, JPEG
/// 76): its code S37-C0 (44 px, 2.1 px per module, tilted 12°) shows the sharpened read two
/// finder patterns; before the pair's crop only `thorough`'s whole-frame passes read it.
#[test]
fn balanced_reads_a_small_code_next_to_others_from_a_pair_of_its_finder_patterns() {
    let image = multicode::frame(37, 0.648, 1.741, 76).image;
    let balanced = detect(&image, Effort::Balanced);
    assert!(
        texts(&balanced).iter().any(|t| t == "S37-C0-UNAL1RPI4J"),
        "{:?}",
        texts(&balanced)
    );
    assert!(
        decoded_by(&balanced)
            .iter()
            .any(|name| name.starts_with("sharpened pair")),
        "{:?}",
        decoded_by(&balanced)
    );
}

/// Asserts that `balanced` reads `text` in `image`, and by a pass whose name starts with
/// `by` and contains `variant`.
fn assert_read_by(image: &GrayImage, text: &str, by: &str, variant: &str) {
    let balanced = detect(image, Effort::Balanced);
    assert!(
        texts(&balanced).iter().any(|t| t == text),
        "{text} not in {:?}",
        texts(&balanced)
    );
    let passes = decoded_by(&balanced);
    assert!(
        passes
            .iter()
            .any(|name| name.starts_with(by) && name.contains(variant)),
        "{passes:?}"
    );
}

/// Frame 12 (blur σ 0.774 px, noise 3.261, JPEG 94): its code S12-C4 (32 px, 1.5 px per
/// module) shows the sharpened read two finder patterns; the double-scale crops of the pair
/// do not read it, the quadruple-scale sharpened crop does.
#[test]
fn balanced_reads_a_code_of_under_two_px_per_module_at_quadruple_scale() {
    let image = multicode::frame(12, 0.774, 3.261, 94).image;
    assert_read_by(&image, "S12-C4-", "sharpened pair", "quad sharpened");
}

/// Frame 39 (blur σ 0.613 px, noise 2.188, JPEG 94): one code reads, so the sharpened read
/// does not run; S39-C0 (43 px, 1.7 px per module) shows the full-resolution read one
/// finder pattern, whose crop reads it.
#[test]
fn balanced_reads_a_small_code_from_a_lone_finder_pattern_next_to_a_read_code() {
    let image = multicode::frame(39, 0.613, 2.188, 94).image;
    assert_read_by(&image, "S39-C0-DLLEH6E9MRUAEW", "lone", "");
}

/// Frame 23 (blur σ 0.867 px, noise 2.516, JPEG 76): its code S23-C4 (36 px, 1.7 px per
/// module) is located by the double-scale crop read of a pair of its finder patterns, whose
/// sampled grid does not decode; read again through its module grid on an unsharp-masked
/// copy of the symbol, it does.
#[test]
fn balanced_reads_a_located_small_code_through_its_sharpened_module_grid() {
    let image = multicode::frame(23, 0.867, 2.516, 76).image;
    assert_read_by(
        &image,
        "S23-C4-VVNAOM7ZP",
        "sharpened pair",
        "double sharpened",
    );
}

/// Frame 33 (blur σ 1.078 px, noise 3.851, JPEG 85): its code S33-C3 (44 px, 2.1 px per
/// module) forms a triple on the sharpened copy whose sampled grid does not decode, and no
/// crop of it reads; re-read through its module grid on an unsharp-masked copy of the
/// symbol, it does (before, only `thorough`'s whole-frame passes read it).
#[test]
fn balanced_reads_a_code_located_by_the_sharpened_read_through_its_module_grid() {
    let image = multicode::frame(33, 1.078, 3.851, 85).image;
    assert_read_by(&image, "S33-C3-GR", "rxing sharpened", "");
}
