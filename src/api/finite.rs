//! [`first_non_finite`]: the JSON pointer of the first NaN or infinite number in anything
//! `Serialize`, found by walking it as serde would serialise it.
//!
//! serde_json writes NaN and ±∞ as `null`, which breaks the response schema wherever it
//! promises a number. Responses are checked with this before they are sent
//! ([`super::response::PoseResponse::try_new`]); walking the value through serde means a
//! field added later is checked without anyone remembering to.

use serde::ser::{self, Serialize, Serializer};
use std::fmt;

/// The JSON pointer of the first number in `value` that is NaN or infinite (`""` when
/// `value` is one), or `None` when every number is finite.
pub fn first_non_finite<T: Serialize + ?Sized>(value: &T) -> Option<String> {
    let mut path = Vec::new();
    match value.serialize(Walker { path: &mut path }) {
        Err(Stop::NonFinite(pointer)) => Some(pointer),
        Ok(()) | Err(Stop::Other(_)) => None,
    }
}

/// Why the walk stopped early.
#[derive(Debug)]
enum Stop {
    /// A non-finite number at this pointer.
    NonFinite(String),
    /// The value refused to serialise (not a finiteness matter).
    Other(String),
}

impl fmt::Display for Stop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stop::NonFinite(pointer) => write!(f, "non-finite number at {pointer:?}"),
            Stop::Other(message) => f.write_str(message),
        }
    }
}

impl std::error::Error for Stop {}

impl ser::Error for Stop {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        Stop::Other(msg.to_string())
    }
}

/// One step of the path to the value being walked; the pointer is only spelled out when a
/// non-finite number is found, so that a clean walk allocates nothing past the path's
/// first growth.
#[derive(Debug)]
enum Segment {
    Field(&'static str),
    Index(usize),
    Key(String),
}

fn pointer(path: &[Segment]) -> String {
    path.iter()
        .map(|segment| match segment {
            Segment::Field(name) => format!("/{}", escape(name)),
            Segment::Index(i) => format!("/{i}"),
            Segment::Key(key) => format!("/{}", escape(key)),
        })
        .collect()
}

fn escape(name: &str) -> String {
    name.replace('~', "~0").replace('/', "~1")
}

/// Serialises one value at `path`, checking its numbers.
struct Walker<'a> {
    path: &'a mut Vec<Segment>,
}

impl Walker<'_> {
    fn float(self, finite: bool) -> Result<(), Stop> {
        if finite {
            Ok(())
        } else {
            Err(Stop::NonFinite(pointer(self.path)))
        }
    }
}

/// A sequence, map or struct being walked; `pops` path segments (an enum variant's name)
/// are removed at its end.
struct Compound<'a> {
    path: &'a mut Vec<Segment>,
    index: usize,
    key: Option<String>,
    pops: usize,
}

impl<'a> Compound<'a> {
    fn new(path: &'a mut Vec<Segment>, pops: usize) -> Self {
        Self {
            path,
            index: 0,
            key: None,
            pops,
        }
    }

    fn at<T: Serialize + ?Sized>(&mut self, segment: Segment, value: &T) -> Result<(), Stop> {
        self.path.push(segment);
        let result = value.serialize(Walker {
            path: &mut *self.path,
        });
        self.path.pop();
        result
    }

    fn element<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
        let index = self.index;
        self.index += 1;
        self.at(Segment::Index(index), value)
    }

    fn finish(self) -> Result<(), Stop> {
        for _ in 0..self.pops {
            self.path.pop();
        }
        Ok(())
    }
}

macro_rules! finite_scalars {
    ($($method:ident: $ty:ty),* $(,)?) => {
        $(fn $method(self, _: $ty) -> Result<(), Stop> { Ok(()) })*
    };
}

impl<'a> Serializer for Walker<'a> {
    type Ok = ();
    type Error = Stop;
    type SerializeSeq = Compound<'a>;
    type SerializeTuple = Compound<'a>;
    type SerializeTupleStruct = Compound<'a>;
    type SerializeTupleVariant = Compound<'a>;
    type SerializeMap = Compound<'a>;
    type SerializeStruct = Compound<'a>;
    type SerializeStructVariant = Compound<'a>;

    finite_scalars!(
        serialize_bool: bool, serialize_i8: i8, serialize_i16: i16, serialize_i32: i32,
        serialize_i64: i64, serialize_i128: i128, serialize_u8: u8, serialize_u16: u16,
        serialize_u32: u32, serialize_u64: u64, serialize_u128: u128, serialize_char: char,
        serialize_str: &str, serialize_bytes: &[u8], serialize_unit_struct: &'static str,
    );

    fn serialize_f32(self, v: f32) -> Result<(), Stop> {
        self.float(v.is_finite())
    }

    fn serialize_f64(self, v: f64) -> Result<(), Stop> {
        self.float(v.is_finite())
    }

    fn serialize_none(self) -> Result<(), Stop> {
        Ok(())
    }

    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> Result<(), Stop> {
        value.serialize(self)
    }

    fn serialize_unit(self) -> Result<(), Stop> {
        Ok(())
    }

    fn serialize_unit_variant(self, _: &'static str, _: u32, _: &'static str) -> Result<(), Stop> {
        Ok(())
    }

    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        value: &T,
    ) -> Result<(), Stop> {
        value.serialize(self)
    }

    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        value: &T,
    ) -> Result<(), Stop> {
        Compound::new(self.path, 0).at(Segment::Field(variant), value)
    }

    fn serialize_seq(self, _: Option<usize>) -> Result<Compound<'a>, Stop> {
        Ok(Compound::new(self.path, 0))
    }

    fn serialize_tuple(self, _: usize) -> Result<Compound<'a>, Stop> {
        Ok(Compound::new(self.path, 0))
    }

    fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Compound<'a>, Stop> {
        Ok(Compound::new(self.path, 0))
    }

    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Compound<'a>, Stop> {
        self.path.push(Segment::Field(variant));
        Ok(Compound::new(self.path, 1))
    }

    fn serialize_map(self, _: Option<usize>) -> Result<Compound<'a>, Stop> {
        Ok(Compound::new(self.path, 0))
    }

    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Compound<'a>, Stop> {
        Ok(Compound::new(self.path, 0))
    }

    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Compound<'a>, Stop> {
        self.path.push(Segment::Field(variant));
        Ok(Compound::new(self.path, 1))
    }
}

impl ser::SerializeSeq for Compound<'_> {
    type Ok = ();
    type Error = Stop;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
        self.element(value)
    }
    fn end(self) -> Result<(), Stop> {
        self.finish()
    }
}

impl ser::SerializeTuple for Compound<'_> {
    type Ok = ();
    type Error = Stop;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
        self.element(value)
    }
    fn end(self) -> Result<(), Stop> {
        self.finish()
    }
}

impl ser::SerializeTupleStruct for Compound<'_> {
    type Ok = ();
    type Error = Stop;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
        self.element(value)
    }
    fn end(self) -> Result<(), Stop> {
        self.finish()
    }
}

impl ser::SerializeTupleVariant for Compound<'_> {
    type Ok = ();
    type Error = Stop;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
        self.element(value)
    }
    fn end(self) -> Result<(), Stop> {
        self.finish()
    }
}

impl ser::SerializeMap for Compound<'_> {
    type Ok = ();
    type Error = Stop;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), Stop> {
        // Keys are names; a non-finite float key would be a bug of its own.
        self.key = Some(match serde_json::to_value(key) {
            Ok(serde_json::Value::String(name)) => name,
            Ok(other) => other.to_string(),
            Err(e) => return Err(Stop::Other(e.to_string())),
        });
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
        let key = self.key.take().unwrap_or_default();
        self.at(Segment::Key(key), value)
    }
    fn end(self) -> Result<(), Stop> {
        self.finish()
    }
}

impl ser::SerializeStruct for Compound<'_> {
    type Ok = ();
    type Error = Stop;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), Stop> {
        self.at(Segment::Field(key), value)
    }
    fn end(self) -> Result<(), Stop> {
        self.finish()
    }
}

impl ser::SerializeStructVariant for Compound<'_> {
    type Ok = ();
    type Error = Stop;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), Stop> {
        self.at(Segment::Field(key), value)
    }
    fn end(self) -> Result<(), Stop> {
        self.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Serialize;
    use std::collections::BTreeMap;

    #[derive(Serialize)]
    struct Inner {
        ok: f64,
        maybe: Option<f64>,
        grid: [[f64; 2]; 2],
    }

    #[derive(Serialize)]
    #[serde(rename_all = "snake_case")]
    enum Shape {
        Point { at: [f64; 2] },
    }

    #[derive(Serialize)]
    struct Outer {
        name: String,
        inner: Inner,
        items: Vec<Inner>,
        shape: Shape,
        by_name: BTreeMap<String, f32>,
    }

    fn outer() -> Outer {
        let inner = || Inner {
            ok: 1.0,
            maybe: None,
            grid: [[0.0, 1.0], [2.0, 3.0]],
        };
        Outer {
            name: "a".into(),
            inner: inner(),
            items: vec![inner(), inner()],
            shape: Shape::Point { at: [0.0, 0.0] },
            by_name: BTreeMap::from([("x/y".to_owned(), 1.0)]),
        }
    }

    #[test]
    fn finds_the_pointer_of_the_first_non_finite_number() {
        assert_eq!(first_non_finite(&outer()), None);
        type Spoil = fn(&mut Outer);
        let cases: [(Spoil, &str); 6] = [
            (|o| o.inner.ok = f64::NAN, "/inner/ok"),
            (|o| o.inner.maybe = Some(f64::INFINITY), "/inner/maybe"),
            (
                |o| o.items[1].grid[1][0] = f64::NEG_INFINITY,
                "/items/1/grid/1/0",
            ),
            (
                |o| {
                    o.shape = Shape::Point {
                        at: [0.0, f64::NAN],
                    }
                },
                "/shape/point/at/1",
            ),
            (
                |o| {
                    o.by_name.insert("x/y".into(), f32::NAN);
                },
                "/by_name/x~1y",
            ),
            (
                |o| {
                    o.inner.ok = f64::NAN;
                    o.items[0].ok = f64::NAN;
                },
                "/inner/ok",
            ),
        ];
        for (spoil, want) in cases {
            let mut value = outer();
            spoil(&mut value);
            assert_eq!(first_non_finite(&value).as_deref(), Some(want));
        }
        assert_eq!(first_non_finite(&f64::NAN).as_deref(), Some(""));
    }
}
