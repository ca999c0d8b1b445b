//! An integer field as JSON Schema (and so the OpenAPI document) counts integers: `30` and
//! `30.0` alike, a number with no fractional part being an integer there. Anything else
//! that is not a non-negative integer below 2⁶⁴ is refused as serde refuses it for `u64`
//! (`invalid_type`); the range of the field is checked by its validation.

use serde::Deserializer;
use serde::de::{Error, Unexpected, Visitor};
use std::fmt;

/// 2⁶⁴, the first float above `u64::MAX`.
const U64_END: f64 = 18_446_744_073_709_551_616.0;

struct Integral;

impl Visitor<'_> for Integral {
    type Value = u64;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("u64")
    }

    fn visit_u64<E: Error>(self, v: u64) -> Result<u64, E> {
        Ok(v)
    }

    fn visit_i64<E: Error>(self, v: i64) -> Result<u64, E> {
        u64::try_from(v).map_err(|_| E::invalid_value(Unexpected::Signed(v), &self))
    }

    // In range and integral, checked before the cast: it is exact.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    fn visit_f64<E: Error>(self, v: f64) -> Result<u64, E> {
        if v.fract() == 0.0 && (0.0..U64_END).contains(&v) {
            Ok(v as u64)
        } else {
            Err(E::invalid_type(Unexpected::Float(v), &self))
        }
    }
}

/// Deserialises a `u64` field that may be written `30` or `30.0`.
///
/// # Errors
/// The deserialiser's error for a fraction, a negative number or one past `u64::MAX`.
pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    d.deserialize_u64(Integral)
}

#[cfg(test)]
mod tests {
    use super::super::problem::{ErrorCode, parse_json};
    use super::super::request::CornersRequest;

    fn max_iterations(value: &str) -> Result<u64, ErrorCode> {
        let body = format!(
            r#"{{"corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
                "camera": {{"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5}},
                "marker": {{"size_mm": 50}}, "solver": {{"max_iterations": {value}}}}}"#
        );
        parse_json::<CornersRequest>(body.as_bytes())
            .map(|r| r.solver.max_iterations)
            .map_err(|p| p.code)
    }

    #[test]
    fn an_integral_float_is_an_integer_as_in_json_schema() {
        assert_eq!(max_iterations("7"), Ok(7));
        assert_eq!(max_iterations("7.0"), Ok(7));
        assert_eq!(max_iterations("7e0"), Ok(7));
        assert_eq!(max_iterations("2.5"), Err(ErrorCode::InvalidType));
        assert_eq!(max_iterations("-5"), Err(ErrorCode::InvalidType));
        assert_eq!(max_iterations("1e20"), Err(ErrorCode::InvalidType));
    }
}
