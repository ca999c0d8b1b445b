//! Where the blocks are: the MCU grid of the file's scan, the components (with their
//! quantization and Huffman tables) and, for a grey frame, the chroma components it gains.

use super::CannotSplice;
use super::block::{Quantizer, chroma_table};
use super::huffman::{Coders, Decoder, Encoder, HuffmanSpec, chroma_ac, chroma_dc, coders};
use super::markers::{Component, Headers};

/// One component: of the file's scan, or a chroma component added to a grey frame.
#[derive(Debug, Clone)]
pub struct Plane {
    /// Y (0), Cb (1) or Cr (2).
    pub channel: usize,
    /// Pixels per sample across and down (1 or 2).
    pub step: (usize, usize),
    /// Blocks per MCU across and down.
    pub blocks: (usize, usize),
    /// Quantization.
    pub quant: Quantizer,
    /// The Huffman decoders and encoders of its tables.
    pub coders: Coders,
    /// Whether it is one of the file's scan (not a chroma component added to a grey frame).
    pub in_scan: bool,
    /// The AC table's ZRL code (16 zeros) as (code, length), when it has one.
    pub zrl: Option<(u32, u32)>,
    /// The length of the AC table's end-of-block code.
    pub eob_bits: u32,
}

impl Plane {
    /// The file's DC and AC decoders; `None` for the chroma added to a grey frame.
    pub fn decoders(&self) -> Option<(&Decoder, &Decoder)> {
        self.in_scan
            .then_some((&self.coders.dc_decoder, &self.coders.ac_decoder))
    }

    /// The DC and AC encoders.
    pub fn encoders(&self) -> (&Encoder, &Encoder) {
        (&self.coders.dc_encoder, &self.coders.ac_encoder)
    }

    fn new(
        channel: usize,
        step: (usize, usize),
        blocks: (usize, usize),
        quant: Quantizer,
        coders: Coders,
        in_scan: bool,
    ) -> Self {
        let zrl = coders.ac_encoder.code(0xF0).ok();
        let eob_bits = coders.ac_encoder.code(0x00).map_or(0, |(_, length)| length);
        Self {
            channel,
            step,
            blocks,
            quant,
            coders,
            in_scan,
            zrl,
            eob_bits,
        }
    }
}

/// The MCU grid of the file's scan and the components drawn into.
#[derive(Debug, Clone)]
pub struct Layout {
    /// The frame and its MCUs.
    pub grid: Grid,
    /// The components: the file's scan's, then (grey frames) Cb and Cr.
    pub planes: Vec<Plane>,
    /// Each block of an MCU: its plane and position in the MCU, in blocks; the file's scan
    /// order, then (grey frames) the added Cb and Cr blocks.
    pub blocks: Vec<(usize, usize, usize)>,
    /// How many of `blocks` the file's scan has.
    pub input_blocks: usize,
    /// What a grey frame's added chroma components are called and coded with.
    pub chroma: Option<Chroma>,
}

/// The chroma components added to a grey frame, each in a scan of its own after the luma
/// scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Chroma {
    /// The component ids of Cb and Cr.
    pub ids: [u8; 2],
    /// The Huffman table slots (DC, AC) of the typical chrominance tables both use: the
    /// ones the luma scan does not.
    pub tables: (u8, u8),
    /// The quantization table slot both use (one luma does not) and the table, zigzag
    /// order: the typical chrominance table at the luma table's quality.
    pub quant: (u8, [u16; 64]),
}

impl Layout {
    /// The layout of the file's scan, with Cb and Cr added when it is grey.
    ///
    /// # Errors
    /// [`CannotSplice::Malformed`] for Huffman tables that are no prefix code.
    pub fn new(headers: &Headers) -> Result<Self, CannotSplice> {
        let grey = headers.components.len() == 1;
        let (h_max, v_max) = if grey {
            (1, 1)
        } else {
            let max = |f: fn(&Component) -> u8| {
                usize::from(headers.components.iter().map(f).max().unwrap_or(1))
            };
            (max(|c| c.h), max(|c| c.v))
        };
        let mut planes = Vec::with_capacity(3);
        for s in &headers.scan {
            let component = headers
                .components
                .get(s.component)
                .ok_or(CannotSplice::Malformed("scan component"))?;
            let (dc, ac) = (table(&headers.dc, s.dc)?, table(&headers.ac, s.ac)?);
            let quant = headers
                .quant
                .get(usize::from(component.quant))
                .and_then(Option::as_ref)
                .ok_or(CannotSplice::Malformed("an undefined quantization table"))?;
            let (h, v) = if grey {
                (1, 1)
            } else {
                (usize::from(component.h), usize::from(component.v))
            };
            planes.push(Plane::new(
                s.component,
                (h_max / h, v_max / v),
                (h, v),
                Quantizer::new(quant),
                coders(dc, ac)?,
                true,
            ));
        }
        let mut chroma = None;
        if grey {
            let (y_dc, y_ac) = headers.scan.first().map_or((0, 0), |s| (s.dc, s.ac));
            let other = |id: u8| u8::from(id == 0);
            let y_id = headers.components.first().map_or(1, |c| c.id);
            let mut ids = (2..=u8::MAX).filter(|&id| id != y_id);
            let y_quant = headers.components.first().map_or(0, |c| c.quant);
            let luma = headers
                .quant
                .get(usize::from(y_quant))
                .and_then(Option::as_ref)
                .ok_or(CannotSplice::Malformed("an undefined quantization table"))?;
            let table = chroma_table(luma);
            chroma = Some(Chroma {
                ids: [ids.next().unwrap_or(2), ids.next().unwrap_or(3)],
                tables: (other(y_dc), other(y_ac)),
                quant: (other(y_quant), table),
            });
            let quant = Quantizer::new(&table);
            for channel in [1, 2] {
                planes.push(Plane::new(
                    channel,
                    (1, 1),
                    (1, 1),
                    quant,
                    coders(&chroma_dc(), &chroma_ac())?,
                    false,
                ));
            }
        }
        let mut blocks = Vec::new();
        for (index, plane) in planes.iter().enumerate() {
            for by in 0..plane.blocks.1 {
                for bx in 0..plane.blocks.0 {
                    blocks.push((index, bx, by));
                }
            }
        }
        let input_blocks = blocks
            .iter()
            .filter(|b| planes.get(b.0).is_some_and(|p| p.in_scan))
            .count();
        let mcu_px = (8 * h_max, 8 * v_max);
        let (width, height) = (usize::from(headers.width), usize::from(headers.height));
        Ok(Self {
            grid: Grid {
                width,
                height,
                mcu_px,
                mcu_shift: (mcu_px.0.trailing_zeros(), mcu_px.1.trailing_zeros()),
                mcus: (width.div_ceil(mcu_px.0), height.div_ceil(mcu_px.1)),
            },
            planes,
            blocks,
            input_blocks,
            chroma,
        })
    }
}

/// The frame's size and its grid of MCUs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Grid {
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// MCU size, px.
    pub mcu_px: (usize, usize),
    /// Its base-2 logarithms (MCUs are 8 or 16 px a side).
    mcu_shift: (u32, u32),
    /// MCUs across and down.
    pub mcus: (usize, usize),
}

impl Grid {
    /// MCUs in the frame.
    pub fn total(&self) -> usize {
        self.mcus.0 * self.mcus.1
    }

    /// The MCU holding pixel (x, y), and the pixel's index in the MCU, row by row.
    pub fn mcu_of(&self, x: usize, y: usize) -> (usize, usize) {
        let (sx, sy) = self.mcu_shift;
        let mcu = (y >> sy) * self.mcus.0 + (x >> sx);
        let local = ((y & (self.mcu_px.1 - 1)) << sx) + (x & (self.mcu_px.0 - 1));
        (mcu, local)
    }
}

/// Huffman table `id` of `tables`.
fn table(tables: &[Option<HuffmanSpec>; 4], id: u8) -> Result<&HuffmanSpec, CannotSplice> {
    tables
        .get(usize::from(id))
        .and_then(Option::as_ref)
        .ok_or(CannotSplice::Malformed("an undefined Huffman table"))
}
