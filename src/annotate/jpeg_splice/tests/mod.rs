//! The splice against whole-frame decoding: JPEGs made here with `jpeg-encoder` in each
//! sampling, grey and with restart intervals, spliced, and decoded by zune-jpeg and by the
//! `image` crate. Outside the MCUs drawn into every pixel is the original's; inside, the
//! drawn pixels have their colours. [`fallback`]: what cannot be spliced falls back to the
//! whole-frame path, and broken data never panics.

mod fallback;
mod runs;

use super::*;
use crate::annotate::overlay::{
    CORNER_MARK, Label, OUTLINE, Overlay, Rgb, Segment, X_AXIS, Y_AXIS, Z_AXIS,
};
use crate::annotate::raster::{Canvas, RgbRaster, Style, draw_overlay};
use crate::annotate::{OutputFormat, annotated_with, codec, redrawn};
use jpeg_encoder::{ColorType, Encoder, SamplingFactor};

/// One recorded pixel write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PixelWrite {
    /// Column, px.
    x: u32,
    /// Row, px.
    y: u32,
    /// The colour written.
    colour: Rgb,
}

/// The writes of a drawing, in order: which pixels the overlay sets, and to what. Writes
/// outside the canvas are dropped; of several writes to one pixel the last one counts.
#[derive(Debug, Clone, PartialEq, Eq)]
struct PixelWrites {
    width_px: usize,
    height_px: usize,
    writes: Vec<PixelWrite>,
}

impl PixelWrites {
    /// No writes yet on a `width_px` × `height_px` canvas (at most `u32::MAX` a side: larger
    /// canvases record nothing).
    fn new(width_px: usize, height_px: usize) -> Self {
        Self {
            width_px,
            height_px,
            writes: Vec::new(),
        }
    }

    /// The writes, in drawing order.
    fn writes(&self) -> &[PixelWrite] {
        &self.writes
    }
}

impl Canvas for PixelWrites {
    fn width_px(&self) -> usize {
        self.width_px
    }

    fn height_px(&self) -> usize {
        self.height_px
    }

    fn put(&mut self, x: i64, y: i64, colour: Rgb) {
        let (Ok(x), Ok(y)) = (u32::try_from(x), u32::try_from(y)) else {
            return;
        };
        if (x as usize) < self.width_px && (y as usize) < self.height_px {
            self.writes.push(PixelWrite { x, y, colour });
        }
    }
}

const WIDTH: u16 = 203;
const HEIGHT: u16 = 141;
/// The test photos' size as the detection's decode reports it, (width, height) px.
const SIZE_PX: (usize, usize) = (WIDTH as usize, HEIGHT as usize);

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

/// Strokes 3 px wide in every direction, a label and corner marks, some at the frame's
/// right and bottom edges (partial MCUs), none in the top rows nor in the last MCU (so
/// that the scan goes on after the last re-encoded MCU).
fn overlay() -> Overlay {
    let segment = |from_px: [f64; 2], to_px: [f64; 2], colour: Rgb| Segment {
        from_px,
        to_px,
        colour,
    };
    Overlay {
        segments: vec![
            segment([40.0, 60.0], [160.0, 70.0], OUTLINE),
            segment([160.0, 70.0], [150.0, 130.0], OUTLINE),
            segment([100.0, 100.0], [190.0, 100.0], X_AXIS),
            segment([100.0, 100.0], [100.0, 40.0], Y_AXIS),
            segment([100.0, 100.0], [60.0, 139.0], Z_AXIS),
            segment([195.0, 50.0], [202.0, 110.0], X_AXIS),
        ],
        labels: vec![Label {
            anchor_px: [30.0, 58.0],
            below: false,
            text: "SKU-1".to_owned(),
        }],
        corner_marks_px: vec![[40.0, 60.0], [160.0, 70.0], [201.0, 100.0]],
    }
}

fn style() -> Style {
    Style::for_image(usize::from(WIDTH), usize::from(HEIGHT))
}

fn writes() -> PixelWrites {
    let mut writes = PixelWrites::new(usize::from(WIDTH), usize::from(HEIGHT));
    draw_overlay(&mut writes, &overlay(), &style());
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

/// Decodes with zune-jpeg (the service's decoder) and with the `image` crate.
fn decode_both(jpeg: &[u8]) -> [RgbRaster; 2] {
    let zune = codec::decode_rgb(jpeg).expect("zune-jpeg decodes");
    let image = image::load_from_memory_with_format(jpeg, image::ImageFormat::Jpeg)
        .expect("the image crate decodes")
        .into_rgb8();
    let (w, h) = (image.width() as usize, image.height() as usize);
    let image = RgbRaster::new(w, h, image.into_raw()).expect("sized");
    [zune, image]
}

fn pixel(raster: &RgbRaster, x: usize, y: usize) -> [u8; 3] {
    let at = (y * raster.width_px() + x) * 3;
    let p = &raster.pixels()[at..at + 3];
    [p[0], p[1], p[2]]
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
            (after.width_px(), after.height_px()),
            (usize::from(WIDTH), usize::from(HEIGHT))
        );
        let mut changed_outside = Vec::new();
        for y in 0..after.height_px() {
            for x in 0..after.width_px() {
                if !near_drawn(&drawn, mcu, margin, x, y)
                    && pixel(before, x, y) != pixel(after, x, y)
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
fn drawn_error(image: &RgbRaster, writes: &PixelWrites) -> f64 {
    let mut last = std::collections::HashMap::new();
    for w in writes.writes() {
        last.insert((w.x as usize, w.y as usize), w.colour);
    }
    let mut sum = [0.0_f64; 3];
    for (&(x, y), colour) in &last {
        for ((s, &got), &want) in sum.iter_mut().zip(&pixel(image, x, y)).zip(&colour.0) {
            *s += f64::from(got.abs_diff(want));
        }
    }
    let n = last.len() as f64;
    sum.iter().map(|s| s / n).fold(0.0, f64::max)
}

/// [`drawn_error`] of the whole-frame path (decode, draw, encode 4:2:0 at quality 90), the
/// worst of both decoders: what the service gave before the splice.
fn whole_frame_error(jpeg: &[u8]) -> f64 {
    let whole = redrawn(jpeg, OutputFormat::Jpeg, &|_| overlay()).expect("drawn");
    decode_both(&whole)
        .iter()
        .map(|image| drawn_error(image, &writes()))
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
    // route's test uses.
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
    let decoded = codec::decode_rgb(&spliced.bytes).expect("decodes");
    let mut marks = PixelWrites::new(usize::from(WIDTH), usize::from(HEIGHT));
    crate::annotate::raster::draw_corner_mark(&mut marks, [40.0, 60.0], &style());
    for w in marks.writes() {
        let got = pixel(&decoded, w.x as usize, w.y as usize);
        let error = got
            .iter()
            .zip(&CORNER_MARK.0)
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
fn annotating_a_jpeg_splices_it() {
    let jpeg = encode(COLOUR_420, |_| {});
    let annotated =
        annotated_with(&jpeg, OutputFormat::Jpeg, SIZE_PX, |_| overlay()).expect("annotated");
    let spliced = Jpeg::parse(&jpeg)
        .and_then(|j| j.splice(&drawing(&j, &writes())))
        .expect("spliced");
    assert_eq!(annotated, spliced.bytes);
    // PNG output stays the whole-frame path.
    let png = annotated_with(&jpeg, OutputFormat::Png, SIZE_PX, |_| overlay()).expect("annotated");
    assert_eq!(
        png,
        redrawn(&jpeg, OutputFormat::Png, &|_| overlay()).expect("drawn")
    );
}
