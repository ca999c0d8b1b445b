//! The price of the overlay: `POST /v1/pose/image/annotated` against `POST /v1/pose/image`
//! on the same 1280×720 frame (target: at most 1.3×), as the two routes' worker
//! jobs run them. The HTTP layer around each is the same and costs tens of µs. The frame is
//! a grey JPEG, so the JPEG variant splices (the `jpeg-overlay` crate, crates/jpeg-overlay,
//! re-encodes only the blocks the overlay touches); "drawing only" times `annotated_image`
//! alone, and "whole frame" the decode-draw-encode path it falls back to.
//!
//! ```sh
//! taskset -c 0 cargo bench --bench annotate
//! ```
//! The ratio of the medians is printed at the end of the run (docs/service.md, The annotated
//! image, gives the measured numbers).

mod common;

use base64::Engine;
use common::{FRAMES, frame};
use criterion::{Criterion, criterion_group, criterion_main};
use qrpose::annotate::raster::{Style, draw_overlay};
use qrpose::annotate::{OutputFormat, annotated_image, codec, overlay};
use qrpose::api::image::{ImageLimits, ImageQuery, answer};
use qrpose::app::ImageAnswer;
use qrpose::detect::cancel::CancelFlag;
use qrpose::geometry::camera::Camera;
use std::hint::black_box;
use std::time::Instant;

fn query() -> ImageQuery {
    ImageQuery {
        fx_px: Some(1000.0),
        fy_px: Some(1000.0),
        cx_px: Some(639.5),
        cy_px: Some(359.5),
        marker_size_mm: Some(50.0),
        ..ImageQuery::default()
    }
}

/// The camera of [`query`], as the routes validate it.
fn camera() -> Option<Camera> {
    query()
        .setup(&ImageLimits::default(), None)
        .ok()
        .map(|setup| setup.pose.camera)
}

/// What the plain route's job does: estimate and serialise (and the answer drawn from).
fn plain(jpeg: &[u8]) -> Option<(ImageAnswer, Vec<u8>)> {
    let setup = query().setup(&ImageLimits::default(), None).ok()?;
    let (answer, response) = answer(&setup, jpeg, CancelFlag::new()).ok()?;
    let json = serde_json::to_vec(&response).ok()?;
    Some((answer, json))
}

/// What the annotated route's job does on top: the camera, the drawing, the encoding and
/// the result header.
fn annotated(jpeg: &[u8], format: OutputFormat) -> Option<(Vec<u8>, String)> {
    let (answer, json) = plain(jpeg)?;
    let image = annotated_image(jpeg, &answer, &camera()?, format).ok()?;
    let header = base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(json);
    Some((image, header))
}

/// The whole-frame path: decode in colour, draw, encode.
fn whole_frame(jpeg: &[u8], answer: &ImageAnswer) -> Option<Vec<u8>> {
    let camera = camera()?;
    let mut raster = codec::decode_rgb(jpeg).ok()?;
    let style = Style::for_image(raster.width_px(), raster.height_px());
    let overlay = overlay::overlay_of(answer, &camera, style.label_height_px());
    draw_overlay(&mut raster, &overlay, &style);
    codec::encode_jpeg(&raster).ok()
}

/// The median time of `f` over `runs` calls, ms.
fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let started = Instant::now();
            f();
            started.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[runs / 2]
}

fn bench(c: &mut Criterion) {
    let (_, width_px, height_px, f_px) = FRAMES[0];
    assert_eq!((width_px, height_px), (1280, 720));
    let jpeg = frame(width_px, height_px, f_px);
    assert!(
        plain(&jpeg).is_some_and(|(a, _)| a.markers.len() == 1),
        "the frame's code must be read"
    );
    c.bench_function("plain 1280x720", |b| b.iter(|| plain(black_box(&jpeg))));
    c.bench_function("annotated jpeg 1280x720", |b| {
        b.iter(|| annotated(black_box(&jpeg), OutputFormat::Jpeg))
    });
    c.bench_function("annotated png 1280x720", |b| {
        b.iter(|| annotated(black_box(&jpeg), OutputFormat::Png))
    });
    let Some((drawn, _)) = plain(&jpeg) else {
        return;
    };
    if let Some(camera) = camera() {
        c.bench_function("drawing only, jpeg 1280x720", |b| {
            b.iter(|| annotated_image(black_box(&jpeg), &drawn, &camera, OutputFormat::Jpeg))
        });
    }
    c.bench_function("drawing only, whole frame jpeg 1280x720", |b| {
        b.iter(|| whole_frame(black_box(&jpeg), &drawn))
    });
    // The ratio, from interleaved runs so that both see the same machine load.
    let (mut plain_ms, mut annotated_ms) = (Vec::new(), Vec::new());
    for _ in 0..15 {
        plain_ms.push(median_ms(9, || {
            black_box(plain(&jpeg));
        }));
        annotated_ms.push(median_ms(9, || {
            black_box(annotated(&jpeg, OutputFormat::Jpeg));
        }));
    }
    plain_ms.sort_by(f64::total_cmp);
    annotated_ms.sort_by(f64::total_cmp);
    let (p, a) = (plain_ms[7], annotated_ms[7]);
    println!(
        "annotated (JPEG) / plain, interleaved medians: {a:.2} ms / {p:.2} ms = {:.2}",
        a / p
    );
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(4));
    targets = bench
}
criterion_main!(benches);
