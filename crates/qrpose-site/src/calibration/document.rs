//! The YAML side of a calibration file: OpenCV's `%YAML:1.0` header set aside (YAML 1.2
//! parsers refuse it), top-level keys found by any of their accepted names with the line
//! they sit on, and matrices read from `{rows, cols, data}` (plus `dt` and the
//! `!!opencv-matrix` tag in OpenCV's files) into row-major numbers.

use super::error::CalibrationError;
use serde_norway::{Mapping, Value};

/// Element types of an OpenCV matrix that are read: `d` (f64) and `f` (f32).
const FLOAT_DTS: [&str; 2] = ["d", "f"];

/// A parsed calibration file and its text, for line numbers.
pub(super) struct Document<'a> {
    text: &'a str,
    root: Mapping,
    /// Whether it starts with a `%YAML` directive, as every `cv2.FileStorage` file does.
    pub(super) yaml_directive: bool,
}

/// A matrix as written: its shape, its elements row-major, and whether it named its element
/// type (`dt`, OpenCV only).
pub(super) struct Matrix {
    pub(super) rows: usize,
    pub(super) cols: usize,
    pub(super) data: Vec<f64>,
    pub(super) has_dt: bool,
}

/// The value under any tags (`!!opencv-matrix`).
fn untagged(value: &Value) -> &Value {
    match value {
        Value::Tagged(tagged) => untagged(&tagged.value),
        other => other,
    }
}

/// What kind of YAML value this is, for messages.
fn kind(value: &Value) -> &'static str {
    match untagged(value) {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(_) => "number",
        Value::String(_) => "string",
        Value::Sequence(_) => "list",
        Value::Mapping(_) => "mapping",
        Value::Tagged(_) => "tagged value",
    }
}

/// A value as a message shows it: numbers and strings as written, anything else by kind.
fn show(value: &Value) -> String {
    match untagged(value) {
        Value::Number(n) => n.to_string(),
        Value::String(s) => format!("{s:?}"),
        other => format!("a {}", kind(other)),
    }
}

/// The text with `%YAML` directive lines (before the first `---`) blanked, so that line
/// numbers stay those of the file; and whether there was one.
fn without_yaml_directive(text: &str) -> (String, bool) {
    let mut found = false;
    let mut in_header = true;
    let lines: Vec<&str> = text
        .lines()
        .map(|line| {
            if in_header && line.starts_with("---") {
                in_header = false;
            }
            if in_header && line.starts_with("%YAML") {
                found = true;
                ""
            } else {
                line
            }
        })
        .collect();
    (lines.join("\n"), found)
}

impl<'a> Document<'a> {
    /// Parses `text`.
    ///
    /// # Errors
    /// [`CalibrationError::Syntax`] with the parser's line, [`CalibrationError::NotAMapping`].
    pub(super) fn parse(text: &'a str) -> Result<Self, CalibrationError> {
        let (yaml, yaml_directive) = without_yaml_directive(text);
        let value: Value = serde_norway::from_str(&yaml).map_err(|e| CalibrationError::Syntax {
            line: e.location().map(|l| l.line()),
            reason: e.to_string(),
        })?;
        match untagged(&value) {
            Value::Mapping(root) => Ok(Self {
                text,
                root: root.clone(),
                yaml_directive,
            }),
            other => Err(CalibrationError::NotAMapping { found: kind(other) }),
        }
    }

    /// The 1-based line of top-level key `key`, when it is written plainly at column 0.
    pub(super) fn line_of(&self, key: &str) -> Option<usize> {
        let plain = format!("{key}:");
        let quoted = format!("\"{key}\":");
        self.text
            .lines()
            .position(|l| l.starts_with(&plain) || l.starts_with(&quoted))
            .map(|i| i + 1)
    }

    /// The value of the first of `names` present, with the name used. `Ok(None)` when
    /// none is.
    ///
    /// # Errors
    /// [`CalibrationError::DuplicateKey`] when two of them are.
    pub(super) fn find(
        &self,
        names: &'static [&'static str],
    ) -> Result<Option<(&'static str, &Value)>, CalibrationError> {
        let mut present = names
            .iter()
            .filter_map(|&name| self.root.get(name).map(|v| (name, v)));
        let first = present.next();
        if let (Some((first, _)), Some((second, _))) = (first, present.next()) {
            return Err(CalibrationError::DuplicateKey {
                line: self.line_of(second),
                first,
                second,
            });
        }
        Ok(first)
    }

    /// The value of top-level key `key`.
    pub(super) fn get(&self, key: &str) -> Option<&Value> {
        self.root.get(key)
    }

    /// A positive integer under `key` (`image_width`), `None` when the key is absent.
    ///
    /// # Errors
    /// [`CalibrationError::Shape`] when it is not an integer in 1..=u32::MAX.
    pub(super) fn positive_u32(&self, key: &'static str) -> Result<Option<u32>, CalibrationError> {
        let Some(value) = self.root.get(key) else {
            return Ok(None);
        };
        let number = untagged(value).as_u64().and_then(|n| u32::try_from(n).ok());
        match number {
            Some(n) if n > 0 => Ok(Some(n)),
            _ => Err(self.shape(
                key,
                format!(
                    "must be a positive whole number of pixels, got {}",
                    show(value)
                ),
            )),
        }
    }

    /// The string under `key`, `None` when the key is absent.
    ///
    /// # Errors
    /// [`CalibrationError::Shape`] when it is not a string.
    pub(super) fn string(&self, key: &'static str) -> Result<Option<&str>, CalibrationError> {
        match self.root.get(key).map(untagged) {
            None => Ok(None),
            Some(Value::String(s)) => Ok(Some(s)),
            Some(other) => Err(self.shape(key, format!("must be a string, not a {}", kind(other)))),
        }
    }

    /// A [`CalibrationError::Shape`] at the line of `key`.
    pub(super) fn shape(&self, key: &str, reason: String) -> CalibrationError {
        CalibrationError::Shape {
            line: self.line_of(key),
            key: key.to_owned(),
            reason,
        }
    }

    /// The matrix `value` under `key`: `{rows, cols, data}`, with `dt` `d` or `f` if given.
    ///
    /// # Errors
    /// [`CalibrationError::Shape`] for a missing or ill-typed field, a `dt` that is not a
    /// float type, or `data` whose length is not rows × cols; [`CalibrationError::NonFinite`]
    /// for a NaN or infinite element.
    pub(super) fn matrix(&self, key: &str, value: &Value) -> Result<Matrix, CalibrationError> {
        let Value::Mapping(m) = untagged(value) else {
            return Err(self.shape(
                key,
                format!(
                    "must be a matrix {{rows, cols, data}}, not a {}",
                    kind(value)
                ),
            ));
        };
        let count = |field: &str| -> Result<usize, CalibrationError> {
            let v = m
                .get(field)
                .ok_or_else(|| self.shape(key, format!("the matrix has no {field}")))?;
            untagged(v)
                .as_u64()
                .and_then(|n| usize::try_from(n).ok())
                .ok_or_else(|| {
                    self.shape(
                        key,
                        format!("{field} must be a whole number, got {}", show(v)),
                    )
                })
        };
        let (rows, cols) = (count("rows")?, count("cols")?);
        let has_dt = match m.get("dt").map(untagged) {
            None => false,
            Some(Value::String(dt)) if FLOAT_DTS.contains(&dt.as_str()) => true,
            Some(other) => {
                return Err(self.shape(
                    key,
                    format!(
                        "dt {}: only floating-point matrices (dt d or f) are calibrations",
                        show(other)
                    ),
                ));
            }
        };
        let data = m
            .get("data")
            .map(untagged)
            .and_then(Value::as_sequence)
            .ok_or_else(|| self.shape(key, "the matrix has no data list".to_owned()))?;
        if data.len() != rows.saturating_mul(cols) {
            return Err(self.shape(
                key,
                format!(
                    "rows × cols is {rows} × {cols} = {} but data has {} elements",
                    rows.saturating_mul(cols),
                    data.len()
                ),
            ));
        }
        let data = data
            .iter()
            .enumerate()
            .map(|(index, v)| self.element(key, index, v))
            .collect::<Result<Vec<f64>, _>>()?;
        Ok(Matrix {
            rows,
            cols,
            data,
            has_dt,
        })
    }

    /// Element `index` of matrix `key` as a finite number.
    fn element(&self, key: &str, index: usize, value: &Value) -> Result<f64, CalibrationError> {
        let non_finite = || CalibrationError::NonFinite {
            line: self.line_of(key),
            key: key.to_owned(),
            index,
        };
        match untagged(value) {
            Value::Number(n) => n.as_f64().filter(|x| x.is_finite()).ok_or_else(non_finite),
            // OpenCV writes NaN and infinity as `.Nan` and `.Inf`, which YAML reads as
            // strings; a literal too large for f64 (`1e400`) is a string too.
            Value::String(s) if is_non_finite_literal(s) => Err(non_finite()),
            other => Err(self.shape(key, format!("element {index} is not a number: {other:?}"))),
        }
    }
}

/// Whether `s` spells NaN or infinity (`.Nan`, `-.Inf`, `1e400`).
fn is_non_finite_literal(s: &str) -> bool {
    let lower = s.trim().trim_start_matches(['+', '-']).to_ascii_lowercase();
    matches!(lower.as_str(), ".nan" | ".inf" | "nan" | "inf" | "infinity")
        || s.trim().parse::<f64>().is_ok_and(|x| !x.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_opencv_header_is_blanked_and_lines_are_kept() {
        let (yaml, found) = without_yaml_directive("%YAML:1.0\n---\na: 1\n");
        assert!(found);
        assert_eq!(yaml, "\n---\na: 1");
        let doc = Document::parse("%YAML:1.0\n---\na: 1\nb: 2\n").expect("parses");
        assert_eq!(doc.line_of("b"), Some(4));
    }

    #[test]
    fn non_finite_spellings_are_recognised() {
        for s in [".Nan", "-.Inf", ".inf", "1e400", "-1e999"] {
            assert!(is_non_finite_literal(s), "{s}");
        }
        for s in ["1.5", "abc", ""] {
            assert!(!is_non_finite_literal(s), "{s}");
        }
    }
}
