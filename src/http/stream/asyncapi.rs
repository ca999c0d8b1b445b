//! The stream's messages as an AsyncAPI 3 document (`openapi/asyncapi.json`, `qrpose
//! asyncapi`, `GET /asyncapi.json`): the channel `GET /v1/stream`, its query parameters (the
//! WebSocket binding's `query`), the messages a client sends (frames, their meta) and those
//! it receives (answers, problems). The schemas are the DTOs' own (`api::stream`), derived as
//! for the OpenAPI document, so the two documents cannot disagree; a test validates the
//! answers a real session sends against them.

use crate::api::alternatives::{Rule, rules};
use crate::api::image::ImageQuery;
use crate::api::problem::Problem;
use crate::api::stream::{FrameMetaDto, FrameProblem, StreamAnswer, TrackQuery};
use crate::http::auth::{BEARER_SUBPROTOCOL_PREFIX, STREAM_SUBPROTOCOL};
use crate::http::error::ApiError;
use crate::http::openapi::security::{SCHEME, scheme_description};
use crate::http::openapi::{Rendered, Served, openapi, serve_document, write_alternatives};
use crate::http::state::AppState;
use axum::extract::State;
use axum::response::IntoResponse;
use serde_json::{Map, Value, json};
use std::sync::OnceLock;
use utoipa::{IntoParams, OpenApi};

/// The components the stream's messages refer to.
#[derive(OpenApi)]
#[openapi(components(schemas(StreamAnswer, FrameProblem, FrameMetaDto, Problem)))]
struct StreamSchemas;

/// The schemas the messages refer to directly.
const ROOTS: [&str; 3] = ["StreamAnswer", "FrameProblem", "FrameMetaDto"];

/// The names of the schemas `value` refers to.
fn references(value: &Value) -> Vec<String> {
    let text = value.to_string();
    text.split("\"$ref\":\"#/components/schemas/")
        .skip(1)
        .filter_map(|r| r.split('"').next().map(str::to_owned))
        .collect()
}

/// The schemas of `all` that `roots` and the query's schema reach through `$ref`s, in
/// `all`'s order.
fn reachable(all: &Value, roots: &[&str], query: &Value) -> Value {
    let mut seen: Vec<String> = Vec::new();
    let mut stack: Vec<String> = roots.iter().map(|r| (*r).to_owned()).collect();
    stack.extend(references(query));
    while let Some(name) = stack.pop() {
        if seen.contains(&name) {
            continue;
        }
        let Some(schema) = all.get(&name) else {
            continue;
        };
        stack.extend(references(schema));
        seen.push(name);
    }
    let kept: Map<String, Value> = all
        .as_object()
        .into_iter()
        .flatten()
        .filter(|(name, _)| seen.contains(name))
        .map(|(name, schema)| (name.clone(), schema.clone()))
        .collect();
    Value::Object(kept)
}

/// Where the AsyncAPI document is served.
pub const ASYNCAPI_PATH: &str = "/asyncapi.json";

/// The query parameters of the stream as one object schema (the WebSocket binding's
/// `query`), as `served` accepts them.
fn query_schema(served: Served) -> Value {
    let mut properties = Map::new();
    let refused: Vec<&str> = rules(served.site, served.zxing_cpp)
        .into_iter()
        .filter_map(|rule| match rule {
            Rule::NoParameter(name) => Some(name),
            _ => None,
        })
        .collect();
    let parameters = ImageQuery::into_params(|| None)
        .into_iter()
        .chain(TrackQuery::into_params(|| None))
        .filter(|p| !refused.contains(&p.name.as_str()));
    for p in parameters {
        let mut schema = serde_json::to_value(&p.schema).unwrap_or(Value::Null);
        if let (Some(description), Some(map)) = (&p.description, schema.as_object_mut()) {
            map.insert("description".to_owned(), json!(description));
        }
        properties.insert(p.name, schema);
    }
    json!({"type": "object", "properties": properties, "additionalProperties": false})
}

/// The AsyncAPI document of a server configured as `served`, as pretty JSON with a final
/// newline.
///
/// # Errors
/// Only if the document cannot be serialised, which a derived document always can.
pub fn asyncapi_json(served: Served) -> Result<String, serde_json::Error> {
    // Every schema of the service (some the stream's types refer to are collected only
    // through the routes), the stream's own, and the alternatives written in, as for the
    // OpenAPI document; then only those the messages reach.
    let mut doc = serde_json::to_value(openapi())?;
    let stream = serde_json::to_value(StreamSchemas::openapi())?;
    if let (Some(all), Some(own)) = (
        doc.pointer_mut("/components/schemas")
            .and_then(Value::as_object_mut),
        stream["components"]["schemas"].as_object(),
    ) {
        for (name, schema) in own {
            all.entry(name.clone()).or_insert_with(|| schema.clone());
        }
    }
    write_alternatives(&mut doc, served);
    let query = query_schema(served);
    let schemas = reachable(&doc["components"]["schemas"], &ROOTS, &query);
    let message = |name: &str, title: &str, content_type: &str, payload: Value| {
        (
            name.to_owned(),
            json!({"name": name, "title": title, "contentType": content_type, "payload": payload}),
        )
    };
    let messages: Map<String, Value> = [
        message(
            "frameMeta",
            "The next frame's id, capture time and prior (text, optional)",
            "application/json",
            json!({"$ref": "#/components/schemas/FrameMetaDto"}),
        ),
        message(
            "frame",
            "A frame: JPEG or PNG bytes (binary)",
            "application/octet-stream",
            json!({"type": "string", "format": "binary"}),
        ),
        message(
            "answer",
            "The answer to one frame, in the order received (text)",
            "application/json",
            json!({"$ref": "#/components/schemas/StreamAnswer"}),
        ),
        message(
            "frameProblem",
            "A frame or text message that cannot be used: its problem (text)",
            "application/problem+json",
            json!({"$ref": "#/components/schemas/FrameProblem"}),
        ),
    ]
    .into_iter()
    .collect();
    let channel_message =
        |name: &str| json!({"$ref": format!("#/channels/stream/messages/{name}")});
    let mut doc = json!({
        "asyncapi": "3.0.0",
        "info": {
            "title": "qrpose stream",
            "version": env!("CARGO_PKG_VERSION"),
            "description": "Frames in, one answer per frame out, with tracks (docs/stream.md). \
                The session closes with 1000 (normal), 1001 (server shutting down), 1008 (a \
                limit: message size, idle time) or 1013 (too many sessions; try again later).",
        },
        "servers": {
            "local": {"host": "127.0.0.1:8080", "protocol": "ws",
                "description": "qrpose serve with its defaults (wss with TLS)"},
        },
        "channels": {
            "stream": {
                "address": "/v1/stream",
                "messages": messages.keys().map(|k| (k.clone(), json!({"$ref": format!("#/components/messages/{k}")}))).collect::<Map<String, Value>>(),
                "bindings": {"ws": {"method": "GET", "query": query}},
            },
        },
        "operations": {
            "receiveFrames": {
                "action": "receive",
                "summary": "The client sends frames, each optionally preceded by its meta.",
                "channel": {"$ref": "#/channels/stream"},
                "messages": [channel_message("frameMeta"), channel_message("frame")],
            },
            "sendAnswers": {
                "action": "send",
                "summary": "The service answers each frame, in order.",
                "channel": {"$ref": "#/channels/stream"},
                "messages": [channel_message("answer"), channel_message("frameProblem")],
            },
        },
        "components": {"messages": messages, "schemas": schemas},
    });
    if served.auth {
        declare_asyncapi_security(&mut doc);
    }
    serde_json::to_string_pretty(&doc).map(|json| json + "\n")
}

/// Declares how a stream session carries its token in the AsyncAPI document: the bearer
/// header, or for a browser the subprotocol `bearer.TOKEN` offered beside `qrpose`.
pub fn declare_asyncapi_security(doc: &mut Value) {
    if let Some(components) = doc.get_mut("components").and_then(Value::as_object_mut) {
        components.insert(
            "securitySchemes".to_owned(),
            json!({
                SCHEME: {"type": "http", "scheme": "bearer",
                    "description": format!("{} The stream needs `pose`.", scheme_description())},
                "subprotocol": {"type": "httpApiKey", "in": "header", "name": "Sec-WebSocket-Protocol",
                    "description": format!("For a browser, which cannot set headers on a WebSocket: \
                        offer the subprotocols `{STREAM_SUBPROTOCOL}` and \
                        `{BEARER_SUBPROTOCOL_PREFIX}TOKEN` (new WebSocket(url, [\"{STREAM_SUBPROTOCOL}\", \
                        \"{BEARER_SUBPROTOCOL_PREFIX}\" + token])); the answer selects \
                        `{STREAM_SUBPROTOCOL}`. Never put the token in the query string.")},
            }),
        );
    }
    let requirements = json!([
        {"$ref": format!("#/components/securitySchemes/{SCHEME}")},
        {"$ref": "#/components/securitySchemes/subprotocol"},
    ]);
    if let Some(servers) = doc.get_mut("servers").and_then(Value::as_object_mut) {
        for server in servers.values_mut().filter_map(Value::as_object_mut) {
            server.insert("security".to_owned(), requirements.clone());
        }
    }
}

/// The AsyncAPI 3 document of `GET /v1/stream`'s messages, as this server is configured
/// (identical to `qrpose asyncapi`, or `qrpose asyncapi --site` when a site is loaded).
#[utoipa::path(
    get,
    path = "/asyncapi.json",
    tag = "operations",
    operation_id = "asyncapi_json",
    responses((status = 200, description = "The AsyncAPI 3.0 document of the stream.",
        body = Object, content_type = "application/json"))
)]
pub async fn serve_asyncapi_json(
    State(state): State<AppState>,
) -> Result<impl IntoResponse, ApiError> {
    static DOCUMENTS: Rendered = [const { OnceLock::new() }; 8];
    serve_document(&DOCUMENTS, Served::by(&state), asyncapi_json)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_message_and_reference_resolves() {
        let doc: Value = serde_json::from_str(&asyncapi_json(Served::default()).expect("renders"))
            .expect("JSON");
        let text = doc.to_string();
        for reference in text.split("\"$ref\":\"").skip(1) {
            let pointer = reference
                .split('"')
                .next()
                .and_then(|r| r.strip_prefix('#'))
                .expect("a local reference");
            assert!(doc.pointer(pointer).is_some(), "{pointer} does not resolve");
        }
        let query = &doc["channels"]["stream"]["bindings"]["ws"]["query"]["properties"];
        assert!(query["coast_ms"].is_object() && query["fx_px"].is_object());
        assert!(query.get("camera_id").is_none(), "no site, no camera id");
    }
}
