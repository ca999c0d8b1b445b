//! YUV4MPEG2 (`.y4m`) output: grey frames as uncompressed video, the format Chromium's
//! fake camera plays (`--use-fake-device-for-media-stream
//! --use-file-for-fake-video-capture=FILE.y4m`).
//!
//! The file: one header line `YUV4MPEG2 W<w> H<h> F<num>:<den> Ip A1:1 C<colour>\n`, then per
//! frame `FRAME\n` and the planes, 8 bits per sample, row-major. `C420jpeg`
//! ([`Y4mColour::C420jpeg`]): the Y plane (the grey image), then U and V planes of
//! ⌈w/2⌉ × ⌈h/2⌉ samples, all 128 (no colour). `Cmono` ([`Y4mColour::Mono`]): the Y plane
//! alone (ffmpeg reads it; Chromium does not).
//!
//! What Chromium's parser (media/capture/video/file_video_capture_device.cc) requires, and
//! this writer keeps: the header within the first 200 bytes and ended by a newline; tokens
//! separated by single spaces; `C` one of `420`, `420jpeg`, `420mpeg2`, `420paldv` (it reads
//! every file as I420, and stops on any other colour space); no interlacing `Im`; every
//! frame header exactly `FRAME\n` (it skips 6 bytes between frames); the frame rate read as
//! the integer num / den. It plays the file in a loop. Even image sizes are safest.

use qrpose_detect::decode::GrayImage;
use std::io::Write;
use thiserror::Error;

/// The grey level of the U and V planes: no colour.
const NEUTRAL_CHROMA: u8 = 128;

/// The colour space of a `.y4m` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Y4mColour {
    /// 4:2:0 with JPEG chroma siting: what Chromium's fake camera reads.
    #[default]
    C420jpeg,
    /// The luma plane alone (`Cmono`): a third smaller, not read by Chromium.
    Mono,
}

impl Y4mColour {
    /// The header's `C` token without its letter: `420jpeg` or `mono`.
    pub fn token(self) -> &'static str {
        match self {
            Self::C420jpeg => "420jpeg",
            Self::Mono => "mono",
        }
    }
}

/// Why a frame could not be written.
#[derive(Debug, Error)]
pub enum Y4mError {
    /// The output failed.
    #[error("cannot write the video: {0}")]
    Io(#[from] std::io::Error),
    /// A frame of another size than the header's.
    #[error(
        "frame of {width_px} × {height_px} px in a video of {video_width_px} × {video_height_px} px"
    )]
    FrameSize {
        /// The frame's width, px.
        width_px: usize,
        /// The frame's height, px.
        height_px: usize,
        /// The video's width, px.
        video_width_px: u32,
        /// The video's height, px.
        video_height_px: u32,
    },
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// The frame rate as the header's rational num:den: whole rates as n:1, others to a
/// thousandth (29.97 → 2997:100).
fn rate_fraction(fps: f64) -> (u64, u64) {
    // Rates are positive and at most MAX_FPS, so the rounded value fits.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let milli = (fps * 1000.0).round().max(1.0) as u64;
    let g = gcd(milli, 1000);
    (milli / g, 1000 / g)
}

/// The header line of a `width_px` × `height_px` video at `fps` frames per second.
pub fn y4m_header(width_px: u32, height_px: u32, fps: f64, colour: Y4mColour) -> String {
    let (num, den) = rate_fraction(fps);
    format!(
        "YUV4MPEG2 W{width_px} H{height_px} F{num}:{den} Ip A1:1 C{}\n",
        colour.token()
    )
}

/// Bytes of one frame's planes (without its `FRAME\n` line).
pub fn y4m_frame_bytes(width_px: u32, height_px: u32, colour: Y4mColour) -> usize {
    let (w, h) = (width_px as usize, height_px as usize);
    match colour {
        Y4mColour::C420jpeg => w * h + 2 * w.div_ceil(2) * h.div_ceil(2),
        Y4mColour::Mono => w * h,
    }
}

/// Writes grey frames as a `.y4m` video: the header on creation, then one frame per call.
#[derive(Debug)]
pub struct Y4mWriter<W: Write> {
    out: W,
    width_px: u32,
    height_px: u32,
    colour: Y4mColour,
    chroma: Vec<u8>,
}

impl<W: Write> Y4mWriter<W> {
    /// Starts a video: writes the header to `out`.
    ///
    /// # Errors
    /// [`Y4mError::Io`] when the write fails.
    pub fn new(
        mut out: W,
        width_px: u32,
        height_px: u32,
        fps: f64,
        colour: Y4mColour,
    ) -> Result<Self, Y4mError> {
        out.write_all(y4m_header(width_px, height_px, fps, colour).as_bytes())?;
        let chroma_bytes =
            y4m_frame_bytes(width_px, height_px, colour) - width_px as usize * height_px as usize;
        Ok(Self {
            out,
            width_px,
            height_px,
            colour,
            chroma: vec![NEUTRAL_CHROMA; chroma_bytes],
        })
    }

    /// Appends one frame.
    ///
    /// # Errors
    /// [`Y4mError::FrameSize`] for a frame of another size, [`Y4mError::Io`] when the write
    /// fails.
    pub fn write_frame(&mut self, image: &GrayImage) -> Result<(), Y4mError> {
        if image.width() != self.width_px as usize || image.height() != self.height_px as usize {
            return Err(Y4mError::FrameSize {
                width_px: image.width(),
                height_px: image.height(),
                video_width_px: self.width_px,
                video_height_px: self.height_px,
            });
        }
        self.out.write_all(b"FRAME\n")?;
        self.out.write_all(image.pixels())?;
        if self.colour == Y4mColour::C420jpeg {
            self.out.write_all(&self.chroma)?;
        }
        Ok(())
    }

    /// Flushes and returns the output.
    ///
    /// # Errors
    /// [`Y4mError::Io`] when the flush fails.
    pub fn finish(mut self) -> Result<W, Y4mError> {
        self.out.flush()?;
        Ok(self.out)
    }
}
