//! A multipart image request that also has query parameters: the query's values and the
//! `request` part's, merged into one [`ImageRequest`].
//!
//! The rule, as documented on the operation: a field given in both is the part's; the
//! camera is taken whole from the part when the part has one (mixing the query's
//! intrinsics with the part's `camera.id` would be a camera in two forms), and the solver is
//! merged field by field. A problem whose `field` points at a value that came from the query
//! names the query parameter, as a raw-body request's would.
//!
//! Without query parameters the part is parsed exactly as before (its problems quote the
//! part's own line and column). Each query parameter given must be in its own range
//! ([`ImageQuery::check_values`]) even when the part overrides it: the document states the
//! parameter's range whatever the body, and the server refuses what it says is invalid.

use super::{ImageQuery, ImageRequest};
use crate::api::problem::{Problem, parse_json, parse_json_value};
use serde_json::{Map, Value};

/// The top-level key whose object is merged field by field; every other key of the part
/// replaces the query's value whole.
const MERGED_FIELD_BY_FIELD: &str = "solver";

/// A multipart body's request, and where its values came from.
#[derive(Debug, Clone, PartialEq)]
pub struct PartsRequest {
    /// The merged request.
    pub request: ImageRequest,
    /// The `request` part's object, when query parameters were merged under it.
    part: Option<Map<String, Value>>,
}

impl PartsRequest {
    /// `problem` (of this request's validation) with its `field` naming the query parameter
    /// when the value at fault came from the query.
    #[must_use]
    pub fn problem_as_sent(&self, problem: Problem) -> Problem {
        match &self.part {
            Some(part) => named_as_sent(problem, part),
            None => problem,
        }
    }
}

/// The request of a multipart body: its `request` part, with `query` (the query
/// parameters, when the URL has any) underneath.
///
/// # Errors
/// 400 `malformed_json` when the part is not JSON; the shape problems of [`ImageRequest`]
/// (422), naming a query parameter when the value came from the query.
pub fn request_of_parts(
    part_json: &[u8],
    query: Option<&ImageQuery>,
) -> Result<PartsRequest, Problem> {
    let alone = || {
        parse_json::<ImageRequest>(part_json).map(|request| PartsRequest {
            request,
            part: None,
        })
    };
    let Some(query) = query.filter(|q| **q != ImageQuery::default()) else {
        return alone();
    };
    // Each parameter is in its range even where the part overrides it.
    query.check_values()?;
    let Value::Object(part) = parse_json::<Value>(part_json)? else {
        // Not an object: the part alone says what is wrong with it.
        return alone();
    };
    let merged = merge(query_object(query), &part);
    match parse_json_value::<ImageRequest>(&Value::Object(merged)) {
        Ok(request) => Ok(PartsRequest {
            request,
            part: Some(part),
        }),
        Err(problem) => Err(named_as_sent(problem, &part)),
    }
}

/// The query's parameters as the JSON object of an [`ImageRequest`], only those given.
fn query_object(query: &ImageQuery) -> Map<String, Value> {
    let mut out = Map::new();
    let Ok(Value::Object(flat)) = serde_json::to_value(query) else {
        return out;
    };
    for (name, value) in flat {
        if value.is_null() {
            continue;
        }
        let pointer = ImageQuery::pointer_of_parameter(&name);
        insert_at(&mut out, &pointer, value);
    }
    out
}

/// Puts `value` at the JSON pointer `pointer` (of object keys) in `object`.
fn insert_at(object: &mut Map<String, Value>, pointer: &str, value: Value) {
    let mut keys: Vec<&str> = pointer.split('/').skip(1).collect();
    let Some(last) = keys.pop() else {
        return;
    };
    let mut target = object;
    for key in keys {
        let entry = target
            .entry(key.to_owned())
            .or_insert_with(|| Value::Object(Map::new()));
        let Value::Object(inner) = entry else {
            return;
        };
        target = inner;
    }
    target.insert(last.to_owned(), value);
}

/// `query` with `part` on top, by the module's rule.
fn merge(mut query: Map<String, Value>, part: &Map<String, Value>) -> Map<String, Value> {
    for (key, value) in part {
        match (query.get_mut(key), value) {
            (Some(Value::Object(below)), Value::Object(above)) if key == MERGED_FIELD_BY_FIELD => {
                for (k, v) in above {
                    below.insert(k.clone(), v.clone());
                }
            }
            _ => {
                query.insert(key.clone(), value.clone());
            }
        }
    }
    query
}

/// `problem` with its `field` naming the query parameter when the part has no value there
/// (the value came from the query).
fn named_as_sent(problem: Problem, part: &Map<String, Value>) -> Problem {
    let Some(field) = problem.field.as_deref() else {
        return problem;
    };
    let in_part =
        Value::Object(part.clone()).pointer(field).is_some() || part_has_parent_of(part, field);
    if in_part {
        return problem;
    }
    ImageQuery::problem_in_query_terms(problem)
}

/// Whether the part gave the object that holds `field` whole (the camera, taken from the
/// part when it has one): a missing field of the part's camera is the part's problem.
fn part_has_parent_of(part: &Map<String, Value>, field: &str) -> bool {
    let top = field.split('/').nth(1).unwrap_or_default();
    top != MERGED_FIELD_BY_FIELD && part.contains_key(top)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::problem::ErrorCode;
    use serde_json::json;

    fn query(pairs: &str) -> ImageQuery {
        serde_urlencoded::from_str(pairs).expect("a valid query")
    }

    fn part(value: Value) -> Vec<u8> {
        serde_json::to_vec(&value).expect("serialisable")
    }

    #[test]
    fn without_query_parameters_the_part_alone_is_the_request() {
        let body = part(
            json!({"camera": {"fx_px": 900, "fy_px": 900, "cx_px": 1, "cy_px": 2},
            "marker": {"size_mm": 40}}),
        );
        let alone = request_of_parts(&body, None).expect("valid").request;
        let empty = request_of_parts(&body, Some(&ImageQuery::default()))
            .expect("valid")
            .request;
        assert_eq!(alone, empty);
        assert_eq!(alone.camera.fx_px, Some(900.0));
    }

    #[test]
    fn the_part_wins_and_the_camera_comes_whole_from_the_part() {
        let body = part(json!({"camera": {"id": "front"}, "effort": "fast",
            "solver": {"gain": 1.5}}));
        let q = query(
            "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50&effort=thorough&method=paper&detector=rxing",
        );
        let merged = request_of_parts(&body, Some(&q)).expect("valid").request;
        assert_eq!(merged.camera.id.as_deref(), Some("front"));
        assert_eq!(merged.camera.fx_px, None, "no camera in two forms");
        assert_eq!(
            merged.marker.map(|m| m.size_mm),
            Some(50.0),
            "from the query"
        );
        assert_eq!(
            merged.effort,
            super::super::EffortDto::Fast,
            "the part wins"
        );
        assert_eq!(
            merged.detector,
            super::super::DetectorDto::Rxing,
            "from the query"
        );
        assert_eq!(merged.solver.method, crate::api::request::MethodDto::Paper);
        assert!(
            (merged.solver.gain - 1.5).abs() < 1e-12,
            "solver fields merged"
        );
    }

    #[test]
    fn the_query_alone_may_give_the_camera() {
        let body = part(json!({"marker": {"size_mm": 40}}));
        let q = query("fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&k1=-0.1");
        let merged = request_of_parts(&body, Some(&q)).expect("valid").request;
        assert_eq!(merged.camera.cx_px, Some(639.5));
        assert_eq!(merged.camera.distortion.map(|d| d.k1), Some(-0.1));
    }

    #[test]
    fn a_problem_names_where_its_value_came_from() {
        let body = part(json!({"marker": {"size_mm": 40}, "points": "finders"}));
        let q = query("fx_px=1000&fy_px=1000&cx_px=1&cy_px=1");
        // A bad value in the part: a pointer into the part.
        let bad_part = part(json!({"marker": {"size_mm": "big"}}));
        let p = request_of_parts(&bad_part, Some(&q)).expect_err("refused");
        assert_eq!(
            (p.code, p.field.as_deref()),
            (ErrorCode::InvalidType, Some("/marker/size_mm"))
        );
        // The part's own unknown field keeps its pointer.
        let typo = part(json!({"markr": {"size_mm": 40}}));
        let p = request_of_parts(&typo, Some(&q)).expect_err("refused");
        assert_eq!(
            (p.code, p.field.as_deref()),
            (ErrorCode::UnknownField, Some("/markr"))
        );
        // The query's value: the parameter's name, in validation's problems too.
        let parts = request_of_parts(&body, Some(&q)).expect("valid");
        assert_eq!(parts.request.camera.fx_px, Some(1000.0));
        let from_query =
            Problem::new(ErrorCode::InvalidCameraParameter, "x").with_field("/camera/fx_px");
        assert_eq!(
            parts.problem_as_sent(from_query).field.as_deref(),
            Some("fx_px")
        );
        let from_part = Problem::new(ErrorCode::PointsNeedReprojection, "x").with_field("/points");
        assert_eq!(
            parts.problem_as_sent(from_part).field.as_deref(),
            Some("/points")
        );
        let whole_camera = part(json!({"camera": {"fx_px": 5}, "marker": {"size_mm": 40}}));
        let parts = request_of_parts(&whole_camera, Some(&q)).expect("parses");
        let missing = Problem::new(ErrorCode::IncompleteCamera, "x").with_field("/camera/fy_px");
        assert_eq!(
            parts.problem_as_sent(missing).field.as_deref(),
            Some("/camera/fy_px"),
            "the part gave the camera"
        );
    }

    #[test]
    fn a_query_parameter_out_of_range_is_refused_where_the_part_overrides_it() {
        let body = part(
            json!({"camera": {"fx_px": 900, "fy_px": 900, "cx_px": 1, "cy_px": 2},
            "marker": {"size_mm": 40}, "solver": {"max_iterations": 30}, "max_detect_ms": 50}),
        );
        for (pairs, code, field) in [
            ("fx_px=-5", ErrorCode::InvalidCameraParameter, "fx_px"),
            (
                "pixel_size_um=0",
                ErrorCode::InvalidCameraParameter,
                "pixel_size_um",
            ),
            (
                "marker_size_mm=-1",
                ErrorCode::InvalidMarkerSize,
                "marker_size_mm",
            ),
            (
                "max_iterations=0",
                ErrorCode::SolverParameterOutOfRange,
                "max_iterations",
            ),
            (
                "max_detect_ms=0",
                ErrorCode::InvalidDetectionBudget,
                "max_detect_ms",
            ),
            ("camera_id=", ErrorCode::UnknownCamera, "camera_id"),
        ] {
            let p = request_of_parts(&body, Some(&query(pairs))).expect_err(pairs);
            assert_eq!((p.code, p.field.as_deref()), (code, Some(field)), "{pairs}");
        }
        let fine = query("fx_px=5&marker_size_mm=1&max_iterations=3&max_detect_ms=1");
        assert!(request_of_parts(&body, Some(&fine)).is_ok());
    }

    #[test]
    fn a_part_that_is_not_json_is_malformed_whatever_the_query() {
        let q = query("fx_px=1000");
        let p = request_of_parts(b"{not json", Some(&q)).expect_err("refused");
        assert_eq!(p.code, ErrorCode::MalformedJson);
        let p = request_of_parts(b"[1, 2]", Some(&q)).expect_err("refused");
        assert_eq!(p.code, ErrorCode::InvalidType);
    }
}
