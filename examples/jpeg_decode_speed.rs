//! How long the JPEG decode to grey takes, per photo, with qrpose's decoder and with
//! zune-jpeg's options, for `scripts/jpeg_decode_bench.py`,
//! which times OpenCV's greyscale decode (libjpeg-turbo) on the same bytes beside it.
//!
//! ```sh
//! cargo run --release --example jpeg_decode_speed -- [--repeat N] FILE.jpg...
//! ```
//! Prints one JSON line per file: `path`, `width_px`, `height_px`, `components`,
//! `strict_ok` (whether zune-jpeg's strict mode decodes the file; qrpose falls back to the
//! lenient decode when it does not) and `ms`, the median over N rounds (default 5) of each
//! variant, the variants alternated within every round:
//!
//! - `qrpose`: `decode::decode_gray` with the default limits, what `timing_ms.decode` times
//!   (format sniffing, the header's dimensions checked, strict decode, lenient on failure);
//! - `strict`, `lenient`: zune-jpeg alone, luma out, strict mode on / off (a failed strict
//!   decode is timed up to its failure);
//! - `lenient_no_unsafe`: lenient with `set_use_unsafe(false)` (zune-core 0.5 still uses
//!   AVX2 when the per-instruction-set flags allow it, so this shows whether the flag matters).

use qrpose::detect::decode::{DecodeLimits, decode_gray};
use std::time::Instant;
use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

/// The variants, in the order each round runs them.
const VARIANTS: [&str; 4] = ["qrpose", "strict", "lenient", "lenient_no_unsafe"];

fn options(strict: bool, unsafe_paths: bool) -> DecoderOptions {
    DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::Luma)
        .set_max_width(usize::from(u16::MAX))
        .set_max_height(usize::from(u16::MAX))
        .set_strict_mode(strict)
        .set_use_unsafe(unsafe_paths)
}

/// zune-jpeg alone: headers, then the pixels into a zeroed buffer (as qrpose does).
fn zune(bytes: &[u8], options: DecoderOptions) -> Result<usize, String> {
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    decoder.decode_headers().map_err(|e| format!("{e:?}"))?;
    let size = decoder.output_buffer_size().ok_or("no size")?;
    let mut pixels = vec![0u8; size];
    decoder
        .decode_into(&mut pixels)
        .map_err(|e| format!("{e:?}"))?;
    Ok(pixels.len())
}

fn run(variant: &str, bytes: &[u8]) -> Result<usize, String> {
    match variant {
        "qrpose" => decode_gray(bytes, &DecodeLimits::default())
            .map(|g| g.pixels().len())
            .map_err(|e| e.to_string()),
        "strict" => zune(bytes, options(true, true)),
        "lenient" => zune(bytes, options(false, true)),
        _ => zune(bytes, options(false, false)),
    }
}

fn median_ms(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn json_string(s: &str) -> String {
    serde_json::Value::String(s.to_owned()).to_string()
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut repeat = 5usize;
    if let Some(at) = args.iter().position(|a| a == "--repeat") {
        repeat = args
            .get(at + 1)
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| {
                eprintln!("--repeat wants a number");
                std::process::exit(2);
            });
        args.drain(at..at + 2);
    }
    if args.is_empty() {
        eprintln!("usage: jpeg_decode_speed [--repeat N] FILE.jpg...");
        std::process::exit(2);
    }
    for path in &args {
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("{path}: {e}");
                std::process::exit(1);
            }
        };
        let mut header = JpegDecoder::new_with_options(ZCursor::new(&bytes), options(false, true));
        let info = header.decode_headers().ok().and_then(|()| header.info());
        let (w, h, components) = info.map_or((0, 0, 0), |i| {
            (usize::from(i.width), usize::from(i.height), i.components)
        });
        let strict_ok = run("strict", &bytes).is_ok();
        // One untimed round: page faults of the first allocation, caches.
        for v in VARIANTS {
            let _ = run(v, &bytes);
        }
        let mut times: Vec<Vec<f64>> = vec![Vec::new(); VARIANTS.len()];
        for _ in 0..repeat.max(1) {
            for (k, v) in VARIANTS.iter().enumerate() {
                let t0 = Instant::now();
                let _ = std::hint::black_box(run(v, &bytes));
                times[k].push(t0.elapsed().as_secs_f64() * 1e3);
            }
        }
        let ms: Vec<String> = VARIANTS
            .iter()
            .zip(times)
            .map(|(v, t)| format!("\"{v}\": {:.3}", median_ms(t)))
            .collect();
        println!(
            "{{\"path\": {}, \"width_px\": {w}, \"height_px\": {h}, \"components\": {components}, \
             \"strict_ok\": {strict_ok}, \"ms\": {{{}}}}}",
            json_string(path),
            ms.join(", ")
        );
    }
}
