//! Panics contained: [`contain`] runs a closure and turns a panic inside it into an error
//! value, [`Panic`], holding the panic's message.
//!
//! The one place where this workspace catches unwinding panics from code it does not
//! control: the image decoders ([`crate::decode`]), the detector backends (rqrr's
//! `detect_grids`, which panics on some real photos; rxing; zxing-cpp's bindings), rqrr's
//! decoder in [`crate::search::reread()`], and the HTTP service's estimation workers. Each
//! site decides what a panic means there (nothing found, a corrupt image, a 500).
//!
//! The closure runs under [`std::panic::AssertUnwindSafe`]: callers assert that nothing
//! the closure left half-updated is observed after a panic. Every site here drops the
//! closure's state with the panic. The panic hook still runs first (by default it prints
//! the message to standard error), and a build with `panic = "abort"` aborts as always.

use std::any::Any;
use std::fmt;
use std::panic::{AssertUnwindSafe, catch_unwind};

/// The message given for a panic payload that is neither a `&str` nor a `String`
/// (`std::panic::panic_any` with another type).
pub const NO_MESSAGE: &str = "a panic without a message";

/// A caught panic: its message ([`panic_message`] of the payload).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Panic {
    message: String,
}

impl Panic {
    /// The panic's message ([`NO_MESSAGE`] when the payload carried none).
    pub fn message(&self) -> &str {
        &self.message
    }

    /// The panic's message, owned.
    pub fn into_message(self) -> String {
        self.message
    }
}

impl fmt::Display for Panic {
    /// The message alone, as `panic!` was given it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Panic {}

/// Runs `f`, turning a panic inside it into [`Panic`] instead of unwinding further.
///
/// # Errors
/// [`Panic`] with the panic's message when `f` panics.
pub fn contain<T>(f: impl FnOnce() -> T) -> Result<T, Panic> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|payload| Panic {
        message: panic_message(payload.as_ref()).to_owned(),
    })
}

/// The message of a caught panic payload: the `&str` or `String` that `panic!` was given,
/// else [`NO_MESSAGE`].
pub fn panic_message(payload: &(dyn Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or(NO_MESSAGE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_a_value_through() {
        assert_eq!(contain(|| 6 * 7), Ok(42));
    }

    #[test]
    fn a_literal_panic_keeps_its_message() {
        let panic = contain(|| -> u8 { panic!("plain text") }).expect_err("panics");
        assert_eq!(panic.message(), "plain text");
        assert_eq!(panic.to_string(), "plain text");
    }

    #[test]
    fn a_formatted_panic_keeps_its_message() {
        let n = 7;
        let panic = contain(|| -> u8 { panic!("index {n} out of range") }).expect_err("panics");
        assert_eq!(panic.into_message(), "index 7 out of range");
    }

    #[test]
    fn a_library_panic_is_contained() {
        let v: Vec<u8> = Vec::new();
        let panic = contain(|| v[3]).expect_err("out of bounds");
        assert!(panic.message().contains("out of bounds"), "{panic}");
    }

    #[test]
    fn a_payload_without_text_has_the_default_message() {
        let panic = contain(|| std::panic::panic_any(17_u32)).expect_err("panics");
        assert_eq!(panic.message(), NO_MESSAGE);
    }

    #[test]
    fn panic_message_reads_str_and_string_payloads() {
        let s: Box<dyn Any + Send> = Box::new("static");
        let owned: Box<dyn Any + Send> = Box::new(String::from("owned"));
        let other: Box<dyn Any + Send> = Box::new(1.5_f64);
        assert_eq!(panic_message(s.as_ref()), "static");
        assert_eq!(panic_message(owned.as_ref()), "owned");
        assert_eq!(panic_message(other.as_ref()), NO_MESSAGE);
    }
}
