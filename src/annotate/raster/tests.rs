//! The drawing primitives: strokes, corner marks and labels, pixel by pixel.

use super::*;
use crate::annotate::overlay::X_AXIS;

fn blank(width_px: usize, height_px: usize) -> RgbRaster {
    RgbRaster::new(width_px, height_px, vec![0; width_px * height_px * 3]).expect("sized")
}

fn coloured(raster: &RgbRaster, colour: Rgb) -> Vec<(usize, usize)> {
    let w = raster.width_px();
    raster
        .pixels()
        .chunks_exact(3)
        .enumerate()
        .filter(|(_, p)| *p == colour.0)
        .map(|(i, _)| (i % w, i / w))
        .collect()
}

#[test]
fn a_horizontal_stroke_covers_its_width_and_stops_at_its_ends() {
    let mut raster = blank(40, 20);
    let segment = Segment {
        from_px: [5.0, 10.0],
        to_px: [30.0, 10.0],
        colour: X_AXIS,
    };
    draw_segment(&mut raster, &segment, 3.0);
    let pixels = coloured(&raster, X_AXIS);
    assert_eq!(pixels.len(), 26 * 3, "rows 9..=11, columns 5..=30");
    assert!(
        pixels
            .iter()
            .all(|&(x, y)| (5..=30).contains(&x) && (9..=11).contains(&y))
    );
}

#[test]
fn a_corner_mark_is_centred_on_its_corner_and_clipped_at_the_border() {
    let mut raster = blank(30, 30);
    let style = Style::for_image(1280, 720);
    draw_corner_mark(&mut raster, [10.4, 12.6], &style);
    let pixels = coloured(&raster, CORNER_MARK);
    let n = pixels.len() as f64;
    let mean_x = pixels.iter().map(|p| p.0 as f64).sum::<f64>() / n;
    let mean_y = pixels.iter().map(|p| p.1 as f64).sum::<f64>() / n;
    assert_eq!((mean_x, mean_y), (10.0, 13.0));
    draw_corner_mark(&mut raster, [-100.0, 0.0], &style);
    draw_corner_mark(&mut raster, [f64::NAN, 0.0], &style);
}

#[test]
fn a_label_draws_text_inside_its_box() {
    let mut raster = blank(200, 40);
    let label = Label {
        anchor_px: [4.0, 30.0],
        below: false,
        text: "SKU-1é".to_owned(),
    };
    draw_label(&mut raster, &label, 2);
    let text = coloured(&raster, LABEL_TEXT);
    assert!(!text.is_empty());
    let box_width = (6 * 8 + 4) * 2;
    assert!(
        text.iter()
            .all(|&(x, y)| (4..4 + box_width).contains(&x) && (6..30).contains(&y))
    );
}

#[test]
fn a_label_sets_exactly_the_pixels_of_its_glyphs() {
    // Runs of set bits drawn at once give the pixels of drawing every bit alone.
    let label = Label {
        anchor_px: [3.0, 2.0],
        below: true,
        text: "SKU-0042 wmW#@%~é".to_owned(),
    };
    for scale in [1, 2, 3] {
        let mut raster = blank(500, 40);
        draw_label(&mut raster, &label, scale);
        let mut want = Vec::new();
        for (k, c) in (0_i64..).zip(label.text.chars()) {
            for (row, bits) in (0_i64..).zip(glyph(c)) {
                for column in (0..GLYPH_PX).filter(|col| bits >> col & 1 == 1) {
                    let x = 3 + LABEL_PADDING * scale + (k * GLYPH_PX + column) * scale;
                    let y = 2 + LABEL_PADDING * scale + row * scale;
                    for (dx, dy) in (0..scale).flat_map(|dx| (0..scale).map(move |dy| (dx, dy))) {
                        want.push(((x + dx) as usize, (y + dy) as usize));
                    }
                }
            }
        }
        want.sort_unstable();
        let mut got = coloured(&raster, LABEL_TEXT);
        got.sort_unstable();
        assert_eq!(got, want, "scale {scale}");
    }
}

/// The pixels of `segment` found by testing every pixel of the raster.
fn brute_force(
    width_px: usize,
    height_px: usize,
    segment: &Segment,
    width: f64,
) -> Vec<(usize, usize)> {
    let [x0, y0] = segment.from_px;
    let (dx, dy) = (segment.to_px[0] - x0, segment.to_px[1] - y0);
    let length_sq = dx * dx + dy * dy;
    let mut pixels = Vec::new();
    for y in 0..height_px {
        for x in 0..width_px {
            let (px, py) = (x as f64 - x0, y as f64 - y0);
            let t = if length_sq > 0.0 {
                (px * dx + py * dy) / length_sq
            } else {
                0.0
            };
            if (0.0..=1.0).contains(&t) && (px - t * dx).hypot(py - t * dy) <= width / 2.0 {
                pixels.push((x, y));
            }
        }
    }
    pixels
}

#[test]
fn a_stroke_is_every_pixel_within_its_half_width() {
    // Testing only a span of each row finds what testing every pixel does.
    let mut state = 11_u64;
    let mut next = |range: f64| {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1_u64 << 53) as f64 * range - range / 4.0
    };
    for k in 0..300 {
        let from_px = [next(80.0), next(60.0)];
        // Vertical, horizontal, on pixel centres, and anything.
        let to_px = match k % 10 {
            0 => [from_px[0], next(60.0)],
            1 => [next(80.0), from_px[1]],
            2 => [next(80.0).round(), next(60.0).round()],
            _ => [next(80.0), next(60.0)],
        };
        let from_px = if k % 10 == 2 {
            from_px.map(f64::round)
        } else {
            from_px
        };
        let segment = Segment {
            from_px,
            to_px,
            colour: X_AXIS,
        };
        let width = [1.0, 2.0, 3.0, 4.5][k % 4];
        let mut raster = blank(60, 45);
        draw_segment(&mut raster, &segment, width);
        assert_eq!(
            coloured(&raster, X_AXIS),
            brute_force(60, 45, &segment, width),
            "{segment:?}"
        );
    }
    let point = Segment {
        from_px: [5.2, 5.0],
        to_px: [5.2, 5.0],
        colour: X_AXIS,
    };
    let mut raster = blank(20, 20);
    draw_segment(&mut raster, &point, 3.0);
    assert_eq!(coloured(&raster, X_AXIS), brute_force(20, 20, &point, 3.0));
}

#[test]
fn the_style_grows_with_the_image() {
    let small = Style::for_image(640, 480);
    let large = Style::for_image(3840, 2160);
    assert!(large.stroke_px > small.stroke_px);
    assert!(large.label_height_px() > small.label_height_px());
}
