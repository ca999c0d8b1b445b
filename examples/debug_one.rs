//! Debug helper: runs each backend on one rendered image and prints raw corners vs truth.
//! `cargo run --release --example debug_one -- target/acc-dev/0000`
use qrpose::detect::{Backend, DetectorChoice, decode, detect_codes};
fn main() {
    let stem = std::env::args().nth(1).unwrap_or_default();
    let bytes = std::fs::read(format!("{stem}.jpg")).unwrap_or_default();
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(format!("{stem}.json")).unwrap_or_default())
            .unwrap_or_default();
    println!(
        "truth {} n={}",
        meta["truth"]["corners_px"], meta["truth"]["module_count"]
    );
    let Ok(img) = decode::decode_gray(&bytes, &decode::DecodeLimits::default()) else {
        return;
    };
    for b in [Backend::Rqrr, Backend::Rxing, Backend::ZxingCpp] {
        if !b.is_built() {
            continue;
        }
        for c in detect_codes(&img, DetectorChoice::Only(b)).unwrap_or_default() {
            println!(
                "{:?} raw {:?} n={:?}",
                b,
                c.candidate.corners_px.map(|p| (p.u(), p.v())),
                c.candidate.module_count
            );
            println!(
                "   scores {:?}",
                qrpose::detect::corners::module_count_scores(&img, &c.candidate.corners_px)
            );
            println!(
                "   refined {:?} {:?} n={:?}",
                c.refinement.corners_px.map(|p| (p.u(), p.v())),
                c.refinement.status,
                c.refinement.module_count
            );
        }
    }
}
