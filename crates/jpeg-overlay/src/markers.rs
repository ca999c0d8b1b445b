//! The JPEG's marker segments up to its scan: what the splice needs from the headers, and
//! the refusal of everything it cannot re-encode exactly.

use super::CannotSplice;
use super::huffman::HuffmanSpec;
use std::ops::Range;

/// A frame component (SOF).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Component {
    /// Component identifier.
    pub id: u8,
    /// Horizontal sampling factor, 1-2.
    pub h: u8,
    /// Vertical sampling factor, 1-2.
    pub v: u8,
    /// Quantization table, 0-3.
    pub quant: u8,
}

/// A component of the scan (SOS).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScanComponent {
    /// Index in [`Headers::components`].
    pub component: usize,
    /// DC Huffman table, 0-3.
    pub dc: u8,
    /// AC Huffman table, 0-3.
    pub ac: u8,
}

/// What the headers say, as of the scan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Headers {
    /// Frame width, px.
    pub width: u16,
    /// Frame height, px.
    pub height: u16,
    /// The frame's components, in SOF order (Y, Cb, Cr).
    pub components: Vec<Component>,
    /// Quantization tables by id, in zigzag order.
    pub quant: [Option<[u16; 64]>; 4],
    /// DC Huffman tables by id.
    pub dc: [Option<HuffmanSpec>; 4],
    /// AC Huffman tables by id.
    pub ac: [Option<HuffmanSpec>; 4],
    /// MCUs per restart interval; 0 for none.
    pub restart_interval: u16,
    /// The scan's components, in scan order.
    pub scan: Vec<ScanComponent>,
    /// The SOF segment in the file, marker included.
    pub sof: Range<usize>,
    /// The SOS segment in the file, marker included; its end is the first entropy byte.
    pub sos: Range<usize>,
}

/// Reads the headers of `file` up to the end of its first SOS segment.
///
/// # Errors
/// [`CannotSplice`] for what the splice cannot re-encode exactly, or malformed headers.
pub fn parse(file: &[u8]) -> Result<Headers, CannotSplice> {
    if file.get(..2) != Some(&[0xFF, 0xD8]) {
        return Err(CannotSplice::Malformed("no SOI marker"));
    }
    let mut state = State::default();
    let mut at = 2;
    loop {
        let (code, segment_at) = next_marker(file, at)?;
        match code {
            0x01 | 0xD0..=0xD7 => {
                at = segment_at;
                continue;
            }
            0xD8 | 0xD9 => return Err(CannotSplice::Malformed("SOI or EOI before the scan")),
            _ => {}
        }
        let length = usize::from(u16::from_be_bytes(
            bytes(file, segment_at, 2)?
                .try_into()
                .map_err(|_| CannotSplice::Malformed("truncated"))?,
        ));
        if length < 2 {
            return Err(CannotSplice::Malformed("segment length"));
        }
        let body = bytes(file, segment_at + 2, length - 2)?;
        let segment = segment_at - 2..segment_at + length;
        match code {
            0xC0 | 0xC1 => state.frame(body, segment.clone(), code == 0xC1)?,
            0xC2 => return Err(CannotSplice::Progressive),
            0xC9..=0xCF => return Err(CannotSplice::Arithmetic),
            0xC3 | 0xC5..=0xC8 => return Err(CannotSplice::Process(code - 0xC0)),
            0xC4 => state.huffman(body)?,
            0xDB => state.quantization(body)?,
            0xDC => return Err(CannotSplice::Dnl),
            0xDD => {
                let &[high, low] = body else {
                    return Err(CannotSplice::Malformed("DRI length"));
                };
                state.restart_interval = u16::from_be_bytes([high, low]);
            }
            0xEE => state.adobe(body),
            0xDA => return state.scan(body, segment),
            _ => {}
        }
        at = segment.end;
    }
}

/// The code of the marker at or after `at` (fill bytes skipped) and where its segment's
/// length field starts.
fn next_marker(file: &[u8], at: usize) -> Result<(u8, usize), CannotSplice> {
    if file.get(at) != Some(&0xFF) {
        return Err(CannotSplice::Malformed("no marker where one must be"));
    }
    let mut code_at = at + 1;
    while file.get(code_at) == Some(&0xFF) {
        code_at += 1;
    }
    match file.get(code_at) {
        Some(0) | None => Err(CannotSplice::Malformed("no marker where one must be")),
        Some(&code) => Ok((code, code_at + 1)),
    }
}

fn bytes(file: &[u8], at: usize, n: usize) -> Result<&[u8], CannotSplice> {
    file.get(at..at + n)
        .ok_or(CannotSplice::Malformed("truncated headers"))
}

/// What the frame header says.
#[derive(Debug)]
struct Frame {
    width: u16,
    height: u16,
    components: Vec<Component>,
    /// The SOF segment in the file.
    segment: Range<usize>,
    /// SOF1: Huffman tables 0-3 allowed, not 0-1.
    extended: bool,
}

/// The tables and frame as far as the headers have been read.
#[derive(Debug, Default)]
struct State {
    frame: Option<Frame>,
    quant: [Option<[u16; 64]>; 4],
    dc: [Option<HuffmanSpec>; 4],
    ac: [Option<HuffmanSpec>; 4],
    restart_interval: u16,
    adobe_transform: Option<u8>,
}

impl State {
    fn frame(
        &mut self,
        body: &[u8],
        segment: Range<usize>,
        extended: bool,
    ) -> Result<(), CannotSplice> {
        if self.frame.is_some() {
            return Err(CannotSplice::Malformed("two frame headers"));
        }
        let &[precision, h1, h0, w1, w0, count, ref rest @ ..] = body else {
            return Err(CannotSplice::Malformed("SOF length"));
        };
        if precision != 8 {
            return Err(CannotSplice::Precision(precision));
        }
        let (height, width) = (u16::from_be_bytes([h1, h0]), u16::from_be_bytes([w1, w0]));
        if height == 0 {
            return Err(CannotSplice::Dnl);
        }
        if width == 0 || rest.len() != 3 * usize::from(count) {
            return Err(CannotSplice::Malformed("SOF size"));
        }
        if count != 1 && count != 3 {
            return Err(CannotSplice::Components(count));
        }
        let components: Vec<Component> = rest
            .chunks_exact(3)
            .map(|c| match *c {
                [id, factors, quant] => Component {
                    id,
                    h: factors >> 4,
                    v: factors & 15,
                    quant,
                },
                _ => Component {
                    id: 0,
                    h: 0,
                    v: 0,
                    quant: 0,
                },
            })
            .collect();
        if components
            .iter()
            .any(|c| !(1..=2).contains(&c.h) || !(1..=2).contains(&c.v))
        {
            return Err(CannotSplice::Sampling);
        }
        let blocks: u8 = components.iter().map(|c| c.h * c.v).sum();
        if count > 1 && blocks > 10 {
            return Err(CannotSplice::Sampling);
        }
        if components.iter().any(|c| c.quant > 3) {
            return Err(CannotSplice::Malformed("quantization table id"));
        }
        for (i, a) in components.iter().enumerate() {
            if components.iter().skip(i + 1).any(|b| b.id == a.id) {
                return Err(CannotSplice::Malformed("two components with one id"));
            }
        }
        self.frame = Some(Frame {
            width,
            height,
            components,
            segment,
            extended,
        });
        Ok(())
    }

    fn huffman(&mut self, mut body: &[u8]) -> Result<(), CannotSplice> {
        while let [class_id, ref rest @ ..] = *body {
            let counts: [u8; 16] = rest
                .get(..16)
                .and_then(|c| c.try_into().ok())
                .ok_or(CannotSplice::Malformed("DHT length"))?;
            let n: usize = counts.iter().map(|&c| usize::from(c)).sum();
            let values = rest
                .get(16..16 + n)
                .ok_or(CannotSplice::Malformed("DHT length"))?;
            if n > 256 {
                return Err(CannotSplice::Malformed("DHT size"));
            }
            let spec = HuffmanSpec {
                counts,
                values: values.to_vec(),
            };
            let tables = match class_id >> 4 {
                0 => &mut self.dc,
                1 => &mut self.ac,
                _ => return Err(CannotSplice::Malformed("DHT class")),
            };
            *tables
                .get_mut(usize::from(class_id & 15))
                .ok_or(CannotSplice::Malformed("DHT id"))? = Some(spec);
            body = rest.get(16 + n..).unwrap_or_default();
        }
        Ok(())
    }

    fn quantization(&mut self, mut body: &[u8]) -> Result<(), CannotSplice> {
        while let [precision_id, ref rest @ ..] = *body {
            let wide = match precision_id >> 4 {
                0 => false,
                1 => true,
                _ => return Err(CannotSplice::Malformed("DQT precision")),
            };
            let size = if wide { 128 } else { 64 };
            let values = rest
                .get(..size)
                .ok_or(CannotSplice::Malformed("DQT length"))?;
            let mut table = [0_u16; 64];
            if wide {
                for (q, pair) in table.iter_mut().zip(values.chunks_exact(2)) {
                    *q = u16::from_be_bytes([
                        pair.first().copied().unwrap_or(0),
                        pair.get(1).copied().unwrap_or(0),
                    ]);
                }
            } else {
                for (q, &v) in table.iter_mut().zip(values) {
                    *q = u16::from(v);
                }
            }
            if table.contains(&0) {
                return Err(CannotSplice::Malformed("a zero quantizer"));
            }
            *self
                .quant
                .get_mut(usize::from(precision_id & 15))
                .ok_or(CannotSplice::Malformed("DQT id"))? = Some(table);
            body = rest.get(size..).unwrap_or_default();
        }
        Ok(())
    }

    /// Adobe's APP14: its colour transform says RGB (0), YCbCr (1) or YCCK (2).
    fn adobe(&mut self, body: &[u8]) {
        if body.starts_with(b"Adobe")
            && let Some(&transform) = body.get(11)
        {
            self.adobe_transform = Some(transform);
        }
    }

    fn scan(self, body: &[u8], segment: Range<usize>) -> Result<Headers, CannotSplice> {
        let Some(Frame {
            width,
            height,
            components,
            segment: sof,
            extended,
        }) = self.frame
        else {
            return Err(CannotSplice::Malformed("a scan before the frame header"));
        };
        // Decoders take three components as RGB when Adobe's marker says so or (some of
        // them) when their ids spell R, G, B; a grey frame becomes YCbCr here, which Adobe's
        // transform 0 would make RGB.
        if self.adobe_transform.is_some_and(|t| t != 1) {
            return Err(CannotSplice::NotYcbcr);
        }
        let ids: Vec<u8> = components.iter().map(|c| c.id).collect();
        if ids == b"RGB" {
            return Err(CannotSplice::NotYcbcr);
        }
        let &[count, ref rest @ ..] = body else {
            return Err(CannotSplice::Malformed("SOS length"));
        };
        if rest.len() != 2 * usize::from(count) + 3 {
            return Err(CannotSplice::Malformed("SOS length"));
        }
        if usize::from(count) != components.len() {
            return Err(CannotSplice::MultipleScans);
        }
        let most_table = if extended { 3 } else { 1 };
        let mut scan = Vec::with_capacity(components.len());
        for pair in rest.chunks_exact(2).take(usize::from(count)) {
            let &[id, tables] = pair else {
                return Err(CannotSplice::Malformed("SOS length"));
            };
            let component = components
                .iter()
                .position(|c| c.id == id)
                .ok_or(CannotSplice::Malformed("a scan component not in the frame"))?;
            if scan
                .iter()
                .any(|s: &ScanComponent| s.component == component)
            {
                return Err(CannotSplice::Malformed("a component twice in the scan"));
            }
            let (dc, ac) = (tables >> 4, tables & 15);
            if dc > most_table || ac > most_table {
                return Err(CannotSplice::Malformed("Huffman table id"));
            }
            scan.push(ScanComponent { component, dc, ac });
        }
        let defined = |tables: &[Option<HuffmanSpec>; 4], id: u8| {
            tables.get(usize::from(id)).is_some_and(Option::is_some)
        };
        if scan
            .iter()
            .any(|s| !defined(&self.dc, s.dc) || !defined(&self.ac, s.ac))
        {
            return Err(CannotSplice::Malformed("an undefined Huffman table"));
        }
        if components.iter().any(|c| {
            self.quant
                .get(usize::from(c.quant))
                .is_none_or(Option::is_none)
        }) {
            return Err(CannotSplice::Malformed("an undefined quantization table"));
        }
        Ok(Headers {
            width,
            height,
            components,
            quant: self.quant,
            dc: self.dc,
            ac: self.ac,
            restart_interval: self.restart_interval,
            scan,
            sof,
            sos: segment,
        })
    }
}

/// Checks what follows the scan's data at `at` up to EOI: whole COM and APPn segments
/// only, and no segment cut off by the end of the file. Anything after EOI is not looked
/// at.
///
/// Tables (DHT, DQT, DRI, DAC) after the only scan serve no scan, and decoders of a
/// one-scan file never read them; a grey frame's spliced version has three scans, after
/// which zune-jpeg does read them, and refuses a malformed table the client's file carried
/// harmlessly (found by `cargo fuzz`). An Adobe APP14 there would change how the
/// three-component version's colours are read. Both fall back to the whole-frame path.
///
/// Whether an EOI ends it: a file may just stop after its scan, which zune-jpeg accepts of
/// a one-scan file but not of the three scans a grey frame's spliced version has (found by
/// `cargo fuzz`), so the splice then adds one.
///
/// # Errors
/// [`CannotSplice::MultipleScans`], [`CannotSplice::Dnl`], or
/// [`CannotSplice::Malformed`] for other markers and for bytes that are no marker segment.
pub fn check_trailer(file: &[u8], mut at: usize) -> Result<bool, CannotSplice> {
    while at < file.len() {
        let (code, segment_at) = next_marker(file, at)?;
        match code {
            0xD9 => return Ok(true),
            0xDA => return Err(CannotSplice::MultipleScans),
            0xDC => return Err(CannotSplice::Dnl),
            0xC4 | 0xCC | 0xDB | 0xDD => {
                return Err(CannotSplice::Malformed("tables after the scan"));
            }
            0xEE => return Err(CannotSplice::Malformed("an Adobe marker after the scan")),
            0xE0..=0xEF | 0xFE => {}
            _ => return Err(CannotSplice::Malformed("a marker after the scan")),
        }
        let length = bytes(file, segment_at, 2)?;
        let length = usize::from(u16::from_be_bytes([
            length.first().copied().unwrap_or(0),
            length.get(1).copied().unwrap_or(0),
        ]));
        if length < 2 {
            return Err(CannotSplice::Malformed("segment length"));
        }
        at = segment_at + length;
        if at > file.len() {
            // zune-jpeg, the service's decoder, fails on such a file when the scan's last
            // code ends within a byte or two of the marker (as it may once re-encoded),
            // though it read the client's file, whose data ended earlier.
            return Err(CannotSplice::Malformed(
                "a segment after the scan runs past the end",
            ));
        }
    }
    Ok(false)
}
