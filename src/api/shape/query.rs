//! A deserialiser over the pairs of a query string (`application/x-www-form-urlencoded`)
//! that fails with a [`ShapeError`].
//!
//! It reads a query as serde_urlencoded 0.7 does: the pairs, percent-decoded by
//! `form_urlencoded`, are a map of parameter name to value (a parameter given twice is two
//! entries, which a struct refuses as a duplicate field); a value is a string, parsed with
//! `FromStr` where the type wants a number or a boolean (a failure is a `custom` error with
//! the parser's message, e.g. "invalid float literal"), `Some` of itself for an option, and
//! the name of a unit variant for an enum.

use super::ShapeError;
use serde::de::value::MapDeserializer;
use serde::de::{
    self, DeserializeOwned, DeserializeSeed, EnumAccess, Error as _, IntoDeserializer,
    VariantAccess, Visitor,
};
use serde::forward_to_deserialize_any;
use std::borrow::Cow;

/// Deserialises `T` from a query string (without the `?`); on failure, the typed error and
/// the path of the parameter at fault (empty when the error is about the query as a whole,
/// such as a missing, unknown or duplicate parameter, which the error's kind names).
///
/// # Errors
/// The first [`ShapeError`] `T`'s `Deserialize` meets, with its path.
pub fn from_query<T: DeserializeOwned>(
    query: &str,
) -> Result<T, serde_path_to_error::Error<ShapeError>> {
    let pairs = Pairs(form_urlencoded::parse(query.as_bytes()));
    serde_path_to_error::deserialize(QueryDeserializer(MapDeserializer::new(pairs)))
}

/// The decoded pairs of a query string.
struct Pairs<'de>(form_urlencoded::Parse<'de>);

impl<'de> Iterator for Pairs<'de> {
    type Item = (Part<'de>, Part<'de>);

    fn next(&mut self) -> Option<Self::Item> {
        self.0.next().map(|(name, value)| (Part(name), Part(value)))
    }
}

/// A whole query: a map (or a sequence of pairs) of its parameters.
struct QueryDeserializer<'de>(MapDeserializer<'de, Pairs<'de>, ShapeError>);

impl<'de> de::Deserializer<'de> for QueryDeserializer<'de> {
    type Error = ShapeError;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ShapeError> {
        self.deserialize_map(visitor)
    }

    fn deserialize_map<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ShapeError> {
        visitor.visit_map(self.0)
    }

    fn deserialize_seq<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ShapeError> {
        visitor.visit_seq(self.0)
    }

    fn deserialize_unit<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ShapeError> {
        self.0.end()?;
        visitor.visit_unit()
    }

    forward_to_deserialize_any! {
        bool u8 u16 u32 u64 i8 i16 i32 i64 f32 f64 char str string option bytes byte_buf
        unit_struct newtype_struct tuple_struct struct identifier tuple enum ignored_any
    }
}

/// A parameter's name or value, percent-decoded.
struct Part<'de>(Cow<'de, str>);

impl<'de> IntoDeserializer<'de, ShapeError> for Part<'de> {
    type Deserializer = Self;

    fn into_deserializer(self) -> Self {
        self
    }
}

/// The methods of the types a value's text is parsed into (`"1.5"` for an `f64`).
macro_rules! parsed {
    ($($ty:ident => $method:ident,)*) => {$(
        fn $method<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ShapeError> {
            match self.0.parse::<$ty>() {
                Ok(parsed) => {
                    IntoDeserializer::<ShapeError>::into_deserializer(parsed).$method(visitor)
                }
                Err(e) => Err(ShapeError::custom(e)),
            }
        }
    )*};
}

impl<'de> de::Deserializer<'de> for Part<'de> {
    type Error = ShapeError;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ShapeError> {
        match self.0 {
            Cow::Borrowed(text) => visitor.visit_borrowed_str(text),
            Cow::Owned(text) => visitor.visit_string(text),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ShapeError> {
        visitor.visit_some(self)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, ShapeError> {
        visitor.visit_enum(UnitEnum(self.0))
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, ShapeError> {
        visitor.visit_newtype_struct(self)
    }

    forward_to_deserialize_any! {
        char str string unit bytes byte_buf unit_struct tuple_struct struct identifier tuple
        ignored_any seq map
    }

    parsed! {
        bool => deserialize_bool,
        u8 => deserialize_u8,
        u16 => deserialize_u16,
        u32 => deserialize_u32,
        u64 => deserialize_u64,
        i8 => deserialize_i8,
        i16 => deserialize_i16,
        i32 => deserialize_i32,
        i64 => deserialize_i64,
        f32 => deserialize_f32,
        f64 => deserialize_f64,
    }
}

/// An enum written as the name of a unit variant.
struct UnitEnum<'de>(Cow<'de, str>);

impl<'de> EnumAccess<'de> for UnitEnum<'de> {
    type Error = ShapeError;
    type Variant = UnitVariant;

    fn variant_seed<S: DeserializeSeed<'de>>(
        self,
        seed: S,
    ) -> Result<(S::Value, UnitVariant), ShapeError> {
        let variant = seed.deserialize(Part(self.0))?;
        Ok((variant, UnitVariant))
    }
}

/// The (absent) content of a unit variant; a query has no way to write any other.
struct UnitVariant;

impl<'de> VariantAccess<'de> for UnitVariant {
    type Error = ShapeError;

    fn unit_variant(self) -> Result<(), ShapeError> {
        Ok(())
    }

    fn newtype_variant_seed<S: DeserializeSeed<'de>>(
        self,
        _seed: S,
    ) -> Result<S::Value, ShapeError> {
        Err(ShapeError::custom("expected unit variant"))
    }

    fn tuple_variant<V: Visitor<'de>>(
        self,
        _len: usize,
        _visitor: V,
    ) -> Result<V::Value, ShapeError> {
        Err(ShapeError::custom("expected unit variant"))
    }

    fn struct_variant<V: Visitor<'de>>(
        self,
        _fields: &'static [&'static str],
        _visitor: V,
    ) -> Result<V::Value, ShapeError> {
        Err(ShapeError::custom("expected unit variant"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::shape::ShapeErrorKind;
    use serde::Deserialize;

    #[derive(Debug, PartialEq, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Query {
        size_mm: Option<f64>,
        count: Option<u32>,
        fast: Option<bool>,
        mode: Option<QueryMode>,
        name: Option<String>,
    }

    #[derive(Debug, PartialEq, Deserialize)]
    #[serde(rename_all = "lowercase")]
    enum QueryMode {
        Fast,
    }

    #[derive(Debug, Deserialize)]
    #[allow(dead_code)]
    struct Required {
        size_mm: f64,
    }

    #[test]
    fn query_values_parse_as_serde_urlencoded_parses_them() {
        let q: Query =
            from_query("size_mm=1.5&count=7&fast=true&mode=f%61st&name=a%20b+c").expect("valid");
        assert_eq!(
            q,
            Query {
                size_mm: Some(1.5),
                count: Some(7),
                fast: Some(true),
                mode: Some(QueryMode::Fast),
                name: Some("a b c".to_owned()),
            }
        );
        let empty: Query = from_query("").expect("no parameters");
        assert_eq!(empty.size_mm, None);
        let pairs: Vec<(String, String)> = from_query("a=1&a=2").expect("pairs");
        assert_eq!(pairs, [("a".into(), "1".into()), ("a".into(), "2".into())]);
    }

    #[test]
    fn query_errors_have_their_kind_and_path() {
        let cases: [(&str, ShapeErrorKind, &str); 7] = [
            (
                "size=5",
                ShapeErrorKind::UnknownField {
                    field: "size".to_owned(),
                },
                "size",
            ),
            (
                "count=1&count=2",
                ShapeErrorKind::DuplicateField {
                    field: "count".to_owned(),
                },
                ".",
            ),
            (
                "mode=slow",
                ShapeErrorKind::UnknownVariant {
                    variant: "slow".to_owned(),
                },
                "mode",
            ),
            ("size_mm=wide", ShapeErrorKind::Custom, "size_mm"),
            ("count=-1", ShapeErrorKind::Custom, "count"),
            ("fast=yes", ShapeErrorKind::Custom, "fast"),
            ("size_mm=", ShapeErrorKind::Custom, "size_mm"),
        ];
        for (query, kind, path) in cases {
            let err = from_query::<Query>(query).expect_err(query);
            assert_eq!(err.inner().kind(), &kind, "{query}");
            assert_eq!(err.path().to_string(), path, "{query}");
            let theirs = serde_urlencoded::from_str::<Query>(query).expect_err(query);
            assert_eq!(err.inner().to_string(), theirs.to_string(), "{query}");
        }
        let err = from_query::<Required>("").expect_err("missing");
        assert_eq!(
            err.inner().kind(),
            &ShapeErrorKind::MissingField {
                field: "size_mm".to_owned()
            }
        );
    }
}
