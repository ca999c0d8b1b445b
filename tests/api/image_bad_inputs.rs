//! `POST /v1/pose/image`: a catalogue of bad requests in both forms. Each gets its 4xx
//! problem+json with the right code (and field, where one is at fault), and the server stays
//! up.

use crate::helpers::{
    BOUNDARY, PHOTO_QUERY, Part, image_part, multipart_body, photo_jpeg, photo_request,
    request_part, spawn_app,
};
use qrpose::api::problem::ErrorCode::{self, *};
use qrpose::api::problem::Problem;
use qrpose::detect::Backend;
use reqwest::header;
use serde_json::{Value, json};

/// One bad request and the expected answer.
struct Case {
    name: &'static str,
    query: String,
    body: Vec<u8>,
    content_type: Option<String>,
    code: ErrorCode,
    field: Option<&'static str>,
}

const JPEG: Option<&str> = Some("image/jpeg");

/// A raw-body case: `query` after the photo's own parameters (`&...`), or instead of them
/// (anything else).
fn raw(
    name: &'static str,
    query: &str,
    body: Vec<u8>,
    content_type: Option<&str>,
    code: ErrorCode,
    field: Option<&'static str>,
) -> Case {
    let query = match query.strip_prefix('&') {
        Some(extra) => format!("{PHOTO_QUERY}&{extra}"),
        None => query.to_owned(),
    };
    Case {
        name,
        query,
        body,
        content_type: content_type.map(str::to_owned),
        code,
        field,
    }
}

/// A multipart case.
fn multipart(
    name: &'static str,
    parts: &[Part<'_>],
    code: ErrorCode,
    field: Option<&'static str>,
) -> Case {
    Case {
        name,
        query: String::new(),
        body: multipart_body(parts),
        content_type: Some(format!("multipart/form-data; boundary={BOUNDARY}")),
        code,
        field,
    }
}

/// The photo's request part with the value at `pointer` replaced (removed for `Null`).
fn request_with(pointer: &str, value: Value) -> Vec<u8> {
    let mut request = photo_request();
    let (parent, key) = pointer.rsplit_once('/').expect("a pointer");
    let target = if parent.is_empty() {
        &mut request
    } else {
        request.pointer_mut(parent).expect("the parent exists")
    };
    let map = target.as_object_mut().expect("an object");
    if value.is_null() {
        map.remove(key);
    } else {
        map.insert(key.to_owned(), value);
    }
    serde_json::to_vec(&request).expect("serialisable")
}

/// The photo with the frame header's dimensions set to 65535 x 65535, the largest a JPEG can
/// declare (4.3 gigapixels); every table stays intact, so only the size is wrong.
fn jpeg_declaring_65535_squared() -> Vec<u8> {
    let mut jpeg = photo_jpeg();
    let sof = jpeg
        .windows(2)
        .position(|w| w[0] == 0xFF && (w[1] == 0xC0 || w[1] == 0xC2))
        .expect("a frame header");
    // FF C0, length (2), precision (1), height (2), width (2).
    jpeg[sof + 5..sof + 9].copy_from_slice(&[0xFF, 0xFF, 0xFF, 0xFF]);
    jpeg
}

/// A PNG signature and IHDR chunk declaring 100000 x 100000 pixels, and nothing else.
fn png_declaring_100000_squared() -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend_from_slice(&13u32.to_be_bytes());
    png.extend_from_slice(b"IHDR");
    png.extend_from_slice(&100_000u32.to_be_bytes());
    png.extend_from_slice(&100_000u32.to_be_bytes());
    png.extend_from_slice(&[8, 0, 0, 0, 0]);
    png.extend_from_slice(&[0, 0, 0, 0]);
    png
}

fn catalogue() -> Vec<Case> {
    let jpeg = photo_jpeg();
    let request = serde_json::to_vec(&photo_request()).expect("serialisable");
    let random: Vec<u8> = (0..20_000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13).to_le_bytes()[0])
        .collect();
    let mut random_after_jpeg_magic = vec![0xFF, 0xD8, 0xFF];
    random_after_jpeg_magic.extend_from_slice(&random);
    // Cut inside the header segments (quantisation and Huffman tables).
    let truncated_in_headers = jpeg[..300].to_vec();
    // Cut inside the entropy-coded scan: a lenient decoder paints the rest grey.
    let truncated_in_scan = jpeg[..jpeg.len() * 7 / 10].to_vec();
    let mut cases = vec![
        raw(
            "zero detection deadline",
            "&max_detect_ms=0",
            jpeg.clone(),
            JPEG,
            InvalidDetectionBudget,
            Some("max_detect_ms"),
        ),
        raw(
            "unknown effort",
            "&effort=maximal",
            jpeg.clone(),
            JPEG,
            UnknownVariant,
            Some("effort"),
        ),
        multipart(
            "negative detection deadline in the request part",
            &[
                image_part(&jpeg),
                request_part(&request_with("/max_detect_ms", json!(-1.0))),
            ],
            InvalidDetectionBudget,
            Some("/max_detect_ms"),
        ),
        raw("empty body", "&", Vec::new(), JPEG, UndecodableImage, None),
        raw(
            "random bytes as JPEG",
            "&",
            random.clone(),
            JPEG,
            UndecodableImage,
            None,
        ),
        raw(
            "random bytes after the JPEG magic",
            "&",
            random_after_jpeg_magic,
            JPEG,
            UndecodableImage,
            None,
        ),
        raw(
            "JPEG truncated in its headers",
            "&",
            truncated_in_headers,
            JPEG,
            UndecodableImage,
            None,
        ),
        raw(
            "JPEG truncated in its scan",
            "&",
            truncated_in_scan,
            JPEG,
            UndecodableImage,
            None,
        ),
        raw(
            "a GIF",
            "&",
            b"GIF89a\x01\x00\x01\x00".to_vec(),
            Some("image/png"),
            UndecodableImage,
            None,
        ),
        raw(
            "PNG header declaring 100000x100000 px",
            "&",
            png_declaring_100000_squared(),
            Some("image/png"),
            ImageTooLarge,
            None,
        ),
        raw(
            "JPEG header declaring 65535x65535 px",
            "&",
            jpeg_declaring_65535_squared(),
            JPEG,
            ImageTooLarge,
            None,
        ),
        raw(
            "a 30 MB body",
            "&",
            vec![0; 30_000_000],
            JPEG,
            PayloadTooLarge,
            None,
        ),
        raw(
            "wrong content type",
            "&",
            jpeg.clone(),
            Some("application/octet-stream"),
            UnsupportedMediaType,
            None,
        ),
        raw(
            "JSON content type",
            "&",
            request.clone(),
            Some("application/json"),
            UnsupportedMediaType,
            None,
        ),
        raw(
            "no content type",
            "&",
            jpeg.clone(),
            None,
            UnsupportedMediaType,
            None,
        ),
        raw(
            "no query parameters",
            "",
            jpeg.clone(),
            JPEG,
            MissingField,
            Some("marker_size_mm"),
        ),
        raw(
            "missing marker size",
            "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5",
            jpeg.clone(),
            JPEG,
            MissingField,
            Some("marker_size_mm"),
        ),
        raw(
            "no camera",
            "marker_size_mm=50",
            jpeg.clone(),
            JPEG,
            IncompleteCamera,
            None,
        ),
        raw(
            "missing principal point",
            "fx_px=1000&fy_px=1000&cx_px=639.5&marker_size_mm=50",
            jpeg.clone(),
            JPEG,
            IncompleteCamera,
            Some("cy_px"),
        ),
        raw(
            "a focal length that is not a number",
            "fx_px=wide&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50",
            jpeg.clone(),
            JPEG,
            MalformedQuery,
            Some("fx_px"),
        ),
        raw(
            "an empty value",
            "fx_px=&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50",
            jpeg.clone(),
            JPEG,
            MalformedQuery,
            Some("fx_px"),
        ),
        raw(
            "a parameter twice",
            "&marker_size_mm=40",
            jpeg.clone(),
            JPEG,
            MalformedQuery,
            Some("marker_size_mm"),
        ),
        raw(
            "NaN focal length",
            "fx_px=NaN&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50",
            jpeg.clone(),
            JPEG,
            NonFiniteNumber,
            Some("fx_px"),
        ),
        raw(
            "negative focal length",
            "fx_px=-1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50",
            jpeg.clone(),
            JPEG,
            InvalidCameraParameter,
            Some("fx_px"),
        ),
        raw(
            "zero marker size",
            "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=0",
            jpeg.clone(),
            JPEG,
            InvalidMarkerSize,
            Some("marker_size_mm"),
        ),
        raw(
            "unknown parameter",
            "&marker_size=50",
            jpeg.clone(),
            JPEG,
            UnknownField,
            Some("marker_size"),
        ),
        raw(
            "unknown method",
            "&method=magic",
            jpeg.clone(),
            JPEG,
            UnknownVariant,
            Some("method"),
        ),
        raw(
            "unknown detector",
            "&detector=opencv",
            jpeg.clone(),
            JPEG,
            UnknownVariant,
            Some("detector"),
        ),
        raw(
            "finders with the paper's method",
            "&points=finders&method=paper",
            jpeg.clone(),
            JPEG,
            PointsNeedReprojection,
            Some("points"),
        ),
        raw(
            "absurd iteration count",
            "&max_iterations=1000000000000",
            jpeg.clone(),
            JPEG,
            SolverParameterOutOfRange,
            Some("max_iterations"),
        ),
        raw(
            "negative iteration count",
            "&max_iterations=-5",
            jpeg.clone(),
            JPEG,
            MalformedQuery,
            Some("max_iterations"),
        ),
        Case {
            content_type: Some("multipart/form-data".to_owned()),
            ..multipart(
                "multipart without a boundary",
                &[image_part(&jpeg), request_part(&request)],
                MalformedMultipart,
                None,
            )
        },
        Case {
            body: b"this is not a multipart body".to_vec(),
            ..multipart("multipart garbage", &[], MalformedMultipart, None)
        },
        Case {
            body: {
                let mut cut = multipart_body(&[image_part(&jpeg), request_part(&request)]);
                cut.truncate(cut.len() / 2);
                cut
            },
            ..multipart(
                "multipart cut short",
                &[],
                MalformedMultipart,
                Some("image"),
            )
        },
        multipart(
            "multipart without the image",
            &[request_part(&request)],
            MissingField,
            Some("image"),
        ),
        multipart(
            "multipart without the request",
            &[image_part(&jpeg)],
            MissingField,
            Some("request"),
        ),
        multipart(
            "multipart with an unknown part",
            &[
                image_part(&jpeg),
                request_part(&request),
                Part {
                    name: Some("camera"),
                    content_type: "application/json",
                    bytes: b"{}",
                },
            ],
            UnknownField,
            Some("camera"),
        ),
        multipart(
            "multipart with the image twice",
            &[image_part(&jpeg), image_part(&jpeg), request_part(&request)],
            MalformedMultipart,
            Some("image"),
        ),
        multipart(
            "multipart with a part without a name",
            &[
                Part {
                    name: None,
                    content_type: "image/jpeg",
                    bytes: &jpeg,
                },
                request_part(&request),
            ],
            MalformedMultipart,
            None,
        ),
        multipart(
            "multipart with random bytes as the image",
            &[image_part(&random), request_part(&request)],
            UndecodableImage,
            None,
        ),
        multipart(
            "multipart with an empty image",
            &[image_part(b""), request_part(&request)],
            UndecodableImage,
            None,
        ),
        multipart(
            "request part not JSON",
            &[image_part(&jpeg), request_part(b"{\"camera\": ")],
            MalformedJson,
            None,
        ),
        multipart(
            "request part with corners",
            &[
                image_part(&jpeg),
                request_part(&request_with(
                    "/corners_px",
                    json!([[0, 0], [1, 0], [1, 1], [0, 1]]),
                )),
            ],
            UnknownField,
            Some("/corners_px"),
        ),
        multipart(
            "request part without a marker",
            &[
                image_part(&jpeg),
                request_part(&request_with("/marker", Value::Null)),
            ],
            MissingField,
            Some("/marker"),
        ),
        multipart(
            "request part with a zero focal length",
            &[
                image_part(&jpeg),
                request_part(&request_with("/camera/fx_px", json!(0.0))),
            ],
            InvalidCameraParameter,
            Some("/camera/fx_px"),
        ),
        multipart(
            "request part with an unknown detector",
            &[
                image_part(&jpeg),
                request_part(&request_with("/detector", json!("opencv"))),
            ],
            UnknownVariant,
            Some("/detector"),
        ),
        // Query parameters with a multipart body are merged under the part; a
        // refused value that came from the query is named by its parameter.
        Case {
            query: "fx_px=-5&fy_px=1000&cx_px=639.5&cy_px=359.5".to_owned(),
            ..multipart(
                "multipart with the camera in the query, refused",
                &[
                    image_part(&jpeg),
                    request_part(&request_with("/camera", Value::Null)),
                ],
                InvalidCameraParameter,
                Some("fx_px"),
            )
        },
        Case {
            query: "fx_px=one".to_owned(),
            ..multipart(
                "multipart with a malformed query parameter",
                &[image_part(&jpeg), request_part(&request)],
                MalformedQuery,
                Some("fx_px"),
            )
        },
        Case {
            query: "fx_px=1000".to_owned(),
            ..multipart(
                "multipart with a refused part under a query",
                &[
                    image_part(&jpeg),
                    request_part(&request_with("/detector", json!("opencv"))),
                ],
                UnknownVariant,
                Some("/detector"),
            )
        },
    ];
    if !Backend::ZxingCpp.is_built() {
        cases.push(raw(
            "zxing-cpp in a build without it",
            "&detector=zxing-cpp",
            jpeg,
            JPEG,
            DetectorUnavailable,
            Some("detector"),
        ));
    }
    cases
}

#[tokio::test]
async fn every_bad_request_gets_its_4xx_problem_and_the_server_stays_up() {
    // Arrange
    let app = spawn_app().await;
    let cases = catalogue();
    assert!(cases.len() >= 25, "the catalogue has {} cases", cases.len());

    for case in cases {
        // Act
        let response = app
            .post_image(&case.query, case.body, case.content_type.as_deref())
            .await;

        // Assert
        let name = case.name;
        let status = response.status().as_u16();
        assert!((400..500).contains(&status), "{name}: {status}");
        let content_type = response.headers()[header::CONTENT_TYPE].clone();
        assert_eq!(content_type, "application/problem+json", "{name}");
        let problem: Problem = response.json().await.expect("a problem document");
        assert_eq!(
            (status, problem.code, problem.field.as_deref()),
            (case.code.status(), case.code, case.field),
            "{name}: {problem:?}"
        );
        assert_eq!(problem.status, status, "{name}");
        app.assert_up(name).await;
    }
}
