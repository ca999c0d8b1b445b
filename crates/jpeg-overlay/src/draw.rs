//! The drawing, MCU by MCU: the pixel writes gathered into a tile per MCU drawn into (the
//! last colour written on each pixel), and drawn into an MCU's coefficients. Each block that
//! holds a drawn pixel is decoded to samples, drawn on in YCbCr and encoded again with the
//! file's quantization; blocks without one keep their coefficients.

use super::CannotSplice;
use super::block::{Coefficients, Quantizer, Transform, ycbcr};
use super::layout::{Grid, Layout};

/// An MCU drawn into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Touched {
    /// The MCU's index in scan order.
    pub mcu: usize,
    /// Its tile's index in [`Drawing::tiles`].
    pub tile: usize,
}

/// The overlay recorded MCU by MCU: a canvas of the frame's size (from
/// [`crate::Jpeg::canvas`]) that keeps, per MCU drawn into, a tile of the last colour
/// written on each of its pixels, for [`crate::Jpeg::splice`]. Colours are sRGB, (R, G, B);
/// pixel (x, y) is column x, row y from the top-left corner. Writes outside the frame are
/// dropped; of several writes to one pixel the last one counts.
#[derive(Debug, Clone)]
pub struct Drawing {
    grid: Grid,
    /// By MCU: 0, or 1 + the index of its tile.
    tile_of: Vec<u32>,
    /// The MCUs drawn into, in drawing order.
    touched: Vec<Touched>,
    /// Per tile, an MCU's pixels row by row: 0 where nothing is drawn, else 1 + the index of
    /// the colour in `palette`.
    tiles: Vec<u8>,
    /// Per tile, the drawn pixels' bounding box in the MCU, (left, top, right, bottom)
    /// inclusive, kept as pixels are written.
    bounds: Vec<[usize; 4]>,
    /// Pixels per tile.
    tile_len: usize,
    /// The colours drawn.
    palette: Vec<[u8; 3]>,
    /// The last colour drawn and its index, to skip the palette search.
    last: Option<([u8; 3], u8)>,
    /// Whether more than 255 colours were drawn (the drawing cannot be spliced).
    overflow: bool,
}

impl Drawing {
    /// Nothing drawn yet on the frame of `grid`.
    pub(crate) fn new(grid: Grid) -> Self {
        Self {
            grid,
            tile_of: vec![0; grid.total()],
            touched: Vec::new(),
            tiles: Vec::new(),
            bounds: Vec::new(),
            tile_len: grid.mcu_px.0 * grid.mcu_px.1,
            palette: Vec::new(),
            last: None,
            overflow: false,
        }
    }

    /// The grid drawn on.
    pub(crate) fn grid(&self) -> Grid {
        self.grid
    }

    /// The MCUs drawn into, in scan order.
    ///
    /// # Errors
    /// [`CannotSplice::Colours`] when more than 255 colours were drawn.
    pub(crate) fn touched(&self) -> Result<Vec<Touched>, CannotSplice> {
        if self.overflow {
            return Err(CannotSplice::Colours);
        }
        let mut touched = self.touched.clone();
        touched.sort_unstable_by_key(|t| t.mcu);
        Ok(touched)
    }

    /// The drawn colours in YCbCr, by palette index.
    pub(crate) fn colours(&self) -> Vec<[f32; 3]> {
        self.palette.iter().copied().map(ycbcr).collect()
    }

    /// 1 + the palette index of `colour`; `None` past 255 colours.
    fn colour_index(&mut self, colour: [u8; 3]) -> Option<u8> {
        if let Some((c, index)) = self.last
            && c == colour
        {
            return Some(index);
        }
        let index = match self.palette.iter().position(|&c| c == colour) {
            Some(i) => i,
            None => {
                self.palette.push(colour);
                self.palette.len() - 1
            }
        };
        let index = u8::try_from(index + 1).ok()?;
        self.last = Some((colour, index));
        Some(index)
    }
}

impl Drawing {
    /// The frame's width, px.
    pub fn width_px(&self) -> usize {
        self.grid.width
    }

    /// The frame's height, px.
    pub fn height_px(&self) -> usize {
        self.grid.height
    }

    /// Sets pixel (`x`, `y`) to `colour` (R, G, B) when it lies inside the frame.
    pub fn put(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        self.put_row(x, x.saturating_add(1), y, colour);
    }

    /// Sets the pixels `from..to` of row `y` that lie inside the frame to `colour`
    /// (R, G, B), as [`Self::put`] on each.
    pub fn put_row(&mut self, from: i64, to: i64, y: i64, colour: [u8; 3]) {
        let clip = |v: i64, size: usize| usize::try_from(v.max(0)).unwrap_or(0).min(size);
        let (from, to) = (clip(from, self.grid.width), clip(to, self.grid.width));
        let Ok(y) = usize::try_from(y) else {
            return;
        };
        if y >= self.grid.height || from >= to {
            return;
        }
        let Some(index) = self.colour_index(colour) else {
            self.overflow = true;
            return;
        };
        let mcu_w = self.grid.mcu_px.0;
        let mut x = from;
        while x < to {
            // The part of the row in one MCU.
            let end = to.min((x / mcu_w + 1) * mcu_w);
            let (mcu, local) = self.grid.mcu_of(x, y);
            if let Some(tile) = self.tile(mcu) {
                let start = tile * self.tile_len + local;
                if let Some(pixels) = self.tiles.get_mut(start..start + (end - x)) {
                    pixels.fill(index);
                }
                let (left, top) = (local % mcu_w, local / mcu_w);
                if let Some(b) = self.bounds.get_mut(tile) {
                    *b = [
                        b[0].min(left),
                        b[1].min(top),
                        b[2].max(left + (end - x) - 1),
                        b[3].max(top),
                    ];
                }
            }
            x = end;
        }
    }
}

impl Drawing {
    /// The index of the tile of `mcu`, made when it has none.
    fn tile(&mut self, mcu: usize) -> Option<usize> {
        let slot = self.tile_of.get_mut(mcu)?;
        if *slot == 0 {
            *slot = u32::try_from(self.touched.len() + 1).ok()?;
            self.touched.push(Touched {
                mcu,
                tile: self.touched.len(),
            });
            self.tiles.resize(self.tiles.len() + self.tile_len, 0);
            self.bounds.push([usize::MAX, usize::MAX, 0, 0]);
        }
        Some(*slot as usize - 1)
    }
}

impl Drawing {
    /// Draws `touched`'s tile into the MCU's `coefficients` (one per block of `layout`).
    /// Writes are applied in YCbCr; a subsampled chroma sample covering several pixels takes
    /// their mean (a box filter). A block drawn over entirely is encoded from the drawing
    /// alone (one of one colour as its DC); a block whose samples do not change keeps its
    /// coefficients.
    pub(crate) fn draw(
        &self,
        touched: Touched,
        colours: &[[f32; 3]],
        layout: &Layout,
        transform: &Transform,
        coefficients: &mut [Coefficients],
    ) {
        let start = touched.tile * self.tile_len;
        let tile = self
            .tiles
            .get(start..start + self.tile_len)
            .unwrap_or_default();
        let mcu_w = layout.grid.mcu_px.0;
        let Some(&[min_x, min_y, max_x, max_y]) = self.bounds.get(touched.tile) else {
            return;
        };
        // Blocks of one footprint (a grey frame's Y, Cb and Cr; 4:2:0's Cb and Cr) share
        // their sums: the last footprint's are kept.
        let mut cached: Option<((usize, usize, usize, usize), Sums)> = None;
        for (&(plane, bx, by), coefficients) in layout.blocks.iter().zip(coefficients.iter_mut()) {
            let Some(p) = layout.planes.get(plane) else {
                continue;
            };
            let (sx, sy) = p.step;
            // The block's pixels in the MCU: 8 × 8 samples of sx × sy pixels each.
            let (left, top, width, height) = (bx * 8 * sx, by * 8 * sy, 8 * sx, 8 * sy);
            if min_x >= left + width || max_x < left || min_y >= top + height || max_y < top {
                continue;
            }
            let footprint = (left, top, sx, sy);
            let sums = match &cached {
                Some((f, sums)) if *f == footprint => sums,
                _ => {
                    &cached
                        .insert((footprint, sums(tile, colours, mcu_w, footprint)))
                        .1
                }
            };
            let Some(channel) = sums.values.get(p.channel) else {
                continue;
            };
            draw_block(transform, &p.quant, coefficients, channel, sums, sx * sy);
        }
    }
}

/// The sums of the drawn values (Y, Cb, Cr) over the pixels of each sample of the block
/// at `(left, top)` in the MCU, of `sx × sy` pixels per sample, and their numbers.
fn sums(
    tile: &[u8],
    colours: &[[f32; 3]],
    mcu_w: usize,
    (left, top, sx, sy): (usize, usize, usize, usize),
) -> Sums {
    let mut sums = Sums {
        values: [[0.0; 64]; 3],
        hits: [0; 64],
        drawn: 0,
        full: 0,
    };
    let (x_shift, y_shift) = (sx / 2, sy / 2);
    for dy in 0..8 * sy {
        let row = (top + dy) * mcu_w + left;
        let sample_row = (dy >> y_shift) * 8;
        let pixels = tile.get(row..row + 8 * sx).unwrap_or_default();
        for (dx, &colour) in pixels.iter().enumerate() {
            let Some(ycc) = colour
                .checked_sub(1)
                .and_then(|c| colours.get(usize::from(c)))
            else {
                continue;
            };
            let sample = (sample_row + (dx >> x_shift)) & 63;
            for (values, &v) in sums.values.iter_mut().zip(ycc) {
                values[sample] += v;
            }
            sums.hits[sample] += 1;
        }
    }
    let covered = u8::try_from(sx * sy).unwrap_or(1);
    for &hit in &sums.hits {
        sums.drawn += usize::from(hit > 0);
        sums.full += usize::from(hit == covered);
    }
    sums
}

/// Per sample of a block: the sums of the drawn values (Y, Cb, Cr) over the pixels it
/// covers, and how many of them are drawn; how many samples hold a drawn pixel, and how
/// many are drawn over entirely.
#[derive(Debug, Clone, Copy)]
struct Sums {
    values: [[f32; 64]; 3],
    hits: [u8; 64],
    drawn: usize,
    full: usize,
}

/// Draws into one block the sums of the drawn values `channel` over the pixels of each
/// sample (their numbers in `sums`), of `covered` pixels per sample.
fn draw_block(
    transform: &Transform,
    quant: &Quantizer,
    coefficients: &mut Coefficients,
    channel: &[f32; 64],
    sums: &Sums,
    covered: usize,
) {
    // covered is 1, 2 or 4.
    let covered = u8::try_from(covered).unwrap_or(1);
    let scale = f32::from(covered);
    if sums.drawn == 0 {
        return;
    }
    if sums.full == 64 {
        // Every sample drawn over: the block's old content does not matter.
        let samples = channel.map(|sum| sum / scale);
        *coefficients = if samples.iter().all(|&v| v == samples[0]) {
            transform.flat(samples[0], quant)
        } else {
            transform.coefficients(&samples, quant)
        };
        return;
    }
    let mut samples = transform.samples(coefficients, quant);
    let mut changed = false;
    if covered == 1 {
        // A pixel per sample: a drawn sample takes the drawn value (a loop without branches).
        for ((sample, &value), &hit) in samples.iter_mut().zip(channel).zip(&sums.hits) {
            let drawn = hit != 0;
            changed |= drawn & ((value - *sample).abs() > 1e-3);
            *sample = if drawn { value } else { *sample };
        }
    } else {
        for ((sample, &sum), &hit) in samples.iter_mut().zip(channel).zip(&sums.hits) {
            if hit == 0 {
                continue;
            }
            let value = (sum + f32::from(covered - hit) * *sample) / scale;
            changed |= (value - *sample).abs() > 1e-3;
            *sample = value;
        }
    }
    if changed {
        *coefficients = transform.coefficients(&samples, quant);
    }
}
