//! Keeping the bytes of the data after re-encoded MCUs: ZRL codes (16 zeros each, put
//! before end-of-block codes, no coefficient changes) make the re-encoded bits a whole
//! number of bytes longer or shorter than the old, so that the output is at the data's bit
//! position modulo 8 and what follows is copied byte for byte, stuffing included.

use super::CannotSplice;
use super::entropy::{BitWriter, Entropy, Interval};
use std::ops::Range;

/// Where ZRL codes may go in re-encoded bits: before the end-of-block code at bit `at`.
#[derive(Debug, Clone, Copy)]
pub struct Slot {
    pub at: usize,
    /// How many ZRLs fit: each stands for 16 of the block's trailing zeros, and the
    /// end-of-block code must still follow (at least one zero left).
    pub room: u32,
    /// The ZRL code, (code, length).
    pub zrl: (u32, u32),
}

/// The MCUs shorter runs of which are copied bit by bit with the re-encoded ones, not
/// aligned with ZRLs to keep their bytes: a run of 8 holds a few dozen bytes.
pub const ALIGNED_RUN: usize = 8;

/// The bits written since the output was last at a known bit position of the data.
pub struct Segment {
    /// The data's bit position the output was at, modulo 8, when the segment began.
    pub start: usize,
    /// Its bits, un-stuffed.
    pub scratch: BitWriter,
    /// Where ZRLs may go in `scratch`.
    pub slots: Vec<Slot>,
}

/// Writes the segment's bits with ZRLs that put the output at bit `at` of the un-stuffed
/// `data` modulo 8, then the data's bits from `at` to its next byte boundary: the output
/// is then where the file's byte `at.div_ceil(8)` would go, and the file's bytes can
/// follow. The segment is left empty. `false`, with nothing written, when no ZRLs align
/// it.
pub fn align_to(writer: &mut BitWriter, data: &[u8], segment: &mut Segment, at: usize) -> bool {
    let length = segment.scratch.bit_len();
    let target = (at - segment.start) % 8 + 8 - length % 8;
    let Some(zrls) = plan_zrls(&segment.slots, u32::try_from(target % 8).unwrap_or(0)) else {
        return false;
    };
    let (bits, length) = std::mem::take(&mut segment.scratch).into_bits();
    write_with_zrls(writer, &bits, length, &segment.slots, &zrls);
    segment.slots.clear();
    writer.copy_bits(data, at, at.div_ceil(8) * 8);
    true
}

/// [`align_to`] the start of `run` (un-stuffed data), then the run: the file's bytes up
/// to its last byte boundary, and its last bits; the segment starts anew after it. `false`,
/// with nothing written, when no ZRLs align it or the run holds no whole byte.
pub fn write_aligned_run(
    writer: &mut BitWriter,
    (file, entropy): (&[u8], &Entropy),
    interval: &Interval,
    segment: &mut Segment,
    run: Range<usize>,
) -> Result<bool, CannotSplice> {
    let (first_byte, last_byte) = (run.start.div_ceil(8), run.end / 8);
    let data = entropy.data.as_slice();
    if last_byte <= first_byte || !align_to(writer, data, segment, run.start) {
        return Ok(false);
    }
    let bytes = writer.bytes().ok_or(CannotSplice::BadEntropy)?;
    let (from, to) = (
        entropy.file_offset(interval, first_byte),
        entropy.file_offset(interval, last_byte),
    );
    bytes.extend_from_slice(file.get(from..to).unwrap_or_default());
    writer.copy_bits(data, last_byte * 8, run.end);
    segment.start = run.end;
    segment.scratch = BitWriter::scratch(interval.data.end.saturating_sub(last_byte) + 1024);
    Ok(true)
}

/// How many ZRLs to put in each slot (by index) so that they add `target` bits modulo 8,
/// as few slots' worth as it takes; `None` when the slots cannot.
fn plan_zrls(slots: &[Slot], target: u32) -> Option<Vec<(usize, u32)>> {
    if target == 0 {
        return Some(Vec::new());
    }
    // One entry per ZRL that fits (seven per slot are all any residue needs).
    let entries: Vec<(usize, u32)> = slots
        .iter()
        .enumerate()
        .flat_map(|(i, s)| std::iter::repeat_n((i, s.zrl.1 % 8), s.room.min(7) as usize))
        .take(64)
        .collect();
    // reached[j] bit r: whether the first j entries can add r modulo 8.
    let mut reached: Vec<u8> = vec![1];
    let target = u8::try_from(target).ok()?;
    let can = |set: u8, r: u8| set >> r & 1 == 1;
    for &(_, bits) in &entries {
        let previous = *reached.last()?;
        // Adding `bits` rotates the set of residues.
        let next = previous | previous.rotate_left(bits);
        reached.push(next);
        if can(next, target) {
            break;
        }
    }
    if !can(*reached.last()?, target) {
        return None;
    }
    // Back from the end: take an entry when the residue was not reachable without it.
    let mut counts: Vec<(usize, u32)> = Vec::new();
    let mut r = target;
    for j in (0..reached.len() - 1).rev() {
        if can(*reached.get(j)?, r) {
            continue;
        }
        let (slot, bits) = *entries.get(j)?;
        r = (r + 8 - u8::try_from(bits).ok()?) % 8;
        match counts.last_mut() {
            Some(last) if last.0 == slot => last.1 += 1,
            _ => counts.push((slot, 1)),
        }
    }
    counts.reverse();
    Some(counts)
}

/// Copies `length` bits of `bits` into `writer`, with `zrls` (slot index, count) ZRL codes
/// before the end-of-block codes of those slots.
fn write_with_zrls(
    writer: &mut BitWriter,
    bits: &[u8],
    length: usize,
    slots: &[Slot],
    zrls: &[(usize, u32)],
) {
    let mut at = 0;
    for &(slot, count) in zrls {
        let Some(s) = slots.get(slot) else {
            continue;
        };
        writer.copy_bits(bits, at, s.at);
        for _ in 0..count {
            writer.put(s.zrl.0, s.zrl.1);
        }
        at = s.at;
    }
    writer.copy_bits(bits, at, length);
}
