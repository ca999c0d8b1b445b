//! The splice against whole-frame decoding: JPEGs made here with `jpeg-encoder` in each
//! sampling, grey and with restart intervals, spliced, and decoded by zune-jpeg and by the
//! `image` crate. Outside the MCUs drawn into every pixel is the original's; inside, the
//! drawn pixels have their colours. The marks drawn are the qrpose service's ([`marks`]).
//! [`fallback`]: what cannot be spliced is refused with its reason, and broken data never
//! panics.

mod fallback;
mod marks;
mod runs;

use super::*;
use jpeg_encoder::{ColorType, Encoder, SamplingFactor};
use marks::{CORNER_MARK, OUTLINE, PixelWrites, X_AXIS, Y_AXIS, Z_AXIS};
use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

const WIDTH: u16 = 203;
const HEIGHT: u16 = 141;

/// A photo-like RGB frame: smooth shading, edges and a little deterministic noise.
fn photo(width: u16, height: u16) -> Vec<u8> {
    let mut pixels = Vec::with_capacity(usize::from(width) * usize::from(height) * 3);
    for y in 0..u32::from(height) {
        for x in 0..u32::from(width) {
            let noise =
                (x.wrapping_mul(7919) ^ y.wrapping_mul(104_729)).wrapping_mul(2_654_435_761) >> 28;
            let edge = if (x / 23 + y / 19) % 3 == 0 {
                50.0
            } else {
                0.0
            };
            let (fx, fy) = (f64::from(x), f64::from(y));
            let channel = |phase: f64| {
                let v = 110.0
                    + 60.0 * (fx / 17.0 + phase).sin() * (fy / 23.0).cos()
                    + edge
                    + f64::from(noise);
                // Clamped to 0-255 and rounded: the cast cannot truncate.
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let byte = v.clamp(0.0, 255.0).round() as u8;
                byte
            };
            pixels.extend([channel(0.0), channel(1.0), channel(2.0)]);
        }
    }
    pixels
}

#[derive(Debug, Clone, Copy)]
struct Options {
    sampling: SamplingFactor,
    grey: bool,
    restart: Option<u16>,
    quality: u8,
}

const COLOUR_420: Options = Options {
    sampling: SamplingFactor::F_2_2,
    grey: false,
    restart: None,
    quality: 90,
};

fn encode(options: Options, configure: impl FnOnce(&mut Encoder<&mut Vec<u8>>)) -> Vec<u8> {
    let rgb = photo(WIDTH, HEIGHT);
    let mut out = Vec::new();
    let mut encoder = Encoder::new(&mut out, options.quality);
    encoder.set_sampling_factor(options.sampling);
    if let Some(interval) = options.restart {
        encoder.set_restart_interval(interval);
    }
    configure(&mut encoder);
    if options.grey {
        let luma: Vec<u8> = rgb
            .chunks_exact(3)
            .map(|p| {
                u8::try_from((u16::from(p[0]) + u16::from(p[1]) + u16::from(p[2])) / 3)
                    .expect("a mean of bytes")
            })
            .collect();
        encoder
            .encode(&luma, WIDTH, HEIGHT, ColorType::Luma)
            .expect("encodes");
    } else {
        encoder
            .encode(&rgb, WIDTH, HEIGHT, ColorType::Rgb)
            .expect("encodes");
    }
    out
}

/// What the service draws on a frame of this size: strokes 2 px wide in every direction, a
/// label and corner marks 9 px across, some at the frame's right and bottom edges (partial
/// MCUs), none in the top rows nor in the last MCU (so that the scan goes on after the last
/// re-encoded MCU).
fn writes() -> PixelWrites {
    let mut writes = PixelWrites::new(usize::from(WIDTH), usize::from(HEIGHT));
    for (from_px, to_px, colour) in [
        ([40.0, 60.0], [160.0, 70.0], OUTLINE),
        ([160.0, 70.0], [150.0, 130.0], OUTLINE),
        ([100.0, 100.0], [190.0, 100.0], X_AXIS),
        ([100.0, 100.0], [100.0, 40.0], Y_AXIS),
        ([100.0, 100.0], [60.0, 139.0], Z_AXIS),
        ([195.0, 50.0], [202.0, 110.0], X_AXIS),
    ] {
        writes.segment(from_px, to_px, 2.0, colour);
    }
    writes.label([30.0, 58.0], "SKU-1");
    for at_px in [[40.0, 60.0], [160.0, 70.0], [201.0, 100.0]] {
        writes.corner_mark(at_px, 4, 1);
    }
    writes
}

/// `writes` replayed on `jpeg`'s canvas.
fn drawing(jpeg: &Jpeg<'_>, writes: &PixelWrites) -> Drawing {
    let mut canvas = jpeg.canvas();
    for w in writes.writes() {
        canvas.put(i64::from(w.x), i64::from(w.y), w.colour);
    }
    canvas
}

/// A decoded frame, row-major RGB.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Rgb {
    width_px: usize,
    height_px: usize,
    pixels: Vec<u8>,
}

impl Rgb {
    /// Pixel (x, y).
    fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let at = (y * self.width_px + x) * 3;
        let p = &self.pixels[at..at + 3];
        [p[0], p[1], p[2]]
    }
}

/// `jpeg` decoded by zune-jpeg, in colour (`ColorSpace::RGB`) or grey (`ColorSpace::Luma`),
/// `strict` or leniently as the qrpose service decodes photos to draw on.
fn decode_zune(jpeg: &[u8], colour: ColorSpace, strict: bool) -> Result<Rgb, String> {
    let options = DecoderOptions::default()
        .jpeg_set_out_colorspace(colour)
        .set_strict_mode(strict);
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(jpeg), options);
    let pixels = decoder.decode().map_err(|e| format!("{e:?}"))?;
    let (width_px, height_px) = decoder.dimensions().ok_or("no frame header")?;
    Ok(Rgb {
        width_px,
        height_px,
        pixels,
    })
}

/// Decodes with zune-jpeg (the qrpose service's decoder) and with the `image` crate.
fn decode_both(jpeg: &[u8]) -> [Rgb; 2] {
    let zune = decode_zune(jpeg, ColorSpace::RGB, false).expect("zune-jpeg decodes");
    let image = image::load_from_memory_with_format(jpeg, image::ImageFormat::Jpeg)
        .expect("the image crate decodes")
        .into_rgb8();
    let (width_px, height_px) = (image.width() as usize, image.height() as usize);
    let image = Rgb {
        width_px,
        height_px,
        pixels: image.into_raw(),
    };
    [zune, image]
}

/// Whether (x, y) lies in a drawn MCU grown by `margin` px (decoders interpolate
/// subsampled chroma across block edges: one pixel reaches into the neighbour).
fn near_drawn(
    drawn: &[(usize, usize)],
    mcu: (usize, usize),
    margin: usize,
    x: usize,
    y: usize,
) -> bool {
    drawn.iter().any(|&(mx, my)| {
        let (x0, y0) = (mx * mcu.0, my * mcu.1);
        x + margin >= x0 && x < x0 + mcu.0 + margin && y + margin >= y0 && y < y0 + mcu.1 + margin
    })
}

/// Splices `writes()` into `jpeg` and checks, for both decoders: the size; every pixel
/// outside the drawn MCUs (grown by `margin`) equal to the original's decode; the mean
/// absolute error of the drawn pixels per channel, returned (worst of the decoders).
fn check_splice(jpeg: &[u8], margin: usize) -> (Spliced, f64) {
    let parsed = Jpeg::parse(jpeg).expect("spliceable");
    let writes = writes();
    let spliced = parsed.splice(&drawing(&parsed, &writes)).expect("spliced");
    // Keeping the bytes after the last re-encoded MCU (ZRL codes make up the length) or
    // shifting them decodes to the same pixels: the coefficients are the same.
    let shifted = parsed
        .splice_with(&drawing(&parsed, &writes), false)
        .expect("spliced");
    assert_eq!(shifted.aligned_tails, 0);
    for (a, b) in decode_both(&spliced.bytes)
        .iter()
        .zip(&decode_both(&shifted.bytes))
    {
        assert!(a == b, "aligned and shifted tails decode differently");
    }
    let mcu = parsed.mcu_size_px();
    let mut drawn: Vec<(usize, usize)> = writes
        .writes()
        .iter()
        .map(|w| (w.x as usize / mcu.0, w.y as usize / mcu.1))
        .collect();
    drawn.sort_unstable();
    drawn.dedup();
    assert_eq!(spliced.drawn_mcus, drawn.len());
    let mut worst_error = 0.0_f64;
    for (before, after) in decode_both(jpeg).iter().zip(&decode_both(&spliced.bytes)) {
        assert_eq!(
            (after.width_px, after.height_px),
            (usize::from(WIDTH), usize::from(HEIGHT))
        );
        let mut changed_outside = Vec::new();
        for y in 0..after.height_px {
            for x in 0..after.width_px {
                if !near_drawn(&drawn, mcu, margin, x, y) && before.pixel(x, y) != after.pixel(x, y)
                {
                    changed_outside.push((x, y));
                }
            }
        }
        assert!(
            changed_outside.is_empty(),
            "{} pixels outside the drawn MCUs changed, first {:?}",
            changed_outside.len(),
            changed_outside.first()
        );
        worst_error = worst_error.max(drawn_error(after, &writes));
    }
    (spliced, worst_error)
}

/// The mean absolute error per channel, worst channel, of the written pixels of `image`
/// against the colour last written to each.
fn drawn_error(image: &Rgb, writes: &PixelWrites) -> f64 {
    let mut last = std::collections::HashMap::new();
    for w in writes.writes() {
        last.insert((w.x as usize, w.y as usize), w.colour);
    }
    let mut sum = [0.0_f64; 3];
    for (&(x, y), colour) in &last {
        for ((s, &got), &want) in sum.iter_mut().zip(&image.pixel(x, y)).zip(colour) {
            *s += f64::from(got.abs_diff(want));
        }
    }
    let n = last.len() as f64;
    sum.iter().map(|s| s / n).fold(0.0, f64::max)
}

/// [`drawn_error`] of the whole-frame path (decode, draw, encode 4:2:0 at quality 90, as
/// the qrpose service does when it cannot splice), the worst of both decoders.
fn whole_frame_error(jpeg: &[u8]) -> f64 {
    let mut frame = decode_zune(jpeg, ColorSpace::RGB, false).expect("decodes");
    let writes = writes();
    for w in writes.writes() {
        let at = (w.y as usize * frame.width_px + w.x as usize) * 3;
        frame.pixels[at..at + 3].copy_from_slice(&w.colour);
    }
    let mut whole = Vec::new();
    let mut encoder = Encoder::new(&mut whole, 90);
    encoder.set_sampling_factor(SamplingFactor::F_2_2);
    encoder
        .encode(&frame.pixels, WIDTH, HEIGHT, ColorType::Rgb)
        .expect("encodes");
    decode_both(&whole)
        .iter()
        .map(|image| drawn_error(image, &writes))
        .fold(0.0, f64::max)
}

/// The bytes `a` and `b` share at their start.
fn common_prefix(a: &[u8], b: &[u8]) -> usize {
    a.iter().zip(b).take_while(|(x, y)| x == y).count()
}

/// The offset of the first entropy-coded byte (after the SOS segment).
fn scan_start(jpeg: &[u8]) -> usize {
    Jpeg::parse(jpeg).expect("parses").headers.sos.end
}

/// The mean absolute error per channel that drawn pixels may have without chroma
/// subsampling (4:4:4, grey made 4:4:4): measured 2.8 and 2.1 at quality 90 (the worst
/// channel, both decoders). Strokes 3 px wide lose more to quantization at lower
/// qualities; a missing or miscoloured stroke errs by 80 or more.
const DRAWN_ERROR_444: f64 = 6.0;

/// Checks the drawn pixels' error: under [`DRAWN_ERROR_444`] at full chroma resolution;
/// with subsampled chroma (a 3 px saturated stroke shares its chroma samples with the
/// photo around it) no worse than the whole-frame path, which gives 4:2:0 whatever the
/// input (measured: spliced 4:2:0 39.7, 4:2:2 21.4, 4:4:0 25.5; whole frame 42.5).
fn check_error(jpeg: &[u8], error: f64, subsampled: bool) {
    if subsampled {
        let whole = whole_frame_error(jpeg);
        assert!(
            error <= whole,
            "drawn pixels err by {error:.1} on average, the whole-frame path by {whole:.1}"
        );
    } else {
        assert!(
            error < DRAWN_ERROR_444,
            "drawn pixels err by {error:.1} on average"
        );
    }
}

fn check_colour(sampling: SamplingFactor, margin: usize) {
    let jpeg = encode(
        Options {
            sampling,
            ..COLOUR_420
        },
        |_| {},
    );
    let (spliced, error) = check_splice(&jpeg, margin);
    check_error(&jpeg, error, margin > 0);
    // The headers and the MCUs before the first drawn one (rows above y = 35) are the
    // file's bytes.
    let start = scan_start(&jpeg);
    assert!(spliced.verbatim_prefix > start + (jpeg.len() - start) / 8);
    assert!(common_prefix(&jpeg, &spliced.bytes) >= spliced.verbatim_prefix);
    assert_eq!(spliced.bytes.last(), Some(&0xD9), "ends with EOI");
    // The scan's data after the last re-encoded MCU kept its bytes.
    assert_eq!((spliced.aligned_tails, spliced.shifted_tails), (1, 0));
    let tail = &jpeg[jpeg.len() - 64..];
    assert!(spliced.bytes.ends_with(tail));
}

#[test]
fn a_420_jpeg_is_spliced_exactly_outside_the_drawn_mcus() {
    check_colour(SamplingFactor::F_2_2, 1);
}

#[test]
fn a_422_jpeg_is_spliced_exactly_outside_the_drawn_mcus() {
    check_colour(SamplingFactor::F_2_1, 1);
}

#[test]
fn a_440_jpeg_is_spliced_exactly_outside_the_drawn_mcus() {
    check_colour(SamplingFactor::F_1_2, 1);
}

#[test]
fn a_444_jpeg_is_spliced_exactly_outside_the_drawn_mcus() {
    check_colour(SamplingFactor::F_1_1, 0);
}

#[test]
fn a_jpeg_with_restart_markers_is_spliced_exactly() {
    for interval in [1, 3, 7, 40] {
        let jpeg = encode(
            Options {
                restart: Some(interval),
                ..COLOUR_420
            },
            |_| {},
        );
        let (spliced, error) = check_splice(&jpeg, 1);
        check_error(&jpeg, error, true);
        assert!(common_prefix(&jpeg, &spliced.bytes) >= spliced.verbatim_prefix);
        assert!(spliced.verbatim_prefix > scan_start(&jpeg));
    }
}

#[test]
fn a_grey_jpeg_becomes_colour_with_its_pixels_unchanged_outside_the_drawn_blocks() {
    {
        let jpeg = encode(
            Options {
                grey: true,
                ..COLOUR_420
            },
            |_| {},
        );
        let parsed = Jpeg::parse(&jpeg).expect("parses");
        assert!(parsed.is_grey());
        assert_eq!(parsed.mcu_size_px(), (8, 8));
        let (spliced, error) = check_splice(&jpeg, 0);
        check_error(&jpeg, error, false);
        // Three components now, the chroma in scans of their own after the luma scan; the
        // headers before the frame header are the file's, and so are the luma scan's header
        // and its data up to the first drawn block.
        assert_eq!(
            Jpeg::parse(&spliced.bytes).err(),
            Some(CannotSplice::MultipleScans)
        );
        let sof = parsed.headers.sof.start;
        assert_eq!(spliced.bytes[sof + 9], 3, "components");
        assert_eq!(spliced.bytes[..sof], jpeg[..sof]);
        let sos = parsed.headers.sos.clone();
        assert!(spliced.verbatim_scan_bytes > (jpeg.len() - sos.end) / 8);
        let kept = &jpeg[sos.start..sos.end + spliced.verbatim_scan_bytes];
        assert!(spliced.bytes.windows(kept.len()).any(|w| w == kept));
    }
}

#[test]
fn the_drawn_colours_are_read_back_by_the_service_decoder() {
    // Every corner-mark pixel of the 4:4:4 splice is magenta within the tolerance the
    // service's annotated-route test uses.
    let jpeg = encode(
        Options {
            sampling: SamplingFactor::F_1_1,
            ..COLOUR_420
        },
        |_| {},
    );
    let spliced = Jpeg::parse(&jpeg)
        .and_then(|j| j.splice(&drawing(&j, &writes())))
        .expect("spliced");
    let [decoded, _] = decode_both(&spliced.bytes);
    let mut marks = PixelWrites::new(usize::from(WIDTH), usize::from(HEIGHT));
    marks.corner_mark([40.0, 60.0], 4, 1);
    for w in marks.writes() {
        let got = decoded.pixel(w.x as usize, w.y as usize);
        let error = got
            .iter()
            .zip(&CORNER_MARK)
            .map(|(a, b)| a.abs_diff(*b))
            .max()
            .unwrap_or(0);
        assert!(error <= 80, "{got:?} at ({}, {})", w.x, w.y);
    }
}

#[test]
fn no_writes_give_the_file_itself() {
    let jpeg = encode(COLOUR_420, |_| {});
    let spliced = Jpeg::parse(&jpeg)
        .and_then(|j| j.splice(&j.canvas()))
        .expect("spliced");
    assert_eq!(spliced.bytes, jpeg);
}

#[test]
fn a_row_written_at_once_is_each_of_its_pixels_written() {
    // put_row clips to the frame like put, MCU boundaries and edges included.
    let jpeg = encode(COLOUR_420, |_| {});
    let parsed = Jpeg::parse(&jpeg).expect("parses");
    let (mut rows, mut pixels) = (parsed.canvas(), parsed.canvas());
    for (from, to, y) in [
        (-5, 40, 3),
        (14, 17, 31),
        (190, 260, 140),
        (7, 9, -1),
        (5, 9, 141),
    ] {
        rows.put_row(from, to, y, X_AXIS);
        for x in from..to {
            pixels.put(x, y, X_AXIS);
        }
    }
    let spliced = |d: &Drawing| parsed.splice(d).expect("spliced");
    assert_eq!(spliced(&rows), spliced(&pixels));
    assert_eq!(spliced(&rows).drawn_mcus, 3 + 2 + 2);
}

#[test]
fn a_drawing_of_another_frame_is_refused() {
    let small = encode(COLOUR_420, |_| {});
    let other = Jpeg::parse(&small).expect("parses");
    let grey = encode(
        Options {
            grey: true,
            ..COLOUR_420
        },
        |_| {},
    );
    // Same size, other MCU grid (8 px MCUs instead of 16).
    let grey = Jpeg::parse(&grey).expect("parses");
    assert_eq!(
        grey.splice(&other.canvas()).err(),
        Some(CannotSplice::SizeMismatch)
    );
}
