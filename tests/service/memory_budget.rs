//! The memory of the image path, measured on the real binary (Linux `/proc`): a 7000 × 7000
//! all-zero PNG (47 KB on the wire, 49 MP decoded) at `effort=thorough` and two full-size
//! 12 MP frames at once, and the peak resident memory must stay within the budget that
//! docs/deploy.md derives the container limits from:
//!
//!   idle + 3 bytes × (pixels admitted at once) + (body bytes admitted at once) + 32 MiB
//!
//! Before the image path was cut down (whole-frame `f32` planes in the sharpen pass, PNGs
//! decoded in colour first) one such PNG alone took the process from 9 MB to 494 MB: about
//! 10 bytes a pixel. Also: the pixel budget refuses a third large image at once with 503
//! `overloaded` rather than letting it in.

use std::io::Cursor;
use std::time::Duration;

const PATIENCE: Duration = Duration::from_secs(600);
/// Bytes a pixel the image path may hold at its peak (docs/deploy.md).
const BYTES_PER_PIXEL: u64 = 3;
/// Allocator slack, thread stacks, rxing's and rqrr's own tables.
const BASE_BYTES: u64 = 32 << 20;

use crate::support::Server;

/// A field of the server's `/proc/<pid>/status`, bytes.
fn status_bytes(server: &Server, field: &str) -> u64 {
    let status =
        std::fs::read_to_string(format!("/proc/{}/status", server.pid())).expect("Linux /proc");
    let line = status
        .lines()
        .find(|l| l.starts_with(field))
        .unwrap_or_else(|| panic!("{field} in {status}"));
    let kb: u64 = line
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .expect("a number of kB");
    kb * 1024
}

/// `POST /v1/pose/image?query` with `body`: the status and the body of the answer.
fn post(server: &Server, body: Vec<u8>, content_type: &str, query: &str) -> (u16, String) {
    crate::support::tls_provider();
    let response = reqwest::blocking::Client::builder()
        .timeout(PATIENCE)
        .build()
        .expect("a client")
        .post(server.url(&format!("/v1/pose/image?{query}")))
        .header("content-type", content_type)
        .body(body)
        .send()
        .expect("an answer");
    let status = response.status().as_u16();
    (status, response.text().unwrap_or_default())
}

fn zero_png(side_px: u32) -> Vec<u8> {
    let mut png = Vec::new();
    image::GrayImage::new(side_px, side_px)
        .write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("a PNG encodes");
    png
}

/// A 4000 × 3000 colour JPEG with texture everywhere (no code), like a phone photo.
fn textured_jpeg() -> Vec<u8> {
    let frame = image::RgbImage::from_fn(4000, 3000, |x, y| {
        let v = u8::try_from((x / 7 + y / 5) % 2 * 150 + (x * 13 + y * 7) % 97).unwrap_or(u8::MAX);
        image::Rgb([v, v.wrapping_add(40), v / 2])
    });
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 85)
        .encode_image(&frame)
        .expect("a JPEG encodes");
    jpeg
}

const CAMERA: &str = "fx_px=3000&fy_px=3000&cx_px=2000&cy_px=1500&marker_size_mm=50";

#[test]
fn a_large_image_and_full_frames_at_once_stay_within_the_documented_budget() {
    let server = Server::start_with(&[
        "--max-concurrent-estimations",
        "2",
        "--queue-length",
        "4",
        "--request-timeout-ms",
        "600000",
    ]);
    std::thread::sleep(Duration::from_millis(300));
    let idle = status_bytes(&server, "VmRSS:");
    let png = zero_png(7000);
    let jpeg = textured_jpeg();
    let thorough = format!("{CAMERA}&effort=thorough&max_detect_ms=60000");
    let answers: Vec<(u16, String)> = std::thread::scope(|s| {
        let zero = s.spawn(|| post(&server, png.clone(), "image/png", &thorough));
        let frames: Vec<_> = (0..2)
            .map(|_| s.spawn(|| post(&server, jpeg.clone(), "image/jpeg", CAMERA)))
            .collect();
        std::iter::once(zero)
            .chain(frames)
            .map(|h| h.join().expect("a client thread"))
            .collect()
    });
    let peak = status_bytes(&server, "VmHWM:");
    // Admitted at once at most: the two workers' images (the 49 MP one and a 12 MP one;
    // the second frame waits for a worker, its body counted) and the three bodies.
    let pixels = 7000 * 7000 + 4000 * 3000;
    let bodies = (png.len() + 2 * jpeg.len()) as u64;
    let budget = idle + BYTES_PER_PIXEL * pixels + bodies + BASE_BYTES;
    for (status, body) in &answers {
        assert_eq!(*status, 200, "{body}");
    }
    eprintln!(
        "idle {} MB, peak {} MB: {:.2} bytes a pixel above idle (budget {} MB)",
        idle >> 20,
        peak >> 20,
        (peak - idle) as f64 / pixels as f64,
        budget >> 20
    );
    assert!(
        peak <= budget,
        "peak {} MB over the budget of {} MB",
        peak >> 20,
        budget >> 20
    );
}

#[test]
fn an_image_beyond_the_pixel_budget_is_refused_at_once_while_another_runs() {
    // Room for one 49 MP image; the second, sent while the first runs, does not fit.
    let server = Server::start_with(&[
        "--max-concurrent-estimations",
        "2",
        "--max-inflight-pixels",
        "60000000",
        "--request-timeout-ms",
        "600000",
    ]);
    let png = zero_png(7000);
    let thorough = format!("{CAMERA}&effort=thorough&max_detect_ms=60000");
    std::thread::scope(|s| {
        let first = s.spawn(|| post(&server, png.clone(), "image/png", &thorough));
        // Until the first is admitted, the second may be the one that runs; then the
        // first is the refused one. Either way exactly one of the two is refused.
        std::thread::sleep(Duration::from_millis(200));
        let second = post(&server, png.clone(), "image/png", &thorough);
        let first = first.join().expect("a client thread");
        let mut statuses = [first.0, second.0];
        statuses.sort_unstable();
        assert_eq!(statuses, [200, 503], "{first:?} / {second:?}");
        let refused = if first.0 == 503 { &first.1 } else { &second.1 };
        assert!(refused.contains("\"code\":\"overloaded\""), "{refused}");
        assert!(refused.contains("max-inflight-pixels"), "{refused}");
    });
}
