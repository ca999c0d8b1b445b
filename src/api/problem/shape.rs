//! What kind of shape error serde met, read from its message: the one place in the service
//! that reads serde's wording.
//!
//! serde reports a document of the wrong shape through the constructors of
//! [`serde::de::Error`] (`missing_field`, `unknown_field`, …), and serde_json's and
//! serde_urlencoded's errors keep only the text those make: serde's fixed wording
//! (`missing field `x``, `unknown field `x`, expected …`), which serde_json follows with
//! the position. The words are pinned by the tests below against serde's own constructors,
//! so that a change of wording fails a test instead of changing a code.

/// The kind of a shape error, with the field a missing, unknown or duplicate field error
/// names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ShapeKind {
    /// A required field is absent.
    MissingField(String),
    /// A field the type does not have (under `deny_unknown_fields`).
    UnknownField(String),
    /// A value outside an enumerated set.
    UnknownVariant,
    /// A field given twice.
    DuplicateField(String),
    /// Any other refusal: a wrong type or value, a wrong length, a custom message.
    Other,
}

impl ShapeKind {
    /// The kind serde's `message` names.
    #[must_use]
    pub fn of(message: &str) -> Self {
        // The first backticked name: `missing field `size_mm``.
        let named = || message.split('`').nth(1).unwrap_or_default().to_owned();
        if message.starts_with("missing field `") {
            Self::MissingField(named())
        } else if message.starts_with("unknown field `") {
            Self::UnknownField(named())
        } else if message.starts_with("unknown variant `") {
            Self::UnknownVariant
        } else if message.starts_with("duplicate field `") {
            Self::DuplicateField(named())
        } else {
            Self::Other
        }
    }

    /// The field a missing, unknown or duplicate field error names.
    #[must_use]
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::MissingField(field) | Self::UnknownField(field) | Self::DuplicateField(field) => {
                Some(field)
            }
            Self::UnknownVariant | Self::Other => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::de::value::Error as Wording;
    use serde::de::{Error as _, Unexpected};

    #[test]
    fn each_constructor_of_serde_reads_as_its_kind() {
        let expected: &'static [&'static str] = &["size_mm", "corners"];
        let field = |s: &str| s.to_owned();
        let cases = [
            (
                Wording::missing_field("size_mm"),
                ShapeKind::MissingField(field("size_mm")),
            ),
            (
                Wording::unknown_field("sise", expected),
                ShapeKind::UnknownField(field("sise")),
            ),
            (
                Wording::unknown_variant("magic", expected),
                ShapeKind::UnknownVariant,
            ),
            (
                Wording::duplicate_field("size_mm"),
                ShapeKind::DuplicateField(field("size_mm")),
            ),
            (
                Wording::invalid_type(Unexpected::Str("5"), &"f64"),
                ShapeKind::Other,
            ),
            (
                Wording::invalid_value(Unexpected::Signed(-5), &"u8"),
                ShapeKind::Other,
            ),
            (Wording::invalid_length(1, &"2 elements"), ShapeKind::Other),
            (Wording::custom("missing field"), ShapeKind::Other),
        ];
        for (error, kind) in cases {
            assert_eq!(ShapeKind::of(&error.to_string()), kind, "{error}");
        }
    }

    #[test]
    fn serde_jsons_messages_read_as_serdes_with_the_position_after() {
        #[derive(Debug, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct Marker {
            size_mm: f64,
        }
        let kind = |json: &str| {
            let error = serde_json::from_str::<Marker>(json).expect_err(json);
            ShapeKind::of(&error.to_string())
        };
        assert_eq!(kind("{}"), ShapeKind::MissingField("size_mm".to_owned()));
        assert_eq!(
            kind(r#"{"size_mm": 1, "a`b": 2}"#),
            ShapeKind::UnknownField("a".to_owned()),
            "a backtick in a name ends it: the pointer comes from the path, not from here"
        );
        assert_eq!(
            kind(r#"{"size_mm": 1, "size_mm": 2}"#),
            ShapeKind::DuplicateField("size_mm".to_owned())
        );
        assert_eq!(kind(r#"{"size_mm": "1"}"#), ShapeKind::Other);
    }
}
