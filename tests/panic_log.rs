//! `telemetry::log_panics`: a contained panic becomes one JSON log event (its own process,
//! since the panic hook and the log subscriber are global).

use qrpose::config::LogFormat;
use std::io::Write;
use std::sync::{Arc, Mutex};

/// A log writer into a shared buffer.
#[derive(Clone, Default)]
struct Captured(Arc<Mutex<Vec<u8>>>);

impl Write for Captured {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().expect("not poisoned").extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl<'w> tracing_subscriber::fmt::MakeWriter<'w> for Captured {
    type Writer = Self;
    fn make_writer(&'w self) -> Self {
        self.clone()
    }
}

#[test]
fn a_contained_panic_is_one_json_log_event() {
    let captured = Captured::default();
    qrpose::telemetry::init_with_writer(LogFormat::Json, captured.clone(), false)
        .expect("first subscriber");
    qrpose::telemetry::log_panics();
    let caught = std::panic::catch_unwind(|| panic!("decoder fell over"));
    assert!(caught.is_err());
    let text = String::from_utf8(captured.0.lock().expect("not poisoned").clone()).expect("utf-8");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 1, "{text}");
    let event: serde_json::Value = serde_json::from_str(lines[0]).expect("a JSON line");
    assert_eq!(event["level"], "ERROR", "{event}");
    assert_eq!(
        event["fields"]["message"], "contained panic: decoder fell over",
        "{event}"
    );
    let location = event["fields"]["location"].as_str().expect("a location");
    assert!(location.starts_with("tests/panic_log.rs:"), "{location}");
}
