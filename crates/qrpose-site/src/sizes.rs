//! Marker sizes by payload: the rules of the site file's `markers` section, looked up in
//! their written order (first match wins), then the default. A size given in the request
//! beats them all (`docs/site.md`, Marker sizes).

use crate::file::{Matcher, SizeRule};

/// Where a marker's size came from; `as_str` is the wire name (`marker_size_source`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SizeSource {
    /// The request's `marker.size_mm` / `marker_size_mm`.
    Request,
    /// A site rule `payload:` equal to the payload.
    SiteExact,
    /// A site rule `prefix:` that the payload starts with.
    SitePrefix,
    /// A site rule `pattern:` that matches the payload.
    SitePattern,
    /// The site's `default_size_mm`.
    SiteDefault,
}

impl SizeSource {
    /// The wire name: `request`, `site:exact`, `site:prefix`, `site:pattern`,
    /// `site:default`.
    pub const fn as_str(self) -> &'static str {
        match self {
            SizeSource::Request => "request",
            SizeSource::SiteExact => "site:exact",
            SizeSource::SitePrefix => "site:prefix",
            SizeSource::SitePattern => "site:pattern",
            SizeSource::SiteDefault => "site:default",
        }
    }
}

/// A size and where it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizeLookup {
    /// The side of the symbol, mm.
    pub size_mm: f64,
    /// Its source.
    pub source: SizeSource,
}

/// The site's size rules and default.
#[derive(Debug, Clone, Default)]
pub struct MarkerSizes {
    /// The size of a code no rule matches, mm.
    pub default_size_mm: Option<f64>,
    /// The rules, in the file's order.
    pub rules: Vec<SizeRule>,
}

impl MarkerSizes {
    /// The size of the code with `payload` (`None`: a code that was not decoded, which only
    /// the default can size): the first rule that matches, else the default, else `None`.
    pub fn lookup(&self, payload: Option<&str>) -> Option<SizeLookup> {
        let by_rule = payload.and_then(|p| {
            self.rules
                .iter()
                .find(|r| r.matcher.matches(p))
                .map(|r| SizeLookup {
                    size_mm: r.size_mm,
                    source: match r.matcher {
                        Matcher::Exact(_) => SizeSource::SiteExact,
                        Matcher::Prefix(_) => SizeSource::SitePrefix,
                        Matcher::Pattern(_) => SizeSource::SitePattern,
                    },
                })
        });
        by_rule.or_else(|| {
            self.default_size_mm.map(|size_mm| SizeLookup {
                size_mm,
                source: SizeSource::SiteDefault,
            })
        })
    }
}

/// The size to use: the request's when it gives one, else the site's for `payload`.
pub fn resolve_size(
    request_size_mm: Option<f64>,
    sizes: Option<&MarkerSizes>,
    payload: Option<&str>,
) -> Option<SizeLookup> {
    match request_size_mm {
        Some(size_mm) => Some(SizeLookup {
            size_mm,
            source: SizeSource::Request,
        }),
        None => sizes.and_then(|s| s.lookup(payload)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sizes() -> MarkerSizes {
        let rule = |matcher, size_mm| SizeRule { matcher, size_mm };
        MarkerSizes {
            default_size_mm: Some(50.0),
            rules: vec![
                rule(Matcher::Exact("DOCK-7".into()), 120.0),
                rule(Matcher::Prefix("TOTE-".into()), 40.0),
                rule(
                    Matcher::Pattern(regex::Regex::new("^LOC-[0-9]{4}$").expect("regex")),
                    80.0,
                ),
                // Shadowed by the prefix rule above: first match wins.
                rule(Matcher::Exact("TOTE-1".into()), 99.0),
            ],
        }
    }

    #[test]
    fn the_first_matching_rule_wins_then_the_default() {
        let s = sizes();
        let cases = [
            (Some("DOCK-7"), 120.0, SizeSource::SiteExact),
            (Some("TOTE-1"), 40.0, SizeSource::SitePrefix),
            (Some("LOC-0001"), 80.0, SizeSource::SitePattern),
            (Some("LOC-00011"), 50.0, SizeSource::SiteDefault),
            (Some("DOCK-77"), 50.0, SizeSource::SiteDefault),
            (None, 50.0, SizeSource::SiteDefault),
        ];
        for (payload, size_mm, source) in cases {
            assert_eq!(
                s.lookup(payload),
                Some(SizeLookup { size_mm, source }),
                "{payload:?}"
            );
        }
    }

    #[test]
    fn without_a_default_an_unmatched_code_has_no_size() {
        let s = MarkerSizes {
            default_size_mm: None,
            ..sizes()
        };
        assert_eq!(s.lookup(Some("SKU-1")), None);
        assert_eq!(s.lookup(None), None);
    }

    #[test]
    fn the_request_size_beats_the_site() {
        let s = sizes();
        let r = resolve_size(Some(33.0), Some(&s), Some("DOCK-7")).expect("a size");
        assert_eq!((r.size_mm, r.source.as_str()), (33.0, "request"));
        let r = resolve_size(None, Some(&s), Some("DOCK-7")).expect("a size");
        assert_eq!((r.size_mm, r.source.as_str()), (120.0, "site:exact"));
        assert_eq!(resolve_size(None, None, Some("DOCK-7")), None);
    }
}
