//! rxing binarisers whose bit matrix is made at once ([`Precomputed`]): rxing's hybrid
//! (local) and global-histogram algorithms, reimplemented bit for bit but thresholding a
//! row and packing a word at a time where rxing sets one bit at a time
//! ([`super::hybrid_binarizer::local_binarizer`],
//! [`super::global_binarizer::global_binarizer`]). Row queries (1-D readers) go to rxing's
//! global-histogram binariser.

use rxing::common::{BitArray, BitMatrix, GlobalHistogramBinarizer, LineOrientation};
use rxing::{Binarizer, LuminanceSource};
use std::borrow::Cow;

/// A bit matrix of a grey image (`pixels`, `width`, `height`); `None` where the algorithm
/// gives none (too little contrast, an empty image).
pub(crate) type Threshold = fn(&[u8], usize, usize) -> Option<BitMatrix>;

/// A binariser whose bit matrix was made by a [`Threshold`] when it was built.
pub(crate) struct Precomputed<LS: LuminanceSource> {
    ghb: GlobalHistogramBinarizer<LS>,
    matrix: Option<BitMatrix>,
    threshold: Threshold,
}

impl<LS: LuminanceSource> Precomputed<LS> {
    /// Binarises `source` with `threshold` at once.
    pub(crate) fn new(source: LS, threshold: Threshold) -> Self {
        let (width, height) = (source.get_width(), source.get_height());
        let matrix = threshold(&source.get_matrix(), width, height);
        Self {
            ghb: GlobalHistogramBinarizer::new(source),
            matrix,
            threshold,
        }
    }
}

impl<LS: LuminanceSource> Binarizer for Precomputed<LS> {
    type Source = LS;

    fn get_luminance_source(&self) -> &LS {
        self.ghb.get_luminance_source()
    }

    fn get_black_row(&self, y: usize) -> rxing::common::Result<Cow<'_, BitArray>> {
        self.ghb.get_black_row(y)
    }

    fn get_black_row_from_matrix(&self, y: usize) -> rxing::common::Result<Cow<'_, BitArray>> {
        match (&self.matrix, u32::try_from(y)) {
            (Some(m), Ok(y)) => Ok(Cow::Owned(m.getRow(y))),
            _ => self.ghb.get_black_row_from_matrix(y),
        }
    }

    fn get_black_matrix(&self) -> rxing::common::Result<&BitMatrix> {
        match &self.matrix {
            Some(m) => Ok(m),
            None => self.ghb.get_black_matrix(),
        }
    }

    fn get_black_line(
        &self,
        l: usize,
        lt: LineOrientation,
    ) -> rxing::common::Result<Cow<'_, BitArray>> {
        self.ghb.get_black_line(l, lt)
    }

    fn create_binarizer(&self, source: LS) -> Self {
        Self::new(source, self.threshold)
    }

    fn get_width(&self) -> usize {
        self.ghb.get_width()
    }

    fn get_height(&self) -> usize {
        self.ghb.get_height()
    }
}

/// Bits per word of rxing's bit arrays.
pub(crate) const WORD_BITS: usize = usize::BITS as usize;

/// A word of 0/1 bytes as bits (bit k = byte k), eight bytes per multiplication.
pub(crate) fn pack_flags(flags: &[u8]) -> usize {
    flags
        .chunks_exact(8)
        .enumerate()
        .fold(0usize, |acc, (k, eight)| {
            let mut le = [0u8; 8];
            le.copy_from_slice(eight);
            let byte = u64::from_le_bytes(le).wrapping_mul(0x0102_0408_1020_4080) >> 56;
            acc | (usize::try_from(byte).unwrap_or(0) << (8 * k))
        })
}
