//! Serde errors that say what went wrong as a value, not only as text.
//!
//! serde reports a document of the wrong shape through the constructors of
//! [`serde::de::Error`] (`missing_field`, `unknown_field`, `unknown_variant`, …), and a
//! format's own error type (serde_json's, serde_urlencoded's) keeps only the text they
//! make. [`ShapeError`] keeps which constructor was called ([`ShapeErrorKind`]) and the
//! field or variant it names, so that the API chooses a problem's stable code from that
//! and never by reading the message. Its message is serde's own wording (built with
//! [`serde::de::value::Error`], the error type serde_urlencoded uses), so it reads as
//! serde's does.
//!
//! Two deserialisers produce it: [`value`] over a parsed JSON document, visiting it as
//! serde_json's own deserialiser for `&Value` does, and [`query`] over the pairs of a query
//! string, parsing numbers and booleans from their text as serde_urlencoded does.

pub mod query;
#[cfg(test)]
mod tests;
pub mod value;

use serde::de::{self, Expected, Unexpected};
use std::fmt::Display;

/// Which [`serde::de::Error`] constructor made a [`ShapeError`], with the name it was given.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ShapeErrorKind {
    /// A required field is absent (`missing_field`).
    MissingField {
        /// The field's name as the document spells it.
        field: String,
    },
    /// A field the type does not have, under `deny_unknown_fields` (`unknown_field`).
    UnknownField {
        /// The field's name as the document spells it.
        field: String,
    },
    /// A value outside an enumerated set (`unknown_variant`).
    UnknownVariant {
        /// The value the document gave.
        variant: String,
    },
    /// A field given twice (`duplicate_field`).
    DuplicateField {
        /// The field's name as the document spells it.
        field: String,
    },
    /// A value of the wrong type (`invalid_type`), e.g. a string where a number belongs.
    InvalidType,
    /// A value of the right type that the type refuses (`invalid_value`), e.g. `-5` for
    /// an unsigned integer.
    InvalidValue,
    /// A sequence or map of the wrong length (`invalid_length`).
    InvalidLength,
    /// Any other refusal (`custom`), e.g. a number that does not parse from its text.
    Custom,
}

impl ShapeErrorKind {
    /// The field this error is about when the constructor names one (a missing, unknown or
    /// duplicate field); `None` for the others, whose field is where the error occurred.
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::MissingField { field }
            | Self::UnknownField { field }
            | Self::DuplicateField { field } => Some(field),
            _ => None,
        }
    }
}

/// A deserialisation error that keeps its kind: what [`value`] and [`query`] fail with.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct ShapeError {
    kind: ShapeErrorKind,
    message: String,
}

impl ShapeError {
    fn new(kind: ShapeErrorKind, message: impl Display) -> Self {
        Self {
            kind,
            message: message.to_string(),
        }
    }

    /// Which constructor made this error, with the field or variant it names.
    pub fn kind(&self) -> &ShapeErrorKind {
        &self.kind
    }

    /// This error's kind, by value.
    pub fn into_kind(self) -> ShapeErrorKind {
        self.kind
    }
}

/// serde's own wording for each constructor.
type Wording = de::value::Error;

impl de::Error for ShapeError {
    fn custom<T: Display>(msg: T) -> Self {
        Self::new(ShapeErrorKind::Custom, msg)
    }

    fn invalid_type(unexp: Unexpected<'_>, exp: &dyn Expected) -> Self {
        Self::new(
            ShapeErrorKind::InvalidType,
            Wording::invalid_type(unexp, exp),
        )
    }

    fn invalid_value(unexp: Unexpected<'_>, exp: &dyn Expected) -> Self {
        Self::new(
            ShapeErrorKind::InvalidValue,
            Wording::invalid_value(unexp, exp),
        )
    }

    fn invalid_length(len: usize, exp: &dyn Expected) -> Self {
        Self::new(
            ShapeErrorKind::InvalidLength,
            Wording::invalid_length(len, exp),
        )
    }

    fn unknown_variant(variant: &str, expected: &'static [&'static str]) -> Self {
        Self::new(
            ShapeErrorKind::UnknownVariant {
                variant: variant.to_owned(),
            },
            Wording::unknown_variant(variant, expected),
        )
    }

    fn unknown_field(field: &str, expected: &'static [&'static str]) -> Self {
        Self::new(
            ShapeErrorKind::UnknownField {
                field: field.to_owned(),
            },
            Wording::unknown_field(field, expected),
        )
    }

    fn missing_field(field: &'static str) -> Self {
        Self::new(
            ShapeErrorKind::MissingField {
                field: field.to_owned(),
            },
            Wording::missing_field(field),
        )
    }

    fn duplicate_field(field: &'static str) -> Self {
        Self::new(
            ShapeErrorKind::DuplicateField {
                field: field.to_owned(),
            },
            Wording::duplicate_field(field),
        )
    }
}
