//! Draw on a JPEG without re-encoding it: only the 8×8 blocks an overlay touches are
//! encoded anew; every other block keeps the file's bits, and every header (EXIF, ICC, the
//! quantization and Huffman tables) its bytes.
//!
//! ```
//! use jpeg_overlay::{CannotSplice, Jpeg};
//!
//! /// `file` with a magenta bar drawn across pixels 10..30 of rows 12 and 13; `Err` when
//! /// the file cannot be spliced (the caller then draws on the decoded frame instead).
//! fn with_bar(file: &[u8]) -> Result<Vec<u8>, CannotSplice> {
//!     let jpeg = Jpeg::parse(file)?;
//!     let mut drawing = jpeg.canvas();
//!     for y in 12..14 {
//!         drawing.put_row(10, 30, y, [255, 0, 255]);
//!     }
//!     Ok(jpeg.splice(&drawing)?.bytes)
//! }
//! # let mut file = Vec::new();
//! # jpeg_encoder::Encoder::new(&mut file, 90)
//! #     .encode(&[128; 64 * 48 * 3], 64, 48, jpeg_encoder::ColorType::Rgb)
//! #     .map_err(|e| e.to_string())?;
//! # assert_ne!(with_bar(&file)?, file);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Decoding a whole frame in colour and encoding it again costs several times what reading
//! a QR code in it does, and changes every pixel the client sent (the qrpose repository's
//! docs/service.md, The annotated image, gives the measured cost). An overlay covers a few
//! percent of the frame, so instead:
//!
//! 1. [`Jpeg::parse`] reads the headers and refuses what cannot be spliced exactly (below).
//! 2. The overlay is drawn onto a [`Drawing`] (from [`Jpeg::canvas`]), not a raster: a
//!    canvas that records, per MCU drawn into, the last colour written on each pixel.
//! 3. [`Jpeg::splice`] Huffman-decodes the scan MCU by MCU (table lookups of 9 bits per
//!    code, or 11 and 12 bits per code with its value, two codes at a time, where
//!    coefficients are only read past), up to and including the MCU after the last drawn
//!    one of each restart interval, keeping the DC predictors. Each MCU holding a drawn
//!    pixel is decoded to coefficients; each of its blocks holding one is dequantized,
//!    inverse-DCT'd (float, Arai-Agui-Nakajima), drawn on in YCbCr (a write sets a pixel's
//!    Y, Cb, Cr; a subsampled chroma sample takes the mean over the pixels it covers, a
//!    box filter), forward-DCT'd and quantized with the file's own tables; blocks drawn
//!    over entirely skip the inverse DCT. The MCU is Huffman-encoded with the file's own
//!    tables, and so is the MCU after each run of drawn MCUs (its DC differences change
//!    with its predecessor's DC; its coefficients do not).
//! 4. The output is the file's bytes up to the byte holding the first changed bit, the
//!    re-encoded MCUs with the MCUs between them, then the rest of the restart interval
//!    (the whole scan without restart markers). A run of 8 or more MCUs between re-encoded
//!    ones, and the rest of the interval, keep their bytes when ZRL codes (16 zeros each,
//!    put before end-of-block codes: no coefficient changes) make the new bits before them
//!    a whole number of bytes longer or shorter than the old; otherwise they are copied
//!    with a bit shift (stuffing undone on reading and done again on writing). The
//!    interval is padded with 1 bits and followed by its RST marker. Intervals without a
//!    drawn MCU are copied byte for byte; the file's trailer (EOI, anything after it) ends
//!    the output, and an EOI when the file had none. All headers (APPn with EXIF and ICC,
//!    DQT, DHT, SOF, DRI, SOS) stay byte-identical.
//!
//! A grey (one-component) frame cannot hold colours, so it becomes YCbCr 4:4:4 with one
//! scan per component: its SOF is rewritten for three components, a DQT (the typical
//! chrominance table of ITU T.81 Annex K, scaled like the file's luminance table) and a
//! DHT (the typical chrominance Huffman tables) go before its SOS in slots luma does not
//! use, its luma scan is spliced as above, and two chroma scans follow it: zero blocks
//! (half a byte each) except where the overlay is drawn. Other headers and the luma scan's
//! SOS stay byte-identical, and decoders give the photo's pixels exactly (zero chroma is
//! neutral). libjpeg, zune-jpeg and the `image` crate read such files; a grey frame with
//! restart markers is refused, because zune-jpeg 0.5 misreads restart markers in JPEGs of
//! one scan per component.
//!
//! Spliced: baseline or extended sequential Huffman JPEG (SOF0, SOF1), 8-bit samples, one
//! component (grey) or three that are YCbCr (JFIF, or no Adobe APP14 marker, or its
//! transform 1; not component ids `R`, `G`, `B`), one scan holding every component,
//! sampling factors 1-2 (4:2:0, 4:2:2, 4:4:0, 4:4:4), with or without a restart interval.
//! Everything else returns a [`CannotSplice`], and the caller decodes, draws and encodes
//! the whole frame instead: progressive, arithmetic-coded, lossless or hierarchical JPEG,
//! 12-bit samples, CMYK or YCCK (four components), RGB (Adobe transform 0 or ids `R`, `G`,
//! `B`), several scans, a DNL marker, a grey frame with restart markers, a Huffman table
//! lacking a code a re-encoded block needs (optimized tables leave out unused symbols),
//! more than 255 colours drawn, and data that does not decode. Nothing here indexes
//! untrusted bytes in a way that can panic: a malformed file is refused, never trusted.

#![warn(missing_docs)]

mod align;
mod block;
mod coding;
mod draw;
mod entropy;
mod huffman;
mod layout;
mod markers;
mod scan;

pub use draw::Drawing;
use entropy::Entropy;
use layout::Layout;
use markers::Headers;

/// Why a JPEG cannot be spliced; the caller re-encodes the whole frame instead.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum CannotSplice {
    /// Not a JPEG this crate can read: broken headers, misplaced markers.
    #[error("malformed JPEG: {0}")]
    Malformed(&'static str),
    /// Progressive JPEG (SOF2).
    #[error("progressive JPEG")]
    Progressive,
    /// Arithmetic coding (SOF9-SOF15, DAC).
    #[error("arithmetic coding")]
    Arithmetic,
    /// Lossless, hierarchical or reserved coding (SOF3, SOF5-SOF8).
    #[error("coding process SOF{0}")]
    Process(u8),
    /// Samples of other than 8 bits.
    #[error("{0}-bit samples")]
    Precision(u8),
    /// Neither one component nor three (CMYK, YCCK).
    #[error("{0} components")]
    Components(u8),
    /// Three components that are RGB, or a grey frame whose Adobe marker would make its
    /// three-component version RGB.
    #[error("colour that is not YCbCr")]
    NotYcbcr,
    /// Sampling factors outside 1-2, or more than 10 blocks per MCU.
    #[error("unsupported sampling factors")]
    Sampling,
    /// More than one scan.
    #[error("more than one scan")]
    MultipleScans,
    /// The height is given by a DNL marker after the scan.
    #[error("a DNL marker")]
    Dnl,
    /// A re-encoded block needs a Huffman code the file's table does not have.
    #[error("the Huffman tables lack a code the drawing needs")]
    MissingCode,
    /// The entropy-coded data is truncated or does not decode.
    #[error("entropy-coded data that does not decode")]
    BadEntropy,
    /// A grey frame with a restart interval: its colour version's chroma scans would carry
    /// restart markers too, and zune-jpeg 0.5 (the `image` crate's decoder) misreads
    /// restart markers in JPEGs of one scan per component.
    #[error("a grey frame with restart markers")]
    GreyWithRestarts,
    /// More than 255 colours drawn.
    #[error("more than 255 colours drawn")]
    Colours,
    /// The drawing is not of this frame's grid.
    #[error("the drawing's size is not the frame's")]
    SizeMismatch,
}

/// A JPEG whose headers allow splicing.
#[derive(Debug, Clone)]
pub struct Jpeg<'a> {
    file: &'a [u8],
    headers: Headers,
    layout: Layout,
}

/// A spliced JPEG and what it took.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Spliced {
    /// The JPEG.
    pub bytes: Vec<u8>,
    /// MCUs drawn into.
    pub drawn_mcus: usize,
    /// MCUs encoded anew: those drawn into, and the one after each run of them.
    pub reencoded_mcus: usize,
    /// How many leading bytes are the file's own (headers and entropy-coded data up to the
    /// byte holding the first changed bit).
    pub verbatim_prefix: usize,
    /// How many leading bytes of the file's scan data are kept as they were (a grey
    /// frame's headers change, its luma scan's data does not).
    pub verbatim_scan_bytes: usize,
    /// Restart intervals (the whole scan without them) whose rest after the last
    /// re-encoded MCU kept its bytes.
    pub aligned_tails: usize,
    /// Restart intervals whose rest was copied shifted bit by bit.
    pub shifted_tails: usize,
    /// Runs of MCUs between re-encoded ones that kept their bytes (ZRL codes in the
    /// re-encoded MCUs before each align it, as for the rest of an interval).
    pub aligned_runs: usize,
}

impl<'a> Jpeg<'a> {
    /// Reads the headers of `file`.
    ///
    /// # Errors
    /// [`CannotSplice`] when the file is no JPEG this crate splices exactly.
    pub fn parse(file: &'a [u8]) -> Result<Self, CannotSplice> {
        let headers = markers::parse(file)?;
        if headers.components.len() == 1 && headers.restart_interval > 0 {
            return Err(CannotSplice::GreyWithRestarts);
        }
        let layout = Layout::new(&headers)?;
        Ok(Self {
            file,
            headers,
            layout,
        })
    }

    /// Width, px.
    pub fn width_px(&self) -> usize {
        usize::from(self.headers.width)
    }

    /// Height, px.
    pub fn height_px(&self) -> usize {
        usize::from(self.headers.height)
    }

    /// The size of an MCU, px: the unit of re-encoding.
    pub fn mcu_size_px(&self) -> (usize, usize) {
        self.layout.grid.mcu_px
    }

    /// An empty canvas of the frame's size, recording by MCU what is drawn on it, for
    /// [`Self::splice`].
    pub fn canvas(&self) -> Drawing {
        Drawing::new(self.layout.grid)
    }

    /// Whether the frame is grey (and its spliced version YCbCr 4:4:4).
    pub fn is_grey(&self) -> bool {
        self.headers.components.len() == 1
    }

    /// The JPEG with `drawing` (from [`Self::canvas`]) drawn into it.
    ///
    /// # Errors
    /// [`CannotSplice`] for a drawing of another frame or in over 255 colours, entropy-coded data that
    /// does not decode, a second scan or DNL after it, or a Huffman code the drawing needs
    /// and the file's tables lack.
    pub fn splice(&self, drawing: &Drawing) -> Result<Spliced, CannotSplice> {
        self.splice_with(drawing, true)
    }

    /// [`Self::splice`]; with `align` false the rest of an interval after its re-encoded
    /// MCUs is always shifted bit by bit, never kept byte for byte with ZRL codes.
    fn splice_with(&self, drawing: &Drawing, align: bool) -> Result<Spliced, CannotSplice> {
        if drawing.grid() != self.layout.grid {
            return Err(CannotSplice::SizeMismatch);
        }
        let touched = drawing.touched()?;
        if touched.is_empty() {
            return Ok(Spliced {
                bytes: self.file.to_vec(),
                drawn_mcus: 0,
                reencoded_mcus: 0,
                verbatim_prefix: self.file.len(),
                verbatim_scan_bytes: self.file.len().saturating_sub(self.headers.sos.end),
                aligned_tails: 0,
                shifted_tails: 0,
                aligned_runs: 0,
            });
        }
        let restarts = self.headers.restart_interval > 0;
        let entropy = Entropy::split(self.file, self.headers.sos.end, restarts)?;
        let ends_in_eoi = markers::check_trailer(self.file, entropy.end)?;
        let headers = self.output_headers();
        let headers_len = headers.len();
        let grey_prefix = self.headers.sof.start;
        let (mut bytes, report) = scan::rewrite(
            self.file,
            &self.layout,
            &entropy,
            usize::from(self.headers.restart_interval),
            drawing,
            headers,
            align,
        )?;
        if !ends_in_eoi {
            bytes.extend_from_slice(&[0xFF, 0xD9]);
        }
        Ok(Spliced {
            bytes,
            drawn_mcus: touched.len(),
            reencoded_mcus: report.reencoded_mcus,
            verbatim_prefix: if self.is_grey() {
                grey_prefix
            } else {
                report.verbatim_prefix
            },
            verbatim_scan_bytes: report.verbatim_prefix.saturating_sub(headers_len),
            aligned_tails: report.aligned_tails,
            shifted_tails: report.shifted_tails,
            aligned_runs: report.aligned_runs,
        })
    }

    /// The headers of the output, up to the first entropy-coded byte: the file's, or for a
    /// grey frame the file's with a three-component SOF and, before the SOS, the chroma
    /// quantization and Huffman tables. With room for the whole output, so that it is
    /// seldom moved as it grows.
    fn output_headers(&self) -> Vec<u8> {
        let file = self.file;
        let (sof, sos) = (&self.headers.sof, &self.headers.sos);
        // The file, half as much again for re-encoded blocks (and a grey frame's chroma
        // scans, under a byte per MCU), and the added headers.
        let capacity = file.len() + file.len() / 2 + self.layout.grid.total() + 1024;
        let mut out = Vec::with_capacity(capacity);
        let (Some(chroma), Some(y)) = (self.layout.chroma, self.headers.components.first()) else {
            out.extend_from_slice(file.get(..sos.end).unwrap_or_default());
            return out;
        };
        out.extend_from_slice(file.get(..sof.start).unwrap_or_default());
        let code = file.get(sof.start + 1).copied().unwrap_or(0xC0);
        let [h1, h0] = self.headers.height.to_be_bytes();
        let [w1, w0] = self.headers.width.to_be_bytes();
        out.extend_from_slice(&[0xFF, code, 0, 17, 8, h1, h0, w1, w0, 3]);
        out.extend_from_slice(&[y.id, 0x11, y.quant]);
        for id in chroma.ids {
            out.extend_from_slice(&[id, 0x11, chroma.quant.0]);
        }
        out.extend_from_slice(file.get(sof.end..sos.start).unwrap_or_default());
        out.extend_from_slice(&[0xFF, 0xDB, 0, 67, chroma.quant.0]);
        for &q in &chroma.quant.1 {
            out.push(u8::try_from(q).unwrap_or(u8::MAX));
        }
        let (dc, ac) = (huffman::chroma_dc(), huffman::chroma_ac());
        let length = 2 + 2 * 17 + dc.values.len() + ac.values.len();
        out.extend_from_slice(&[0xFF, 0xC4]);
        out.extend_from_slice(&u16::try_from(length).unwrap_or(0).to_be_bytes());
        out.push(chroma.tables.0);
        out.extend_from_slice(&dc.counts);
        out.extend_from_slice(&dc.values);
        out.push(0x10 | chroma.tables.1);
        out.extend_from_slice(&ac.counts);
        out.extend_from_slice(&ac.values);
        out.extend_from_slice(file.get(sos.clone()).unwrap_or_default());
        out
    }
}

#[cfg(test)]
mod tests;

/// The README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
