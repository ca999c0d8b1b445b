//! The scan's entropy-coded data: split at its restart markers and un-stuffed (0xFF 0x00 read
//! as 0xFF) so that bits can be addressed by position, and the writer that stuffs again.

use super::CannotSplice;
use std::ops::Range;

/// Bytes after the last interval's data, so that an 8-byte read near the end never fails.
const PADDING: usize = 8;

/// The un-stuffed data of every restart interval, back to back.
#[derive(Debug, Clone)]
pub struct Entropy {
    /// The data bytes, [`PADDING`] zero bytes at the end.
    pub data: Vec<u8>,
    /// The restart intervals, in order (one when the file has no restart interval).
    pub intervals: Vec<Interval>,
    /// Indices in `data` of the 0xFF bytes (stuffed as 0xFF 0x00 in the file), ascending.
    pub stuffed: Vec<usize>,
    /// Where in the file the entropy-coded data ends: the marker after the scan (or its
    /// fill bytes), or the end of the file.
    pub end: usize,
}

/// One restart interval.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Interval {
    /// Its bytes in [`Entropy::data`].
    pub data: Range<usize>,
    /// Its stuffed bytes in the file, without the fill bytes or the marker that end it.
    pub file: Range<usize>,
    /// Where the next interval starts in the file (after this one's RST marker), or
    /// [`Entropy::end`] for the last.
    pub next: usize,
}

impl Entropy {
    /// Splits the entropy-coded data starting at `start` in `file`. `restarts` says whether
    /// the file has a restart interval: RST markers are expected, in order, only then.
    ///
    /// # Errors
    /// [`CannotSplice::Malformed`] for a misplaced RST marker or fill bytes inside data.
    pub fn split(file: &[u8], start: usize, restarts: bool) -> Result<Self, CannotSplice> {
        let mut data = Vec::with_capacity(file.len().saturating_sub(start) + PADDING);
        let mut intervals = Vec::new();
        let mut stuffed = Vec::new();
        let (mut at, mut interval_file, mut interval_data) = (start, start, 0);
        let mut next_rst = 0_u8;
        let end = loop {
            let rest = file.get(at..).unwrap_or_default();
            let Some(ff) = find_ff(rest) else {
                data.extend_from_slice(rest);
                intervals.push(Interval {
                    data: interval_data..data.len(),
                    file: interval_file..file.len(),
                    next: file.len(),
                });
                break file.len();
            };
            data.extend_from_slice(rest.get(..ff).unwrap_or_default());
            let marker_at = at + ff;
            // 0xFF bytes before a marker are fill.
            let mut code_at = marker_at + 1;
            while file.get(code_at) == Some(&0xFF) {
                code_at += 1;
            }
            match file.get(code_at).copied() {
                Some(0) if code_at == marker_at + 1 => {
                    stuffed.push(data.len());
                    data.push(0xFF);
                    at = code_at + 1;
                }
                Some(0) => return Err(CannotSplice::Malformed("fill bytes inside data")),
                Some(code @ 0xD0..=0xD7) => {
                    if !restarts || code != 0xD0 + next_rst {
                        return Err(CannotSplice::Malformed("unexpected RST marker"));
                    }
                    next_rst = (next_rst + 1) % 8;
                    intervals.push(Interval {
                        data: interval_data..data.len(),
                        file: interval_file..marker_at,
                        next: code_at + 1,
                    });
                    at = code_at + 1;
                    (interval_file, interval_data) = (at, data.len());
                }
                _ => {
                    intervals.push(Interval {
                        data: interval_data..data.len(),
                        file: interval_file..marker_at,
                        next: marker_at,
                    });
                    break marker_at;
                }
            }
        };
        data.resize(data.len() + PADDING, 0);
        Ok(Self {
            data,
            intervals,
            stuffed,
            end,
        })
    }

    /// The file offset of byte `index` of `data`, which lies in `interval` (or is its end).
    pub fn file_offset(&self, interval: &Interval, index: usize) -> usize {
        let before = self.stuffed.partition_point(|&i| i < index)
            - self.stuffed.partition_point(|&i| i < interval.data.start);
        interval.file.start + (index - interval.data.start) + before
    }
}

/// The index of the first 0xFF byte of `bytes`, eight bytes at a time.
fn find_ff(bytes: &[u8]) -> Option<usize> {
    const ONES: u64 = 0x0101_0101_0101_0101;
    const HIGHS: u64 = 0x8080_8080_8080_8080;
    let mut chunks = bytes.chunks_exact(8);
    let mut at = 0;
    for chunk in &mut chunks {
        if let &[a, b, c, d, e, f, g, h] = chunk {
            let word = u64::from_le_bytes([a, b, c, d, e, f, g, h]);
            // A zero byte of !word is a 0xFF byte of word.
            if (!word).wrapping_sub(ONES) & word & HIGHS != 0 {
                break;
            }
        }
        at += 8;
    }
    bytes
        .get(at..)
        .and_then(|rest| rest.iter().position(|&b| b == 0xFF))
        .map(|i| at + i)
}

/// Reads bits, most significant first, from un-stuffed data, keeping its bit position.
#[derive(Debug, Clone, Copy)]
pub struct BitReader<'a> {
    data: &'a [u8],
    /// The next byte to load.
    next: usize,
    /// Loaded bits, the next one in the most significant place.
    buffer: u64,
    /// How many bits of `buffer` are loaded.
    count: u32,
}

impl<'a> BitReader<'a> {
    /// A reader at bit `position` of `data`.
    pub fn new(data: &'a [u8], position: usize) -> Self {
        let mut reader = Self {
            data,
            next: position / 8,
            buffer: 0,
            count: 0,
        };
        reader.refill();
        reader.consume(u32::try_from(position % 8).unwrap_or(0));
        reader
    }

    /// The bit position.
    pub fn position(&self) -> usize {
        self.next * 8 - self.count as usize
    }

    /// Loads whole bytes up to 56-63 bits (zeros past the data), without a branch. Bits
    /// below `count` in `buffer` are zero or already the data's, so OR-ing the next 8 bytes
    /// in keeps them right.
    #[inline(always)]
    fn refill(&mut self) {
        self.buffer |= load_u64(self.data, self.next) >> (self.count & 63);
        self.next += ((63 - (self.count & 63)) >> 3) as usize;
        self.count |= 56;
    }

    /// The next 32 bits (zeros past the data), without consuming them.
    #[inline(always)]
    pub fn peek_u32(&mut self) -> u32 {
        self.refill();
        let [a, b, c, d, ..] = self.buffer.to_be_bytes();
        u32::from_be_bytes([a, b, c, d])
    }

    /// Skips `n` bits, at most 32, after a [`Self::peek_u32`] (which leaves 56 or more).
    #[inline(always)]
    pub fn consume(&mut self, n: u32) {
        self.buffer = self.buffer.wrapping_shl(n);
        self.count = self.count.saturating_sub(n);
    }
}

/// The 8 bytes of `data` from `byte` on, big-endian (zeros past the end).
#[inline]
fn load_u64(data: &[u8], byte: usize) -> u64 {
    match data.get(byte..byte + 8) {
        Some(&[a, b, c, d, e, f, g, h]) => u64::from_be_bytes([a, b, c, d, e, f, g, h]),
        _ => {
            let mut bytes = [0_u8; 8];
            for (slot, &b) in bytes.iter_mut().zip(data.get(byte..).unwrap_or_default()) {
                *slot = b;
            }
            u64::from_be_bytes(bytes)
        }
    }
}

/// The 32 bits of `data` from bit `position` on (zeros past the end).
#[inline]
fn peek_at(data: &[u8], position: usize) -> u32 {
    let [a, b, c, d, ..] = (load_u64(data, position / 8) << (position % 8)).to_be_bytes();
    u32::from_be_bytes([a, b, c, d])
}

/// Bits not yet written out: the low `count` bits of `bits` (fewer than 32 between calls).
#[derive(Debug, Clone, Copy, Default)]
pub struct Pending {
    bits: u64,
    count: u32,
}

impl Pending {
    /// Appends the low `n` bits (0-32) of `value`, writing 32 bits to `out` once there are
    /// as many (a 0x00 after each 0xFF byte when `stuffing`).
    #[inline(always)]
    pub fn put(&mut self, out: &mut Vec<u8>, value: u32, n: u32, stuffing: bool) {
        if n == 0 {
            return;
        }
        let mask = u64::MAX >> (64 - n);
        self.put_code(out, u64::from(value) & mask, n, stuffing);
    }

    /// [`Self::put`] of a Huffman code (and the value bits after it) of `n` bits, 1-32,
    /// nothing above them set: no mask, no test for zero bits.
    #[inline(always)]
    pub fn put_code(&mut self, out: &mut Vec<u8>, code: u64, n: u32, stuffing: bool) {
        self.bits = (self.bits << (n & 63)) | code;
        self.count += n;
        if self.count >= 32 {
            self.count -= 32;
            let [_, _, _, _, a, b, c, d] = (self.bits >> self.count).to_be_bytes();
            write_word(out, [a, b, c, d], stuffing);
        }
    }
}

/// Appends four bytes, a 0x00 after each 0xFF byte when `stuffing`.
#[inline]
fn write_word(out: &mut Vec<u8>, word: [u8; 4], stuffing: bool) {
    // A zero byte of !w is a 0xFF byte of w.
    let w = u32::from_be_bytes(word);
    let has_ff = (!w).wrapping_sub(0x0101_0101) & w & 0x8080_8080 != 0;
    if stuffing && has_ff {
        for byte in word {
            out.push(byte);
            if byte == 0xFF {
                out.push(0);
            }
        }
    } else {
        out.extend_from_slice(&word);
    }
}

/// Writes bits, most significant first, stuffing a 0x00 after every 0xFF byte (or, as a
/// scratch buffer, not).
#[derive(Debug, Clone, Default)]
pub struct BitWriter {
    out: Vec<u8>,
    pending: Pending,
    stuffing: bool,
}

impl BitWriter {
    /// A writer of entropy-coded data appending to `out`.
    pub fn new(out: Vec<u8>) -> Self {
        Self {
            out,
            pending: Pending::default(),
            stuffing: true,
        }
    }

    /// A writer of un-stuffed bits, to be copied into another with [`Self::copy_bits`], with
    /// room for `bytes`.
    pub fn scratch(bytes: usize) -> Self {
        Self {
            out: Vec::with_capacity(bytes),
            stuffing: false,
            ..Self::default()
        }
    }

    /// Bits written so far (of a scratch writer: its position).
    pub fn bit_len(&self) -> usize {
        self.out.len() * 8 + self.pending.count as usize
    }

    /// A scratch writer's bits, the last byte padded with zeros, and their number.
    pub fn into_bits(mut self) -> (Vec<u8>, usize) {
        let length = self.bit_len();
        self.flush_bytes();
        let Pending { bits, count } = self.pending;
        if count > 0 {
            self.out.push((bits << (8 - count)).to_be_bytes()[7]);
        }
        (self.out, length)
    }

    /// The pending bits, to be given back with [`Self::restore_pending`] after writing to
    /// [`Self::bytes_mut`], and whether the writer stuffs.
    pub fn take_pending(&mut self) -> (Pending, bool) {
        (std::mem::take(&mut self.pending), self.stuffing)
    }

    /// The output, for [`Pending::put`].
    pub fn bytes_mut(&mut self) -> &mut Vec<u8> {
        &mut self.out
    }

    /// Gives back the pending bits of [`Self::take_pending`].
    pub fn restore_pending(&mut self, pending: Pending) {
        self.pending = pending;
    }

    /// Appends the low `n` bits (0-32) of `value`.
    #[inline(always)]
    pub fn put(&mut self, value: u32, n: u32) {
        self.pending.put(&mut self.out, value, n, self.stuffing);
    }

    /// Appends `count` copies of the low `n` bits (1-32) of `value`.
    pub fn repeat(&mut self, value: u32, n: u32, count: usize) {
        if n == 0 || n > 32 {
            return;
        }
        if value & (u32::MAX >> (32 - n)) == 0 {
            self.zeros(count * n as usize);
            return;
        }
        // As many copies as fit in 32 bits at a time.
        let per_word = (32 / n) as usize;
        let mut word = 0_u32;
        for _ in 0..per_word {
            word = word.checked_shl(n).unwrap_or(0) | value & (u32::MAX >> (32 - n));
        }
        let word_bits = n * (32 / n);
        for _ in 0..count / per_word {
            self.put(word, word_bits);
        }
        for _ in 0..count % per_word {
            self.put(value, n);
        }
    }

    /// Appends `bits` zero bits: whole zero bytes at once (a zero byte is never stuffed), as
    /// a grey frame's added chroma scans are mostly made of (zero blocks of typical tables).
    fn zeros(&mut self, bits: usize) {
        // Up to a byte boundary of the output.
        let lead = ((8 - self.pending.count % 8) % 8) as usize;
        if bits < lead + 8 {
            self.put_zeros(bits);
            return;
        }
        self.put_zeros(lead);
        self.flush_bytes();
        let bytes = (bits - lead) / 8;
        self.out.resize(self.out.len() + bytes, 0);
        self.put_zeros(bits - lead - 8 * bytes);
    }

    /// Appends `bits` zero bits, 32 at a time.
    fn put_zeros(&mut self, mut bits: usize) {
        while bits > 0 {
            let n = bits.min(32);
            self.put(0, u32::try_from(n).unwrap_or(32));
            bits -= n;
        }
    }

    /// Writes out the whole bytes of the pending bits.
    fn flush_bytes(&mut self) {
        let Pending { bits, count } = &mut self.pending;
        while *count >= 8 {
            *count -= 8;
            let byte = (*bits >> *count).to_be_bytes()[7];
            self.out.push(byte);
            if byte == 0xFF && self.stuffing {
                self.out.push(0);
            }
        }
    }

    /// Appends bits `from..to` of un-stuffed `data`.
    pub fn copy_bits(&mut self, data: &[u8], from: usize, to: usize) {
        let (mut pending, stuffing) = self.take_pending();
        let mut at = from;
        while at < to {
            let n = u32::try_from((to - at).min(32)).unwrap_or(32);
            let word = peek_at(data, at);
            pending.put(&mut self.out, word >> (32 - n), n, stuffing);
            at += n as usize;
        }
        self.pending = pending;
    }

    /// Pads with 1 bits to a byte boundary, as at the end of a restart interval.
    pub fn pad(&mut self) {
        let n = (8 - self.pending.count % 8) % 8;
        self.put(u32::MAX, n);
        self.flush_bytes();
    }

    /// The output, when the bits end on a byte boundary (after [`Self::pad`]), to append
    /// bytes or markers unstuffed.
    pub fn bytes(&mut self) -> Option<&mut Vec<u8>> {
        self.flush_bytes();
        (self.pending.count == 0).then_some(&mut self.out)
    }

    /// The output; pending bits short of a byte (none after [`Self::pad`]) are dropped.
    pub fn into_bytes(mut self) -> Vec<u8> {
        self.flush_bytes();
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The padded bytes of the `lead` codes, then `count` copies of the `n` bits of `value`
    /// written a bit at a time.
    fn one_by_one(lead: &[(u32, u32)], value: u32, n: u32, count: usize) -> Vec<u8> {
        let mut writer = BitWriter::new(Vec::new());
        for &(v, bits) in lead {
            writer.put(v, bits);
        }
        for _ in 0..count {
            for bit in (0..n).rev() {
                writer.put(value >> bit & 1, 1);
            }
        }
        writer.pad();
        writer.into_bytes()
    }

    #[test]
    fn repeated_codes_are_the_codes_written_one_by_one() {
        // Zero codes take the whole-byte path, others the 32-bit one; after 0-31 pending
        // bits, with 0xFF bytes (stuffed) before them.
        for lead in [
            vec![],
            vec![(1, 1)],
            vec![(0x7F, 7)],
            vec![(0xFFFF, 16), (5, 3)],
            vec![(0x1234_5678, 31)],
        ] {
            for (value, n, count) in [
                (0, 4, 1000),
                (0, 3, 7),
                (0, 9, 333),
                (0b1010, 4, 100),
                (1, 2, 77),
            ] {
                let mut writer = BitWriter::new(Vec::new());
                for &(v, bits) in &lead {
                    writer.put(v, bits);
                }
                writer.repeat(value, n, count);
                writer.pad();
                assert_eq!(
                    writer.into_bytes(),
                    one_by_one(&lead, value, n, count),
                    "{lead:?}, {count} × {n} bits of {value:#b}"
                );
            }
        }
    }
}
