//! Speed of the image path: decode + detect + refine of a JPEG frame with one code.
//!
//! ```sh
//! cargo bench --bench detect                      # rqrr, rxing, auto
//! cargo bench --features zxing-cpp --bench detect # plus zxing-cpp alone (decode + detect)
//! ```
//! Run with `taskset -c 0` (or on an idle machine) for the one-core median.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use qrpose::detect::{Backend, DetectorChoice, decode, detect_codes, find_candidates};
use qrpose::geometry::{camera::Camera, euler::EulerXyz, frames::MarkerToCamera, marker::Marker};
use qrpose::render::{EcLevel, Effects, Encoding, Scene, render};
use std::hint::black_box;

fn frame(width_px: u32, height_px: u32, f_px: f64) -> Vec<u8> {
    let marker = Marker::try_new(50.0).unwrap_or_else(|_| unreachable!());
    let camera = Camera::from_pixels(
        f_px,
        f_px,
        f64::from(width_px) / 2.0 - 0.5,
        f64::from(height_px) / 2.0 - 0.5,
    )
    .unwrap_or_else(|_| unreachable!());
    let r = EulerXyz::from_degrees(20.0, -15.0, 30.0).to_rotation();
    let centre = Vector3::new(40.0, -20.0, 500.0);
    let scene = Scene {
        payload: b"SKU-0042-warehouse-bin-17".to_vec(),
        ec_level: EcLevel::M,
        marker,
        camera,
        width_px,
        height_px,
        pose: MarkerToCamera::new(r, centre - r * marker.centre().0.coords),
    };
    let effects = Effects {
        blur_px: 0.8,
        noise: 2.0,
        lighting: 0.3,
        clutter: 30,
        encoding: Encoding::Jpeg(85),
        seed: 3,
        ..Effects::default()
    };
    render(&scene, &effects)
        .map(|r| r.encoded)
        .unwrap_or_default()
}

fn bench(c: &mut Criterion) {
    for (name, w, h, f) in [
        ("1280x720", 1280, 720, 1000.0),
        ("1920x1080", 1920, 1080, 1400.0),
    ] {
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
