//! One block's entropy coding (ITU T.81 F.1.2, F.2.2): reading it to coefficients or only
//! past it, and writing it with given Huffman tables.

use super::CannotSplice;
use super::block::Coefficients;
use super::entropy::{BitReader, BitWriter, Pending};
use super::huffman::{self, Decoder, Encoder};

/// The value of `bits` (the `size` bits read after a size category), ITU T.81 F.2.2.1.
#[inline]
fn extend(bits: u32, size: u32) -> i32 {
    let value = i32::try_from(bits).unwrap_or(0);
    if size == 0 {
        0
    } else if bits < 1 << (size - 1) {
        value - (1 << size) + 1
    } else {
        value
    }
}

/// Reads a block's DC difference, which updates `dc`.
#[inline(always)]
fn read_dc(
    reader: &mut BitReader<'_>,
    dc_decoder: &Decoder,
    dc: &mut i32,
) -> Result<(), CannotSplice> {
    let ahead = reader.peek_u32();
    let (size, length) = dc_decoder.lookup(ahead)?;
    let size = u32::from(size);
    if size > 11 {
        return Err(CannotSplice::BadEntropy);
    }
    *dc = dc.wrapping_add(extend(value_bits(ahead, length, size), size));
    reader.consume(length + size);
    Ok(())
}

/// Reads past one block; its DC updates `dc`. Inlined into the loop over an MCU's blocks:
/// most blocks of a splice are only read past.
#[inline(always)]
pub fn skip_block(
    reader: &mut BitReader<'_>,
    dc_decoder: &Decoder,
    ac_decoder: &Decoder,
    dc: &mut i32,
) -> Result<(), CannotSplice> {
    read_dc(reader, dc_decoder, dc)?;
    skip_ac(reader, ac_decoder)
}

/// Reads one block into `out` (zigzag order); its DC updates `dc`.
pub fn read_block(
    reader: &mut BitReader<'_>,
    dc_decoder: &Decoder,
    ac_decoder: &Decoder,
    dc: &mut i32,
    out: &mut Coefficients,
) -> Result<(), CannotSplice> {
    read_dc(reader, dc_decoder, dc)?;
    out[0] = *dc;
    let mut k = 1_usize;
    while k < 64 {
        let ahead = reader.peek_u32();
        let (symbol, length) = ac_decoder.lookup(ahead)?;
        let (run, size) = (usize::from(symbol >> 4), u32::from(symbol & 15));
        if size == 0 {
            reader.consume(length);
            if run == 15 {
                k += 16;
                if k > 64 {
                    return Err(CannotSplice::BadEntropy);
                }
                continue;
            }
            break;
        }
        k += run;
        if k > 63 || size > 10 {
            return Err(CannotSplice::BadEntropy);
        }
        let value = extend(value_bits(ahead, length, size), size);
        if let Some(slot) = out.get_mut(k) {
            *slot = value;
        }
        reader.consume(length + size);
        k += 1;
    }
    Ok(())
}

/// Reads past a block's AC coefficients.
#[inline(always)]
fn skip_ac(outer: &mut BitReader<'_>, ac_decoder: &Decoder) -> Result<(), CannotSplice> {
    // A local copy keeps the reader's state in registers.
    let mut local = *outer;
    let reader = &mut local;
    // The next coefficient's zigzag index; an end of block takes it past 128.
    let mut k = 1_u32;
    while k < 64 {
        let ahead = reader.peek_u32();
        if let Some([first, both, advance, total]) = ac_decoder.skip_ac_pair(ahead) {
            // Both codes when the first leaves the block unfinished.
            if k + u32::from(advance) >= 64 {
                reader.consume(u32::from(first));
                k += u32::from(advance);
                continue;
            }
            reader.consume(u32::from(both));
            k += u32::from(total);
            // Two more from the same 32 bits: at most 12 were taken, and a pair's codes and
            // values fit in the next 12.
            if k < 64
                && let Some([first, both, advance, total]) = ac_decoder.skip_ac_pair(ahead << both)
            {
                if k + u32::from(advance) < 64 {
                    reader.consume(u32::from(both));
                    k += u32::from(total);
                } else {
                    reader.consume(u32::from(first));
                    k += u32::from(advance);
                }
            }
            continue;
        }
        let (bits, advance) = match ac_decoder.skip_ac(ahead) {
            Some(entry) => entry,
            None => {
                // A code longer than the skip table's lookahead, or no code.
                let (symbol, length) = ac_decoder.lookup(ahead)?;
                let (run, size) = (symbol >> 4, symbol & 15);
                let advance = match (run, size) {
                    (_, 11..) => return Err(CannotSplice::BadEntropy),
                    (15, 0) => 16,
                    (_, 0) => huffman::END_OF_BLOCK,
                    (run, _) => run + 1,
                };
                (length + u32::from(size), advance)
            }
        };
        reader.consume(bits);
        k += u32::from(advance);
    }
    *outer = local;
    // Past 64 but not by an end of block: a run beyond the block.
    if (65..128).contains(&k) {
        return Err(CannotSplice::BadEntropy);
    }
    Ok(())
}

/// The `size` bits after a code of `length` bits at the start of `ahead` (length ≤ 16 and
/// size ≤ 11: they fit in the 32 bits).
#[inline]
fn value_bits(ahead: u32, length: u32, size: u32) -> u32 {
    if size == 0 {
        0
    } else {
        (ahead << length) >> (32 - size)
    }
}

/// The size category of `value` and its bits (ITU T.81 F.1.2.1).
#[inline]
fn magnitude(value: i32) -> (u32, u32) {
    let a = value.unsigned_abs();
    let size = 32 - a.leading_zeros();
    let bits = if value < 0 {
        1_u32
            .checked_shl(size)
            .unwrap_or(0)
            .wrapping_sub(1)
            .wrapping_sub(a)
    } else {
        a
    };
    (size, bits)
}

/// Writes one block (zigzag order) after the DC predictor `dc`, which it updates. When it
/// ends in an end-of-block code (its last code written), the number of zero coefficients
/// that code stands for.
///
/// # Errors
/// [`CannotSplice::MissingCode`] for a code the tables lack, [`CannotSplice::BadEntropy`]
/// for a coefficient out of range.
pub fn write_block(
    writer: &mut BitWriter,
    dc_encoder: &Encoder,
    ac_encoder: &Encoder,
    dc: &mut i32,
    coefficients: &Coefficients,
) -> Result<Option<u32>, CannotSplice> {
    // The pending bits in locals, so that they stay in registers.
    let (mut bits, stuffing) = writer.take_pending();
    let result = encode_block(
        writer.bytes_mut(),
        &mut bits,
        stuffing,
        (dc_encoder, ac_encoder),
        dc,
        coefficients,
    );
    writer.restore_pending(bits);
    result
}

/// [`write_block`] with the writer's pending bits in `bits`.
#[inline(always)]
fn encode_block(
    out: &mut Vec<u8>,
    bits: &mut Pending,
    stuffing: bool,
    (dc_encoder, ac_encoder): (&Encoder, &Encoder),
    dc: &mut i32,
    coefficients: &Coefficients,
) -> Result<Option<u32>, CannotSplice> {
    let (size, value_bits) = magnitude(coefficients[0].wrapping_sub(*dc));
    *dc = coefficients[0];
    if size > 11 {
        return Err(CannotSplice::BadEntropy);
    }
    let (code, length) = dc_encoder.code(u8::try_from(size).unwrap_or(0))?;
    bits.put_code(
        out,
        u64::from(code << size | value_bits),
        length + size,
        stuffing,
    );
    // Which AC coefficients are not zero.
    let mut nonzero = 0_u64;
    for (k, &value) in coefficients.iter().enumerate().skip(1) {
        nonzero |= u64::from(value != 0) << k;
    }
    let mut next = 1_u32;
    while nonzero != 0 {
        let k = nonzero.trailing_zeros();
        nonzero &= nonzero - 1;
        let mut run = k - next;
        while run > 15 {
            let (code, length) = ac_encoder.code(0xF0)?;
            bits.put_code(out, u64::from(code), length, stuffing);
            run -= 16;
        }
        let (size, value_bits) = magnitude(coefficients[(k & 63) as usize]);
        if size > 10 {
            return Err(CannotSplice::BadEntropy);
        }
        let symbol = u8::try_from(run << 4 | size).map_err(|_| CannotSplice::BadEntropy)?;
        let (code, length) = ac_encoder.code(symbol)?;
        bits.put_code(
            out,
            u64::from(code << size | value_bits),
            length + size,
            stuffing,
        );
        next = k + 1;
    }
    if next < 64 {
        let (code, length) = ac_encoder.code(0x00)?;
        bits.put_code(out, u64::from(code), length, stuffing);
        return Ok(Some(64 - next));
    }
    Ok(None)
}
