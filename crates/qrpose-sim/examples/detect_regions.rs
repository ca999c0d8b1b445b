//! What detection restricted to the tracks' regions costs next to the whole-frame search, on
//! the same frames: rendered multi-code frames (the generator of the detection benchmark,
//! 1280 × 720, 2-6 codes of 30-120 mm at 0.3-2 m, blur σ 0.6 px, noise 2, JPEG 90).
//!
//! Per frame: `detect_within` (auto, `balanced`, default deadline) on the whole frame; then
//! `detect_in_regions` with one region per code the whole frame read (a live track), its true
//! corners moved by up to ±`shift` px (a tracker's prediction error) with a margin of a
//! quarter of the code's side plus that shift; and once more with each region moved to the
//! mirrored place of the frame where there is no code (a track whose code is gone: above
//! `fast`, every crop pass runs). Each time is the least of five runs. Refining the corners
//! of the codes found, which both searches do, is timed on its own too: it is the floor of
//! the regions' time.
//!
//! `cargo run --release -p qrpose-sim --example detect_regions -- [frames] [shift_px]
//! [effort]` (defaults 30, 3, the regions' effort `balanced`; the whole frame is always read
//! at `balanced`).

use qrpose_core::geometry::frames::PixelPoint;
use qrpose_detect::decode::{DecodeLimits, decode_gray};
use qrpose_detect::refine::refine_corners;
use qrpose_detect::{
    Budget, Detection, DetectorChoice, Effort, SearchRegion, detect_in_regions, detect_within,
};
use qrpose_sim::render::{
    Effects, Encoding, GroundTruth, SceneRanges, quads_overlap, random_scene, render_scene,
};
use std::time::Instant;

/// The least time of `runs` runs of `f`, ms, and its last result.
fn timed<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = f();
    for _ in 0..runs {
        let t = Instant::now();
        out = f();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (best, out)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// A deterministic shift in −1..1 from a seed (splitmix64).
fn unit(seed: u64) -> f64 {
    let mut z = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    // The top 53 bits as a fraction of 2^53, exactly representable.
    #[allow(clippy::cast_precision_loss)]
    let f = (z >> 11) as f64 / (1u64 << 53) as f64;
    2.0 * f - 1.0
}

fn longest_side_px(c: &[[f64; 2]; 4]) -> f64 {
    (0..4)
        .map(|i| {
            let (a, b) = (c[i], c[(i + 1) % 4]);
            (a[0] - b[0]).hypot(a[1] - b[1])
        })
        .fold(0.0, f64::max)
}

/// The region of a live track: the corners moved by `offset` px, margin a quarter of the
/// side plus the shift.
fn region(corners: &[[f64; 2]; 4], offset: [f64; 2], shift_px: f64) -> SearchRegion {
    SearchRegion::Quad {
        corners_px: corners.map(|[u, v]| PixelPoint::new(u + offset[0], v + offset[1])),
        margin_px: 0.25 * longest_side_px(corners) + shift_px,
    }
}

fn decoded(d: &Detection) -> Vec<String> {
    d.codes
        .iter()
        .filter_map(|c| c.candidate.text.clone())
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let frames: u64 = args.next().map_or(Ok(30), |a| a.parse())?;
    let shift_px: f64 = args.next().map_or(Ok(3.0), |a| a.parse())?;
    let region_effort = match args.next().as_deref() {
        None | Some("balanced") => Effort::Balanced,
        Some("fast") => Effort::Fast,
        Some("thorough") => Effort::Thorough,
        Some(other) => return Err(format!("effort {other}: fast, balanced or thorough").into()),
    };
    let effects = |seed| Effects {
        supersample: 4,
        blur_px: 0.6,
        noise: 2.0,
        encoding: Encoding::Jpeg(90),
        seed,
        ..Effects::default()
    };
    let budget = Budget::default();
    let region_budget = Budget::new(region_effort, None);
    let (mut ratios, mut ratios_gone) = (Vec::new(), Vec::new());
    let (mut full_ms, mut crops_ms, mut gone_ms) = (Vec::new(), Vec::new(), Vec::new());
    let mut refine_ms = Vec::new();
    let (mut tracked, mut reread) = (0usize, 0usize);
    println!("frame codes read  whole_ms  regions_ms  ratio  read_in_regions  gone_ms");
    for seed in 0..frames {
        let scene = random_scene(seed, &SceneRanges::default())?;
        let rendered = render_scene(&scene, &effects(seed))?;
        let image = decode_gray(&rendered.encoded, &DecodeLimits::default())?;
        let (whole_ms, whole) = timed(5, || detect_within(&image, DetectorChoice::Auto, &budget));
        let whole = whole?;
        let read = decoded(&whole);
        // The truth of every code the whole frame read (in the scene's order), its payload.
        let live: Vec<(&GroundTruth, String)> = rendered
            .truth
            .iter()
            .zip(&scene.codes)
            .filter_map(|(t, c)| Some((t, String::from_utf8(c.payload.clone()).ok()?)))
            .filter(|(_, p)| read.contains(p))
            .collect();
        if live.is_empty() {
            continue;
        }
        let regions: Vec<SearchRegion> = live
            .iter()
            .enumerate()
            .map(|(k, (t, _))| {
                let s = seed * 64 + 2 * k as u64;
                region(
                    &t.corners_px,
                    [shift_px * unit(s), shift_px * unit(s + 1)],
                    shift_px,
                )
            })
            .collect();
        let (regions_ms, crops) = timed(5, || detect_in_regions(&image, &regions, &region_budget));
        let found = decoded(&crops);
        let hits = live.iter().filter(|(_, p)| found.contains(p)).count();
        // Refining the corners, which both searches do for every code they keep.
        let (refine_time_ms, _) = timed(5, || {
            crops
                .codes
                .iter()
                .map(|c| refine_corners(&image, &c.candidate.corners_px, c.candidate.module_count))
                .collect::<Vec<_>>()
        });
        refine_ms.push(refine_time_ms);
        // The same regions where the codes are not: mirrored across the frame, kept only
        // where they overlap no code.
        let width = image.width() as f64;
        let gone: Vec<SearchRegion> = live
            .iter()
            .map(|(t, _)| t.corners_px.map(|[u, v]| [width - 1.0 - u, v]))
            .filter(|m| {
                !rendered
                    .truth
                    .iter()
                    .any(|t| quads_overlap(m, &t.corners_px))
            })
            .map(|m| region(&m, [0.0, 0.0], shift_px))
            .collect();
        let (gone_time_ms, _) = timed(5, || detect_in_regions(&image, &gone, &region_budget));
        tracked += live.len();
        reread += hits;
        ratios.push(regions_ms / whole_ms);
        full_ms.push(whole_ms);
        crops_ms.push(regions_ms);
        if !gone.is_empty() {
            ratios_gone.push(gone_time_ms / whole_ms);
            gone_ms.push(gone_time_ms);
        }
        println!(
            "{seed:5} {:5} {:4} {whole_ms:9.2} {regions_ms:11.2} {:6.3} {hits:8}/{:<7} {}",
            rendered.truth.len(),
            read.len(),
            regions_ms / whole_ms,
            live.len(),
            if gone.is_empty() {
                "-".to_owned()
            } else {
                format!("{gone_time_ms:.2} ({} regions)", gone.len())
            },
        );
    }
    println!();
    println!(
        "median whole frame {:.2} ms, regions {:.2} ms, ratio {:.3} (max {:.3}); codes read \
         again in their regions {reread}/{tracked}",
        median(full_ms),
        median(crops_ms),
        median(ratios.clone()),
        ratios.iter().copied().fold(0.0, f64::max),
    );
    println!(
        "refining the corners of the codes read in the regions: median {:.2} ms",
        median(refine_ms)
    );
    println!(
        "regions without their codes: median {:.2} ms, ratio to the whole frame {:.3} (max {:.3})",
        median(gone_ms),
        median(ratios_gone.clone()),
        ratios_gone.iter().copied().fold(0.0, f64::max),
    );
    Ok(())
}
