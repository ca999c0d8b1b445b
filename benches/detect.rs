//! Speed of the image path: decode + detect + refine of a JPEG frame with one code.
//!
//! ```sh
//! cargo bench --bench detect                      # rqrr, rxing, auto
//! cargo bench --features zxing-cpp --bench detect # plus zxing-cpp alone (decode + detect)
//! ```
//! Run with `taskset -c 0` (or on an idle machine) for the one-core median.

mod common;

use common::{FRAMES, frame};
use criterion::{Criterion, criterion_group, criterion_main};
use qrpose::detect::{Backend, DetectorChoice, decode, detect_codes, find_candidates};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    for (name, w, h, f) in FRAMES {
        let jpeg = frame(w, h, f);
        let limits = decode::DecodeLimits::default();
        c.bench_function(&format!("decode only {name}"), |b| {
            b.iter(|| decode::decode_gray(black_box(&jpeg), &limits))
        });
        let mut choices = vec![
            ("auto", DetectorChoice::Auto),
            ("rxing", DetectorChoice::Only(Backend::Rxing)),
            ("rqrr", DetectorChoice::Only(Backend::Rqrr)),
        ];
        if Backend::ZxingCpp.is_built() {
            choices.push(("zxing-cpp", DetectorChoice::Only(Backend::ZxingCpp)));
        }
        for (backend, choice) in &choices {
            c.bench_function(&format!("decode+detect+refine {backend} {name}"), |b| {
                b.iter(|| {
                    let image = decode::decode_gray(black_box(&jpeg), &limits).ok();
                    image.map(|i| detect_codes(&i, *choice))
                })
            });
        }
        if Backend::ZxingCpp.is_built() {
            c.bench_function(
                &format!("decode+detect (no refine) zxing-cpp {name}"),
                |b| {
                    b.iter(|| {
                        let image = decode::decode_gray(black_box(&jpeg), &limits).ok();
                        image.map(|i| find_candidates(&i, DetectorChoice::Only(Backend::ZxingCpp)))
                    })
                },
            );
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(4));
    targets = bench
}
criterion_main!(benches);
