use super::*;

#[test]
fn prefixes_cover_their_paths_and_nothing_beside_them() {
    let cases = [
        ("/v1/pose/corners", Access::Scope(Scope::Pose)),
        ("/v1/pose/image/annotated", Access::Scope(Scope::Pose)),
        ("/v1/pose", Access::Scope(Scope::Pose)),
        ("/v1/stream", Access::Scope(Scope::Pose)),
        ("/v1/calibrate", Access::Scope(Scope::Pose)),
        (
            "/v1/calibrate/anything-added-later",
            Access::Scope(Scope::Pose),
        ),
        ("/v1/site", Access::Scope(Scope::Site)),
        ("/v1/site/reload", Access::Scope(Scope::Admin)),
        ("/metrics", Access::Scope(Scope::Metrics)),
        ("/v1/poses", Access::AnyClient),
        ("/v1/sites", Access::AnyClient),
        ("/v1/unknown", Access::AnyClient),
        ("/v1", Access::AnyClient),
        ("/healthz", Access::Open),
        ("/readyz", Access::Open),
        ("/", Access::Open),
        ("/page/app.js", Access::Open),
        ("/docs/", Access::Open),
        ("/openapi.json", Access::Open),
        ("/asyncapi.json", Access::Open),
        ("/metricsx", Access::Open),
        ("/v1x/pose", Access::Open),
    ];
    for (path, access) in cases {
        assert_eq!(access_for(path), access, "{path}");
    }
}

fn headers(pairs: &[(&str, &str)]) -> HeaderMap {
    let mut map = HeaderMap::new();
    for (name, value) in pairs {
        map.append(
            axum::http::HeaderName::from_bytes(name.as_bytes()).expect("a name"),
            HeaderValue::from_str(value).expect("a value"),
        );
    }
    map
}

#[test]
fn tokens_come_from_the_bearer_header_or_a_websocket_subprotocol_only() {
    let cases: [(&[(&str, &str)], Presented<'_>); 10] = [
        (&[], Presented::None),
        (&[("authorization", "Bearer abc")], Presented::Token("abc")),
        (
            &[("authorization", "bearer  abc ")],
            Presented::Token("abc"),
        ),
        (&[("authorization", "Basic YWJjOg==")], Presented::Malformed),
        (&[("authorization", "Bearer ")], Presented::Malformed),
        (
            &[("authorization", "Bearer a"), ("authorization", "Bearer b")],
            Presented::Malformed,
        ),
        (
            &[
                ("upgrade", "websocket"),
                ("sec-websocket-protocol", "qrpose, bearer.tok_1"),
            ],
            Presented::Token("tok_1"),
        ),
        // Not an upgrade: the subprotocol header means nothing.
        (
            &[("sec-websocket-protocol", "bearer.tok_1")],
            Presented::None,
        ),
        (
            &[
                ("upgrade", "websocket"),
                ("sec-websocket-protocol", "qrpose"),
            ],
            Presented::None,
        ),
        // The header wins over the subprotocol.
        (
            &[
                ("authorization", "Bearer h"),
                ("upgrade", "WebSocket"),
                ("sec-websocket-protocol", "bearer.s"),
            ],
            Presented::Token("h"),
        ),
    ];
    for (pairs, presented) in cases {
        assert_eq!(presented_token(&headers(pairs)), presented, "{pairs:?}");
    }
}
