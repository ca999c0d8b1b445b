//! Refused input of `qrpose-sim`, as the service's problem documents are shaped
//! (`type`, `title`, `status`, `detail`, `code`, `field`): scripts read both alike.

use serde_json::{Value, json};

/// A refusal: a stable snake_case `code`, what is wrong, and the field at fault.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    /// The stable code (`invalid_type`, `missing_field`, …).
    pub code: &'static str,
    /// What is wrong, for a person.
    pub detail: String,
    /// The field at fault: a flag's name or a JSON pointer into a file.
    pub field: Option<String>,
}

impl Problem {
    /// A problem with `code` and `detail`, no field.
    #[must_use]
    pub fn new(code: &'static str, detail: impl Into<String>) -> Self {
        Self {
            code,
            detail: detail.into(),
            field: None,
        }
    }

    /// The same problem naming `field`.
    #[must_use]
    pub fn with_field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }

    /// A JSON file that did not fit its type: `malformed_json` when it is not JSON; else
    /// `missing_field` (the pointer then ends with the missing field), `unknown_field`,
    /// `unknown_variant`, or `invalid_type`, at the path where serde stopped. serde_json
    /// keeps only a message, so the kind is read from its first words here, in this one
    /// place, and pinned by the tests below.
    #[must_use]
    pub fn from_json_error(err: &serde_path_to_error::Error<serde_json::Error>) -> Self {
        let message = err.inner().to_string();
        if err.inner().classify() != serde_json::error::Category::Data {
            return Self::new("malformed_json", message);
        }
        let mut pointer = String::new();
        for segment in err.path().iter() {
            let token = match segment {
                serde_path_to_error::Segment::Seq { index } => index.to_string(),
                serde_path_to_error::Segment::Map { key } => key.clone(),
                serde_path_to_error::Segment::Enum { variant } => variant.clone(),
                serde_path_to_error::Segment::Unknown => continue,
            };
            pointer.push('/');
            pointer.push_str(&token.replace('~', "~0").replace('/', "~1"));
        }
        let backticked = message.split('`').nth(1).unwrap_or_default().to_owned();
        let code = if message.starts_with("missing field") {
            pointer = format!("{pointer}/{backticked}");
            "missing_field"
        } else if message.starts_with("unknown field") {
            "unknown_field"
        } else if message.starts_with("unknown variant") {
            "unknown_variant"
        } else {
            "invalid_type"
        };
        Self::new(code, message).with_field(pointer)
    }

    /// The problem document, pretty-printed.
    #[must_use]
    pub fn to_json_pretty(&self) -> String {
        let document: Value = json!({
            "type": format!("urn:qrpose:problem:{}", self.code),
            "title": "Refused input",
            "status": 422,
            "detail": self.detail,
            "code": self.code,
            "field": self.field,
        });
        serde_json::to_string_pretty(&document).unwrap_or_else(|_| self.detail.clone())
    }
}

/// Parses `bytes` as JSON of type `T`; a refusal as [`Problem::from_json_error`] says.
///
/// # Errors
/// A problem naming what did not fit.
pub fn parse_json<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, Problem> {
    let mut deserializer = serde_json::Deserializer::from_slice(bytes);
    serde_path_to_error::deserialize(&mut deserializer).map_err(|e| Problem::from_json_error(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct File {
        #[allow(dead_code)]
        codes: Vec<Code>,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Code {
        size_mm: f64,
        kind: Kind,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(rename_all = "snake_case")]
    enum Kind {
        Suction,
    }

    fn refusal(text: &str) -> Problem {
        parse_json::<File>(text.as_bytes()).expect_err("refused")
    }

    #[test]
    fn each_kind_of_shape_error_has_its_code_and_pointer() {
        let missing = refusal(r#"{"codes": [{"kind": "suction"}]}"#);
        assert_eq!(missing.code, "missing_field");
        assert_eq!(missing.field.as_deref(), Some("/codes/0/size_mm"));
        let unknown = refusal(r#"{"codes": [{"size_mm": 1, "kind": "suction", "x": 1}]}"#);
        assert_eq!(unknown.code, "unknown_field");
        assert_eq!(unknown.field.as_deref(), Some("/codes/0/x"));
        let variant = refusal(r#"{"codes": [{"size_mm": 1, "kind": "jaw"}]}"#);
        assert_eq!(variant.code, "unknown_variant");
        assert_eq!(variant.field.as_deref(), Some("/codes/0/kind"));
        let wrong = refusal(r#"{"codes": [{"size_mm": "1", "kind": "suction"}]}"#);
        assert_eq!(wrong.code, "invalid_type");
        assert_eq!(wrong.field.as_deref(), Some("/codes/0/size_mm"));
        assert_eq!(refusal("{\"codes\": [").code, "malformed_json");
    }

    #[test]
    fn the_document_has_the_services_fields() {
        let text = Problem::new("invalid_type", "no")
            .with_field("/a")
            .to_json_pretty();
        let value: Value = serde_json::from_str(&text).expect("JSON");
        assert_eq!(value["type"], "urn:qrpose:problem:invalid_type");
        assert_eq!(value["code"], "invalid_type");
        assert_eq!(value["field"], "/a");
        assert_eq!(value["status"], 422);
    }
}
