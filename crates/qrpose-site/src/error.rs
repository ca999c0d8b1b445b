//! Why a site file was refused: a [`SiteError`] names the file, the line when it is known
//! and the [`Reason`]. Its `Display` is one line, `FILE:LINE: reason`, the form an editor
//! jumps to; `qrpose serve --site` and `qrpose site check` print it as it is.

use std::path::{Path, PathBuf};
use thiserror::Error;

/// A site file that cannot be used: where, and why.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("{}{}: {reason}", file.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct SiteError {
    /// The site file as it was given (or the calibration file it names, for a read error of
    /// that file: then `reason` names both).
    pub file: PathBuf,
    /// 1-based line in `file`, when the refusal points at one.
    pub line: Option<usize>,
    /// What is wrong.
    pub reason: Reason,
}

impl SiteError {
    /// An error of `file` at `line`.
    pub fn new(file: &Path, line: Option<usize>, reason: Reason) -> Self {
        Self {
            file: file.to_path_buf(),
            line,
            reason,
        }
    }
}

/// What is wrong with a site file. Every variant is a refusal of the whole file: a site is
/// loaded complete or not at all.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Reason {
    /// The file cannot be read (missing, unreadable, not UTF-8).
    #[error("cannot read the site file: {0}")]
    Read(String),
    /// The YAML does not parse, or does not fit the format: a syntax error, an unknown key
    /// (typos are refused, not ignored), a value of the wrong type, or a value refused where
    /// it is read (a negative size, an invalid regular expression, a zero quaternion, a
    /// payload listed twice); the parser's message.
    #[error("{0}")]
    Format(String),
    /// Two size rules with the same key, or a payload mapped twice: which one was meant?
    #[error("{section}: {key} is listed twice")]
    Duplicate {
        /// `markers.sizes`, `map` or `objects`.
        section: &'static str,
        /// `payload "DOCK-7"`, `prefix "TOTE-"`, `pattern "^LOC-"`.
        key: String,
    },
    /// A camera names neither a calibration file nor inline intrinsics, or both.
    #[error("camera {id:?}: {detail}")]
    CameraForm {
        /// The camera id.
        id: String,
        /// What is missing or conflicting.
        detail: String,
    },
    /// A camera's calibration file does not exist.
    #[error("camera {id:?}: calibration file {path} does not exist")]
    MissingCalibration {
        /// The camera id.
        id: String,
        /// The calibration file, resolved against the site file's directory.
        path: PathBuf,
    },
    /// A camera's calibration file exists but was refused by its reader.
    #[error("camera {id:?}: calibration file {path}: {detail}")]
    InvalidCalibration {
        /// The camera id.
        id: String,
        /// The calibration file, resolved against the site file's directory.
        path: PathBuf,
        /// The reader's reason (with the calibration file's own line).
        detail: String,
    },
    /// Inline intrinsics or distortion that the camera model refuses.
    #[error("camera {id:?}: {key}: {detail}")]
    InvalidCamera {
        /// The camera id.
        id: String,
        /// `intrinsics` or `distortion`.
        key: &'static str,
        /// The camera model's reason.
        detail: String,
    },
    /// A mapped code whose size the site does not give: it could never be localised from.
    #[error(
        "map: code {payload:?} has no size: add it to markers.sizes or set markers.default_size_mm"
    )]
    MappedCodeWithoutSize {
        /// The payload.
        payload: String,
    },
}

/// The 1-based line of the first occurrence of `needle` in `text`, if any: the line of a
/// value the YAML parser did not locate (a calibration path, a payload).
pub fn line_of(text: &str, needle: &str) -> Option<usize> {
    text.lines().position(|l| l.contains(needle)).map(|i| i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_is_file_line_reason() {
        let e = SiteError::new(
            Path::new("site.yaml"),
            Some(7),
            Reason::Format("bad".into()),
        );
        assert_eq!(e.to_string(), "site.yaml:7: bad");
        let e = SiteError::new(Path::new("site.yaml"), None, Reason::Read("gone".into()));
        assert_eq!(e.to_string(), "site.yaml: cannot read the site file: gone");
    }

    #[test]
    fn line_of_finds_the_first_line_with_the_value() {
        assert_eq!(line_of("a: 1\nb: front.yaml\nc: 3", "front.yaml"), Some(2));
        assert_eq!(line_of("a: 1", "front.yaml"), None);
    }
}
