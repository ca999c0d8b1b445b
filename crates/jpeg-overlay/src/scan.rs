//! The scan, interval by interval: restart intervals without a drawn MCU are copied byte for
//! byte; in the others the MCUs before the first drawn one keep their bytes, the drawn MCUs
//! and the one after each run of them are encoded anew, and runs of 8 MCUs or more between
//! them and the rest of the interval are copied byte for byte too when ZRL codes can make
//! the new bits before them a whole number of bytes longer or shorter ([`super::align`]),
//! else shifted bit by bit. A grey frame's added chroma follows in two scans of its own.

use super::CannotSplice;
use super::align::{ALIGNED_RUN, Segment, Slot, align_to, write_aligned_run};
use super::block::{Coefficients, Transform};
use super::coding::{read_block, skip_block, write_block};
use super::draw::{Drawing, Touched};
use super::entropy::{BitReader, BitWriter, Entropy, Interval};
use super::layout::{Chroma, Layout};
use std::ops::Range;

/// What [`rewrite`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Rewritten {
    /// MCUs encoded anew (those drawn into and the one after each run of them).
    pub reencoded_mcus: usize,
    /// How many leading bytes of the output are the file's, unchanged.
    pub verbatim_prefix: usize,
    /// Restart intervals whose rest after the re-encoded MCUs was copied byte for byte.
    pub aligned_tails: usize,
    /// Restart intervals whose rest was copied shifted bit by bit.
    pub shifted_tails: usize,
    /// Runs of MCUs between re-encoded ones whose bytes were kept (ZRLs align them).
    pub aligned_runs: usize,
}

/// The walk's state.
struct Walk<'a> {
    file: &'a [u8],
    layout: &'a Layout,
    entropy: &'a Entropy,
    /// The writes by MCU.
    drawing: &'a Drawing,
    /// The drawn colours in YCbCr.
    colours: Vec<[f32; 3]>,
    /// MCUs in the frame.
    total: usize,
    transform: Transform,
    /// The DC predictor of each plane, of the file's data and of the output.
    read_dc: [i32; 3],
    write_dc: [i32; 3],
    coefficients: Vec<Coefficients>,
    /// A grey frame's drawn chroma blocks (Cb, Cr) by MCU, ascending.
    chroma: Vec<(usize, [Coefficients; 2])>,
    report: Rewritten,
    changed: bool,
    /// Whether to try keeping the bytes of an interval's rest.
    align: bool,
}

/// Writes the entropy-coded data of the scan spliced with the drawing after `out` (the
/// headers), then (grey frames) the chroma scans, then the file's trailer. With `align`
/// false the rest of each interval is always shifted (for tests).
///
/// # Errors
/// [`CannotSplice::BadEntropy`] for data that does not decode, [`CannotSplice::MissingCode`]
/// when a re-encoded block needs a code the file's tables lack.
pub fn rewrite(
    file: &[u8],
    layout: &Layout,
    entropy: &Entropy,
    restart_interval: usize,
    drawing: &Drawing,
    out: Vec<u8>,
    align: bool,
) -> Result<(Vec<u8>, Rewritten), CannotSplice> {
    let total = layout.grid.total();
    let per_interval = if restart_interval == 0 {
        total
    } else {
        restart_interval
    };
    if entropy.intervals.len() != total.div_ceil(per_interval) {
        return Err(CannotSplice::BadEntropy);
    }
    let mut walk = Walk {
        file,
        layout,
        entropy,
        drawing,
        colours: drawing.colours(),
        total,
        transform: Transform,
        read_dc: [0; 3],
        write_dc: [0; 3],
        coefficients: vec![[0; 64]; layout.blocks.len()],
        chroma: Vec::new(),
        report: Rewritten {
            verbatim_prefix: out.len(),
            ..Rewritten::default()
        },
        changed: false,
        align,
    };
    let mut writer = BitWriter::new(out);
    let touched = drawing.touched()?;
    let mut next_touched = 0;
    for (index, interval) in entropy.intervals.iter().enumerate() {
        let mcus = index * per_interval..((index + 1) * per_interval).min(total);
        let first = next_touched;
        while touched.get(next_touched).is_some_and(|t| t.mcu < mcus.end) {
            next_touched += 1;
        }
        let here = touched.get(first..next_touched).unwrap_or_default();
        if here.is_empty() {
            let bytes = writer.bytes().ok_or(CannotSplice::BadEntropy)?;
            bytes.extend_from_slice(
                file.get(interval.file.start..interval.next)
                    .unwrap_or_default(),
            );
            if !walk.changed {
                walk.report.verbatim_prefix = bytes.len();
            }
            continue;
        }
        walk.interval(&mut writer, interval, mcus, here, index)?;
    }
    if let Some(chroma) = layout.chroma {
        walk.chroma_scans(&mut writer, chroma, total, per_interval)?;
    }
    let mut out = writer.into_bytes();
    out.extend_from_slice(file.get(entropy.end..).unwrap_or_default());
    Ok((out, walk.report))
}

impl Walk<'_> {
    /// Splices the restart interval `index` (MCUs `mcus`), which holds the drawn MCUs `here`.
    fn interval(
        &mut self,
        writer: &mut BitWriter,
        interval: &Interval,
        mcus: Range<usize>,
        here: &[Touched],
        index: usize,
    ) -> Result<(), CannotSplice> {
        let (file, entropy) = (self.file, self.entropy);
        let data = entropy.data.as_slice();
        let end_bits = interval.data.end * 8;
        self.read_dc = [0; 3];
        let mut reader = BitReader::new(data, interval.data.start * 8);
        // The MCUs before the first drawn one: their bytes, then the bits up to it.
        let first = here.first().map_or(mcus.start, |t| t.mcu);
        for _ in mcus.start..first {
            self.skip_mcu(&mut reader)?;
        }
        check(&reader, end_bits)?;
        let start = reader.position();
        let bytes = writer.bytes().ok_or(CannotSplice::BadEntropy)?;
        let prefix_end = entropy.file_offset(interval, start / 8);
        bytes.extend_from_slice(
            file.get(interval.file.start..prefix_end)
                .unwrap_or_default(),
        );
        if !self.changed {
            self.report.verbatim_prefix = bytes.len();
            self.changed = true;
        }
        writer.copy_bits(data, start / 8 * 8, start);
        self.write_dc = self.read_dc;
        // The drawn MCUs, the one after each run of them, and those between, into scratch.
        let last_touched = here.last().map_or(first, |t| t.mcu);
        let last = (last_touched + 1).min(mcus.end - 1);
        let capacity = interval.data.end.saturating_sub(start / 8) + 1024;
        let mut segment = Segment {
            start,
            scratch: BitWriter::scratch(capacity),
            slots: Vec::new(),
        };
        let mut pending = here.iter().peekable();
        let mut previous_touched = false;
        // Where the run of MCUs copied as they are began.
        let mut copy_from: Option<usize> = None;
        let mut mcu = first;
        while mcu <= last {
            let drawn = pending.next_if(|t| t.mcu == mcu);
            if drawn.is_some() || previous_touched {
                if let Some(from) = copy_from.take() {
                    segment.scratch.copy_bits(data, from, reader.position());
                }
                self.decode_mcu(&mut reader)?;
                if let Some(&t) = drawn {
                    self.drawing.draw(
                        t,
                        &self.colours,
                        self.layout,
                        &self.transform,
                        &mut self.coefficients,
                    );
                    // A grey frame's added chroma, where the drawing is not neutral (a
                    // zero block is what the chroma scans write anyway).
                    if let (Some(_), [_, cb, cr]) =
                        (self.layout.chroma, self.coefficients.as_slice())
                        && cb.iter().chain(cr).any(|&c| c != 0)
                    {
                        self.chroma.push((mcu, [*cb, *cr]));
                    }
                }
                self.encode_mcu(&mut segment.scratch, &mut segment.slots)?;
                self.report.reencoded_mcus += 1;
            } else if let Some(next) = pending
                .peek()
                .map(|t| t.mcu)
                .filter(|&next| copy_from.is_none() && self.align && next >= mcu + ALIGNED_RUN)
            {
                // A long run of MCUs kept as they are: its bytes, when ZRLs can align it.
                let run_start = reader.position();
                for _ in mcu..next {
                    self.skip_mcu(&mut reader)?;
                }
                check(&reader, end_bits)?;
                self.write_dc = self.read_dc;
                let run = run_start..reader.position();
                if write_aligned_run(writer, (file, entropy), interval, &mut segment, run.clone())?
                {
                    self.report.aligned_runs += 1;
                } else {
                    segment.scratch.copy_bits(data, run.start, run.end);
                }
                previous_touched = false;
                mcu = next;
                continue;
            } else {
                copy_from.get_or_insert(reader.position());
                self.skip_mcu(&mut reader)?;
                self.write_dc = self.read_dc;
            }
            previous_touched = drawn.is_some();
            check(&reader, end_bits)?;
            mcu += 1;
        }
        let end = reader.position();
        if let Some(from) = copy_from {
            segment.scratch.copy_bits(data, from, end);
        }
        if self.align && last + 1 < mcus.end && align_to(writer, data, &mut segment, end) {
            // The rest of the interval keeps its bytes.
            let bytes = writer.bytes().ok_or(CannotSplice::BadEntropy)?;
            let resume = entropy.file_offset(interval, end.div_ceil(8));
            bytes.extend_from_slice(file.get(resume..interval.next).unwrap_or_default());
            self.report.aligned_tails += 1;
            return Ok(());
        }
        let (bits, length) = segment.scratch.into_bits();
        writer.copy_bits(&bits, 0, length);
        // The rest of the interval, shifted as it comes.
        for _ in last + 1..mcus.end {
            self.skip_mcu(&mut reader)?;
        }
        check(&reader, end_bits)?;
        writer.copy_bits(data, end, reader.position());
        writer.pad();
        if mcus.end < self.total {
            let bytes = writer.bytes().ok_or(CannotSplice::BadEntropy)?;
            bytes.extend_from_slice(&[0xFF, 0xD0 + u8::try_from(index % 8).unwrap_or(0)]);
        }
        if last + 1 < mcus.end {
            self.report.shifted_tails += 1;
        }
        Ok(())
    }

    /// Reads past one MCU, keeping the DC predictors.
    fn skip_mcu(&mut self, reader: &mut BitReader<'_>) -> Result<(), CannotSplice> {
        let layout = self.layout;
        for &(plane, _, _) in layout.blocks.iter().take(layout.input_blocks) {
            let (Some(p), Some(dc)) = (layout.planes.get(plane), self.read_dc.get_mut(plane))
            else {
                return Err(CannotSplice::BadEntropy);
            };
            let (dc_decoder, ac_decoder) = p.decoders().ok_or(CannotSplice::BadEntropy)?;
            skip_block(reader, dc_decoder, ac_decoder, dc)?;
        }
        Ok(())
    }

    /// Reads one MCU's coefficients (the chroma added to a grey frame is zero).
    fn decode_mcu(&mut self, reader: &mut BitReader<'_>) -> Result<(), CannotSplice> {
        let layout = self.layout;
        for (&(plane, _, _), coefficients) in layout.blocks.iter().zip(&mut self.coefficients) {
            *coefficients = [0; 64];
            let (Some(p), Some(dc)) = (layout.planes.get(plane), self.read_dc.get_mut(plane))
            else {
                return Err(CannotSplice::BadEntropy);
            };
            if let Some((dc_decoder, ac_decoder)) = p.decoders() {
                read_block(reader, dc_decoder, ac_decoder, dc, coefficients)?;
            }
        }
        Ok(())
    }

    /// Writes the MCU's blocks of the file's scan to `scratch`, noting where ZRLs may go.
    fn encode_mcu(
        &mut self,
        scratch: &mut BitWriter,
        slots: &mut Vec<Slot>,
    ) -> Result<(), CannotSplice> {
        let layout = self.layout;
        let blocks = layout.blocks.iter().zip(&self.coefficients);
        for (&(plane, _, _), coefficients) in blocks.take(layout.input_blocks) {
            let (Some(p), Some(dc)) = (layout.planes.get(plane), self.write_dc.get_mut(plane))
            else {
                return Err(CannotSplice::BadEntropy);
            };
            let zeros = write_block(scratch, p.encoders().0, p.encoders().1, dc, coefficients)?;
            if let (Some(zeros), Some(zrl)) = (zeros, p.zrl) {
                let room = zeros.saturating_sub(1) / 16;
                if room > 0 {
                    slots.push(Slot {
                        at: scratch.bit_len() - p.eob_bits as usize,
                        room,
                        zrl,
                    });
                }
            }
        }
        Ok(())
    }

    /// Writes a grey frame's Cb and Cr scans: zero blocks but where the overlay is drawn.
    fn chroma_scans(
        &mut self,
        writer: &mut BitWriter,
        chroma: Chroma,
        total: usize,
        per_interval: usize,
    ) -> Result<(), CannotSplice> {
        let layout = self.layout;
        for (k, &id) in chroma.ids.iter().enumerate() {
            let Some(p) = layout.planes.get(layout.input_blocks + k) else {
                return Err(CannotSplice::BadEntropy);
            };
            let tables = chroma.tables.0 << 4 | chroma.tables.1;
            let bytes = writer.bytes().ok_or(CannotSplice::BadEntropy)?;
            bytes.extend_from_slice(&[0xFF, 0xDA, 0, 8, 1, id, tables, 0, 63, 0]);
            let (dc_code, dc_bits) = p.encoders().0.code(0)?;
            let (eob_code, eob_bits) = p.encoders().1.code(0)?;
            let zero = (dc_code << eob_bits | eob_code, dc_bits + eob_bits);
            let mut drawn = self.chroma.iter().peekable();
            for (index, start) in (0..total).step_by(per_interval).enumerate() {
                let mut dc = 0;
                let end = (start + per_interval).min(total);
                let mut mcu = start;
                while mcu < end {
                    if let Some((_, blocks)) = drawn.next_if(|d| d.0 == mcu) {
                        let block = blocks.get(k).ok_or(CannotSplice::BadEntropy)?;
                        if dc == 0 && block.iter().all(|&c| c == 0) {
                            writer.put(zero.0, zero.1);
                        } else {
                            write_block(writer, p.encoders().0, p.encoders().1, &mut dc, block)?;
                        }
                        mcu += 1;
                    } else if dc != 0 {
                        write_block(writer, p.encoders().0, p.encoders().1, &mut dc, &[0; 64])?;
                        mcu += 1;
                    } else {
                        // Zero blocks up to the next drawn one.
                        let next = drawn.peek().map_or(end, |d| d.0.clamp(mcu + 1, end));
                        writer.repeat(zero.0, zero.1, next - mcu);
                        mcu = next;
                    }
                }
                writer.pad();
                if start + per_interval < total {
                    let bytes = writer.bytes().ok_or(CannotSplice::BadEntropy)?;
                    bytes.extend_from_slice(&[0xFF, 0xD0 + u8::try_from(index % 8).unwrap_or(0)]);
                }
            }
        }
        Ok(())
    }
}

/// Fails when the reader went past the interval's data (`end_bits`).
fn check(reader: &BitReader<'_>, end_bits: usize) -> Result<(), CannotSplice> {
    if reader.position() > end_bits {
        return Err(CannotSplice::BadEntropy);
    }
    Ok(())
}
