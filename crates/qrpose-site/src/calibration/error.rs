//! [`CalibrationError`]: why a calibration file was refused, with the line of the culprit
//! where it is known (1-based, in the file as given) and the file for
//! [`super::read_calibration_file`].

use qrpose_core::geometry::camera::{CameraError, DistortionModel};
use std::path::PathBuf;
use thiserror::Error;

/// `"line N: "`, or nothing when the line is not known.
fn at(line: Option<usize>) -> String {
    line.map(|l| format!("line {l}: ")).unwrap_or_default()
}

/// Why a calibration file was refused. `Display` gives the reason and, where known, the
/// line (`line 12: distortion_coefficients: …`); a file's errors are wrapped in
/// [`CalibrationError::InFile`], whose `Display` starts with the path.
#[derive(Debug, Error)]
pub enum CalibrationError {
    /// The file cannot be read (missing, unreadable, or not UTF-8).
    #[error("cannot read calibration file {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// A refusal of the file at `path`.
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// Why it was refused.
        source: Box<CalibrationError>,
    },
    /// The text is not YAML (after the OpenCV `%YAML:1.0` header is set aside).
    #[error("{}not valid YAML: {reason}", at(*line))]
    Syntax {
        /// Where the parser stopped.
        line: Option<usize>,
        /// What the parser said.
        reason: String,
    },
    /// The document is not a mapping of keys (`camera_matrix: …`).
    #[error("a calibration file is a YAML mapping of keys such as camera_matrix, not a {found}")]
    NotAMapping {
        /// What the document is instead.
        found: &'static str,
    },
    /// A key the reader needs is absent.
    #[error("missing key {key}{}", aliases_note(aliases))]
    MissingKey {
        /// The key.
        key: &'static str,
        /// Other names accepted for it.
        aliases: &'static [&'static str],
    },
    /// Two names for one thing are both given (`camera_matrix` and `K`).
    #[error("{}both {first} and {second} are given: keep one", at(*line))]
    DuplicateKey {
        /// The line of the second.
        line: Option<usize>,
        /// The first name.
        first: &'static str,
        /// The second name.
        second: &'static str,
    },
    /// A value has the wrong shape or type: a matrix without `rows`, a `dt` other than `d`
    /// or `f`, `rows × cols` not matching `data`, a 4 × 3 camera matrix, an image size that
    /// is not a positive integer, a model name that is not a string.
    #[error("{}{key}: {reason}", at(*line))]
    Shape {
        /// Where.
        line: Option<usize>,
        /// The key at fault.
        key: String,
        /// What is wrong.
        reason: String,
    },
    /// A matrix element is NaN or infinite (OpenCV writes them `.Nan`, `.Inf`).
    #[error("{}{key}: element {index} is not a finite number", at(*line))]
    NonFinite {
        /// Where.
        line: Option<usize>,
        /// The matrix.
        key: String,
        /// The element, 0-based, row-major.
        index: usize,
    },
    /// The camera matrix has a skew term: qrpose's camera model has none
    /// (`docs/conventions.md`), and dropping it would move every pixel.
    #[error(
        "{}{key}: skew {skew_px} px (element [0][1]) is not 0; qrpose's camera has no skew term: recalibrate without it (OpenCV's default)",
        at(*line)
    )]
    Skew {
        /// Where.
        line: Option<usize>,
        /// The camera matrix key.
        key: String,
        /// The skew, px.
        skew_px: f64,
    },
    /// A camera matrix whose focal length is not positive.
    #[error("{}{key}: {source}", at(*line))]
    Camera {
        /// Where.
        line: Option<usize>,
        /// The camera matrix key.
        key: String,
        /// The camera's refusal.
        source: CameraError,
    },
    /// `distortion_model` names no model that the reader knows.
    #[error(
        "{}distortion_model {name:?} is not plumb_bob, rational_polynomial or equidistant (fisheye)",
        at(*line)
    )]
    UnknownModel {
        /// Where.
        line: Option<usize>,
        /// The name given.
        name: String,
    },
    /// The number of distortion coefficients fits no model (or not the one named).
    #[error("{}{count} distortion coefficients {}", at(*line), count_reason(*model))]
    CoefficientCount {
        /// Where.
        line: Option<usize>,
        /// The model named by `distortion_model`, if any.
        model: Option<DistortionModel>,
        /// How many there are.
        count: usize,
    },
    /// 12 or 14 coefficients: OpenCV's thin-prism (s1..s4) and tilted-sensor (τx, τy)
    /// terms, which qrpose does not model.
    #[error(
        "{}{count} distortion coefficients: OpenCV's thin-prism and tilted-sensor models are not supported; when the terms after the 8th are all 0, keep the first 8 (rational_polynomial)",
        at(*line)
    )]
    UnsupportedModel {
        /// Where.
        line: Option<usize>,
        /// How many there are.
        count: usize,
    },
}

fn aliases_note(aliases: &[&str]) -> String {
    if aliases.is_empty() {
        String::new()
    } else {
        format!(" (or {})", aliases.join(", "))
    }
}

fn count_reason(model: Option<DistortionModel>) -> String {
    match model {
        Some(DistortionModel::PlumbBob) => "do not fit plumb_bob, which takes 5 (or 4, k3 = 0)".to_owned(),
        Some(m) => format!("do not fit {m}, which takes {}", m.coefficient_count()),
        None => "fit no model: plumb_bob takes 4 or 5, rational_polynomial 8, equidistant 4 (with distortion_model: equidistant)".to_owned(),
    }
}

impl CalibrationError {
    /// The line of the culprit in the calibration file, 1-based, when known.
    #[must_use]
    pub fn line(&self) -> Option<usize> {
        match self {
            Self::InFile { source, .. } => source.line(),
            Self::Syntax { line, .. }
            | Self::DuplicateKey { line, .. }
            | Self::Shape { line, .. }
            | Self::NonFinite { line, .. }
            | Self::Skew { line, .. }
            | Self::Camera { line, .. }
            | Self::UnknownModel { line, .. }
            | Self::CoefficientCount { line, .. }
            | Self::UnsupportedModel { line, .. } => *line,
            Self::Read { .. } | Self::NotAMapping { .. } | Self::MissingKey { .. } => None,
        }
    }
}
