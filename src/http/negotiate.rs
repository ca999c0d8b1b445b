//! Content negotiation for the routes that answer with an image: which encoding an
//! `Accept` header asks for (RFC 9110 §12.5.1), by q-value, the most specific matching range
//! deciding each media type.

use crate::annotate::OutputFormat;
use axum::http::HeaderValue;

/// The encoding an `Accept` header asks for: PNG when it prefers `image/png` to
/// `image/jpeg` (by q-value, the most specific matching range deciding each); JPEG
/// otherwise, including when it names neither (the route then answers as if no `Accept`
/// was sent, RFC 9110 §12.5.1, rather than 406).
pub fn negotiate_format(accept: Option<&HeaderValue>) -> OutputFormat {
    let Some(accept) = accept.and_then(|v| v.to_str().ok()) else {
        return OutputFormat::Jpeg;
    };
    let quality = |media_type: &str| quality_of(accept, media_type);
    if quality("image/png") > quality("image/jpeg") {
        OutputFormat::Png
    } else {
        OutputFormat::Jpeg
    }
}

/// The q-value `accept` gives `media_type` (`type/subtype`, lower case): that of the most
/// specific range matching it (exact, then `type/*`, then `*/*`), 0 when none does.
fn quality_of(accept: &str, media_type: &str) -> f64 {
    let main_type = media_type.split('/').next().unwrap_or_default();
    let mut best: Option<(u8, f64)> = None;
    for range in accept.split(',') {
        let mut parts = range.split(';');
        let name = parts.next().unwrap_or_default().trim().to_ascii_lowercase();
        let specificity = if name == media_type {
            3
        } else if name.strip_suffix("/*") == Some(main_type) {
            2
        } else if name == "*/*" {
            1
        } else {
            continue;
        };
        let q = parts
            .filter_map(|p| p.trim().strip_prefix("q="))
            .find_map(|q| q.trim().parse::<f64>().ok())
            .filter(|q| (0.0..=1.0).contains(q))
            .unwrap_or(1.0);
        if best.is_none_or(|(s, _)| specificity > s) {
            best = Some((specificity, q));
        }
    }
    best.map_or(0.0, |(_, q)| q)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn format_for(accept: &str) -> OutputFormat {
        negotiate_format(Some(
            &HeaderValue::from_str(accept).expect("a header value"),
        ))
    }

    #[test]
    fn accept_chooses_png_only_when_it_prefers_png() {
        assert_eq!(negotiate_format(None), OutputFormat::Jpeg);
        for (accept, expected) in [
            ("image/png", OutputFormat::Png),
            ("IMAGE/PNG", OutputFormat::Png),
            ("image/png, image/jpeg", OutputFormat::Jpeg),
            ("image/jpeg;q=0.5, image/png", OutputFormat::Png),
            ("image/*;q=0.2, image/png;q=0.9", OutputFormat::Png),
            ("image/png;q=0.4, image/*", OutputFormat::Jpeg),
            ("image/png, */*;q=0.1", OutputFormat::Png),
            ("*/*", OutputFormat::Jpeg),
            ("application/json", OutputFormat::Jpeg),
            ("image/png;q=nonsense", OutputFormat::Png),
        ] {
            assert_eq!(format_for(accept), expected, "Accept: {accept}");
        }
    }
}
