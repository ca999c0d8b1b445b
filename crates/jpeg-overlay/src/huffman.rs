//! Huffman tables (DHT): a decoder with a 9-bit lookahead table, as libjpeg's, and an encoder
//! table built from the same specification, so that re-encoded blocks use the file's codes.

use super::CannotSplice;
use std::sync::{Arc, Mutex, PoisonError};

/// Bits looked up at once; longer codes take the canonical slow path.
const LOOKAHEAD: u32 = 9;
/// Bits looked up at once when reading past AC coefficients.
const SKIP_LOOKAHEAD: u32 = 11;
/// [`Decoder::skip_ac`]'s advance for an end of block: past the end of any block.
pub const END_OF_BLOCK: u8 = 0x80;
/// Bits looked up at once for two AC codes and their values together.
const PAIR_LOOKAHEAD: u32 = 12;

/// A table as a DHT segment gives it: how many codes of each length 1-16, and the symbols
/// in code order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HuffmanSpec {
    /// `counts[l - 1]` codes of length `l`.
    pub counts: [u8; 16],
    /// The symbols, shortest code first.
    pub values: Vec<u8>,
}

/// The canonical code of each symbol of `spec`, as (code, length) in code order.
/// [`CannotSplice::Malformed`] when the lengths overflow the code space.
fn canonical_codes(spec: &HuffmanSpec) -> Result<Vec<(u32, u32)>, CannotSplice> {
    let mut codes = Vec::with_capacity(spec.values.len());
    let mut code = 0_u32;
    for (length, &count) in (1_u32..).zip(&spec.counts) {
        for _ in 0..count {
            codes.push((code, length));
            code += 1;
        }
        // A complete code of this length would end at 2^length; more codes do not fit.
        if code > 1 << length {
            return Err(CannotSplice::Malformed("Huffman code lengths overflow"));
        }
        code <<= 1;
    }
    if codes.len() != spec.values.len() {
        return Err(CannotSplice::Malformed("Huffman table size"));
    }
    Ok(codes)
}

/// Decodes symbols of one table.
#[derive(Debug, Clone)]
pub struct Decoder {
    /// By the next [`LOOKAHEAD`] bits: `length << 8 | symbol`, or 0 for a longer code.
    fast: Arc<[u16; 1 << LOOKAHEAD]>,
    /// By the next [`SKIP_LOOKAHEAD`] bits, read as an AC table: the bits of the code and
    /// its value `<< 8 |` how far it advances in the block (run + 1, 16 for ZRL,
    /// [`END_OF_BLOCK`]); 0 for a longer code or a size over 10.
    skip: Arc<[u16; 1 << SKIP_LOOKAHEAD]>,
    /// By the next [`PAIR_LOOKAHEAD`] bits, read as an AC table: the first code with its
    /// value, and the second too when it fits, as `bits of the first | bits of both << 8 |
    /// advance of the first << 16 | advance of both << 24`; 0 when not even the first fits.
    /// Built by [`Self::with_pairs`].
    pairs: Option<Arc<[u32; 1 << PAIR_LOOKAHEAD]>>,
    /// The largest code of each length (index 0-16), -1 when there is none.
    max_code: [i32; 17],
    /// What to add to a code of each length to get its index in `values`.
    offset: [i32; 17],
    values: Arc<[u8]>,
}

impl Decoder {
    /// The decoder of `spec`.
    ///
    /// # Errors
    /// [`CannotSplice::Malformed`] for an impossible table.
    pub fn new(spec: &HuffmanSpec) -> Result<Self, CannotSplice> {
        let codes = canonical_codes(spec)?;
        let mut fast = Box::new([0_u16; 1 << LOOKAHEAD]);
        let mut skip = Box::new([0_u16; 1 << SKIP_LOOKAHEAD]);
        let mut max_code = [-1_i32; 17];
        let mut offset = [0_i32; 17];
        for (index, (&(code, length), &symbol)) in (0_i32..).zip(codes.iter().zip(&spec.values)) {
            let (Ok(code_i), Ok(slot)) = (i32::try_from(code), usize::try_from(length)) else {
                return Err(CannotSplice::Malformed("Huffman code"));
            };
            if let (Some(max), Some(off)) = (max_code.get_mut(slot), offset.get_mut(slot)) {
                if *max < 0 {
                    *off = index - code_i;
                }
                *max = code_i;
            }
            if length <= LOOKAHEAD {
                let shift = LOOKAHEAD - length;
                let first = usize::try_from(code << shift).unwrap_or(usize::MAX);
                let entry = u16::try_from(length << 8).unwrap_or(0) | u16::from(symbol);
                if let Some(run) = fast.get_mut(first..first.saturating_add(1 << shift)) {
                    run.fill(entry);
                }
            }
            if length <= SKIP_LOOKAHEAD {
                let shift = SKIP_LOOKAHEAD - length;
                let first = usize::try_from(code << shift).unwrap_or(usize::MAX);
                if let Some(run) = skip.get_mut(first..first.saturating_add(1 << shift)) {
                    run.fill(skip_entry(symbol, length));
                }
            }
        }
        Ok(Self {
            fast: Arc::from(fast),
            skip: Arc::from(skip),
            pairs: None,
            max_code,
            offset,
            values: Arc::from(spec.values.as_slice()),
        })
    }

    /// The symbol whose code starts `ahead` (the next 32 bits), and the code's length.
    ///
    /// # Errors
    /// [`CannotSplice::BadEntropy`] for bits that are no code of the table.
    #[inline]
    pub fn lookup(&self, ahead: u32) -> Result<(u8, u32), CannotSplice> {
        let entry = self
            .fast
            .get(usize::try_from(ahead >> (32 - LOOKAHEAD)).unwrap_or(0))
            .copied()
            .unwrap_or(0);
        if entry != 0 {
            let [length, symbol] = entry.to_be_bytes();
            return Ok((symbol, u32::from(length)));
        }
        self.lookup_long(ahead)
    }

    /// For an AC table: the bits to skip past the coefficient whose code starts `ahead`,
    /// and how far it advances in the block ([`END_OF_BLOCK`] for the end); `None` when
    /// [`Self::lookup`] must decide.
    #[inline]
    pub fn skip_ac(&self, ahead: u32) -> Option<(u32, u8)> {
        let entry = self
            .skip
            .get(usize::try_from(ahead >> (32 - SKIP_LOOKAHEAD)).unwrap_or(0))
            .copied()
            .unwrap_or(0);
        let [bits, advance] = entry.to_be_bytes();
        (entry != 0).then_some((u32::from(bits), advance))
    }

    /// This decoder with the table of [`Self::skip_ac_pair`], for reading past AC
    /// coefficients two codes at a time.
    pub fn with_pairs(mut self) -> Self {
        let mut pairs = Box::new([0_u32; 1 << PAIR_LOOKAHEAD]);
        let window = |bits: u32| bits << (32 - PAIR_LOOKAHEAD);
        for (index, entry) in (0_u32..).zip(pairs.iter_mut()) {
            let ahead = window(index);
            let Some((first, advance)) = self.skip_ac(ahead) else {
                continue;
            };
            if first > PAIR_LOOKAHEAD {
                continue;
            }
            let (mut both, mut total) = (first, u32::from(advance));
            if advance != END_OF_BLOCK
                && let Some((second, next)) = self.skip_ac(ahead << first)
                && first + second <= PAIR_LOOKAHEAD
            {
                both += second;
                total += u32::from(next);
            }
            *entry = first | both << 8 | u32::from(advance) << 16 | total.min(255) << 24;
        }
        self.pairs = Some(Arc::from(pairs));
        self
    }

    /// For an AC table with pairs: the bits and advance of the first code whose code starts
    /// `ahead`, and of it and the next together; `None` when [`Self::skip_ac`] must decide.
    #[inline(always)]
    pub fn skip_ac_pair(&self, ahead: u32) -> Option<[u8; 4]> {
        let entry = self
            .pairs
            .as_ref()?
            .get(usize::try_from(ahead >> (32 - PAIR_LOOKAHEAD)).unwrap_or(0))
            .copied()
            .unwrap_or(0);
        (entry != 0).then_some(entry.to_le_bytes())
    }

    /// [`Self::lookup`] for codes longer than [`LOOKAHEAD`] bits (ITU T.81 F.2.2.3).
    #[cold]
    fn lookup_long(&self, ahead: u32) -> Result<(u8, u32), CannotSplice> {
        for length in LOOKAHEAD + 1..=16 {
            let code = i64::from(ahead >> (32 - length));
            let slot = usize::try_from(length).unwrap_or(0);
            let max = i64::from(self.max_code.get(slot).copied().unwrap_or(-1));
            if code <= max {
                let offset = i64::from(self.offset.get(slot).copied().unwrap_or(0));
                return usize::try_from(code + offset)
                    .ok()
                    .and_then(|i| self.values.get(i).copied())
                    .map(|symbol| (symbol, length))
                    .ok_or(CannotSplice::BadEntropy);
            }
        }
        Err(CannotSplice::BadEntropy)
    }
}

/// The [`Decoder::skip_ac`] entry of AC `symbol` with a code of `length` bits.
fn skip_entry(symbol: u8, length: u32) -> u16 {
    let (run, size) = (symbol >> 4, symbol & 15);
    let advance = match (run, size) {
        (_, 11..) => return 0,
        (15, 0) => 16,
        (_, 0) => END_OF_BLOCK,
        (run, _) => run + 1,
    };
    let bits = u16::try_from(length).unwrap_or(0) + u16::from(size);
    bits << 8 | u16::from(advance)
}

/// The code of each symbol of one table, for writing.
#[derive(Debug, Clone)]
pub struct Encoder {
    /// By symbol: `length << 16 | code`, or 0 when the table has no code for it.
    codes: Arc<[u32; 256]>,
}

impl Encoder {
    /// The encoder of `spec`.
    ///
    /// # Errors
    /// [`CannotSplice::Malformed`] for an impossible table.
    pub fn new(spec: &HuffmanSpec) -> Result<Self, CannotSplice> {
        let mut codes = Box::new([0_u32; 256]);
        for (&(code, length), &symbol) in canonical_codes(spec)?.iter().zip(&spec.values) {
            if let Some(slot) = codes.get_mut(usize::from(symbol)) {
                // A symbol listed twice keeps its first (shorter) code, as decoders find it.
                if *slot == 0 {
                    *slot = length << 16 | code;
                }
            }
        }
        Ok(Self {
            codes: Arc::from(codes),
        })
    }

    /// The code of `symbol` as (code, length in bits).
    ///
    /// # Errors
    /// [`CannotSplice::MissingCode`] when the table has none: the file's encoder left out a
    /// symbol its own data did not use.
    #[inline]
    pub fn code(&self, symbol: u8) -> Result<(u32, u32), CannotSplice> {
        match self.codes.get(usize::from(symbol)).copied().unwrap_or(0) {
            0 => Err(CannotSplice::MissingCode),
            packed => Ok((packed & 0xFFFF, packed >> 16)),
        }
    }
}

/// The decoders (the AC one with [`Decoder::with_pairs`]) and encoders of a DC and an AC
/// table.
#[derive(Debug, Clone)]
pub struct Coders {
    /// Reads DC differences.
    pub dc_decoder: Decoder,
    /// Reads AC coefficients, and past them two codes at a time.
    pub ac_decoder: Decoder,
    /// Writes DC differences.
    pub dc_encoder: Encoder,
    /// Writes AC coefficients.
    pub ac_encoder: Encoder,
}

impl Coders {
    /// The coders of the DC table `dc` and the AC table `ac`, built anew.
    fn build(dc: &HuffmanSpec, ac: &HuffmanSpec) -> Result<Self, CannotSplice> {
        Ok(Self {
            dc_decoder: Decoder::new(dc)?,
            ac_decoder: Decoder::new(ac)?.with_pairs(),
            dc_encoder: Encoder::new(dc)?,
            ac_encoder: Encoder::new(ac)?,
        })
    }
}

/// How many table pairs [`coders`] remembers.
const RECENT_CODERS: usize = 8;

/// The coders of the table pairs used last, most recent first, at most `capacity` of them.
/// Clones share the lookup tables, so a hit copies no table.
struct Recent {
    entries: Vec<(HuffmanSpec, HuffmanSpec, Coders)>,
    capacity: usize,
}

impl Recent {
    const fn new(capacity: usize) -> Self {
        Self {
            entries: Vec::new(),
            capacity,
        }
    }

    /// The coders of (`dc`, `ac`): the remembered ones, or built and remembered, the least
    /// recently used pair forgotten past the capacity.
    fn get(&mut self, dc: &HuffmanSpec, ac: &HuffmanSpec) -> Result<Coders, CannotSplice> {
        let entry = match self.entries.iter().position(|(d, a, _)| d == dc && a == ac) {
            Some(i) => self.entries.remove(i),
            None => (dc.clone(), ac.clone(), Coders::build(dc, ac)?),
        };
        let coders = entry.2.clone();
        self.entries.insert(0, entry);
        self.entries.truncate(self.capacity);
        Ok(coders)
    }
}

/// The process's [`Recent`] coders. A camera writes every frame with the same tables, and
/// building an AC decoder's lookup tables costs about what splicing a tenth of a 1280×720
/// frame does.
static RECENT: Mutex<Recent> = Mutex::new(Recent::new(RECENT_CODERS));

/// The coders of the DC table `dc` and the AC table `ac`: built, or the ones built for the
/// same tables by a recent call (at most [`RECENT_CODERS`] pairs are kept).
///
/// # Errors
/// [`CannotSplice::Malformed`] for a table that is no prefix code.
pub fn coders(dc: &HuffmanSpec, ac: &HuffmanSpec) -> Result<Coders, CannotSplice> {
    RECENT
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .get(dc, ac)
}

/// ITU T.81 Annex K.3, table K.4: the typical chrominance DC table.
pub fn chroma_dc() -> HuffmanSpec {
    HuffmanSpec {
        counts: [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0],
        values: (0..=11).collect(),
    }
}

/// ITU T.81 Annex K.3, table K.6: the typical chrominance AC table.
pub fn chroma_ac() -> HuffmanSpec {
    HuffmanSpec {
        counts: [0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77],
        values: vec![
            0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07,
            0x61, 0x71, 0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09,
            0x23, 0x33, 0x52, 0xf0, 0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25,
            0xf1, 0x17, 0x18, 0x19, 0x1a, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38,
            0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56,
            0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74,
            0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x82, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89,
            0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5,
            0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba,
            0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6,
            0xd7, 0xd8, 0xd9, 0xda, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf2,
            0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether `a` and `b` share their lookup tables (one was cloned from the other).
    fn shared(a: &Coders, b: &Coders) -> bool {
        Arc::ptr_eq(&a.ac_decoder.skip, &b.ac_decoder.skip)
            && Arc::ptr_eq(&a.dc_decoder.fast, &b.dc_decoder.fast)
            && Arc::ptr_eq(&a.ac_encoder.codes, &b.ac_encoder.codes)
    }

    #[test]
    fn recent_coders_are_shared_until_forgotten() {
        let (dc, ac) = (chroma_dc(), chroma_ac());
        let mut recent = Recent::new(2);
        let first = recent.get(&dc, &ac).expect("a prefix code");
        assert!(shared(&first, &recent.get(&dc, &ac).expect("remembered")));
        let other = recent.get(&ac, &dc).expect("a prefix code");
        assert!(!shared(&first, &other), "other tables, other coders");
        // (dc, ac) was used before (ac, dc): a third pair makes it the one forgotten.
        recent.get(&dc, &dc).expect("a prefix code");
        assert!(shared(&other, &recent.get(&ac, &dc).expect("remembered")));
        assert!(!shared(&first, &recent.get(&dc, &ac).expect("built again")));
    }
}
