//! The JSON request path of `POST /v1/pose/corners` and of the image endpoint's `request`
//! part, as the handlers run it (parse, validate, estimate, serialise), on arbitrary bytes:
//! never a panic, and every answer is a pose or a problem document with a 4xx status.
#![no_main]

use libfuzzer_sys::fuzz_target;
use qrpose::api::estimate_corners;
use qrpose::api::image::{ImageLimits, ImageRequest, estimate_image};
use qrpose::api::problem::parse_json;
use qrpose::api::request::CornersRequest;
use std::io::Cursor;
use std::sync::LazyLock;

/// A 4 × 4 white PNG: the image request runs its whole path in microseconds.
static TINY_PNG: LazyLock<Vec<u8>> = LazyLock::new(|| {
    let mut png = Vec::new();
    image::GrayImage::from_pixel(4, 4, image::Luma([255]))
        .write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("a PNG encodes");
    png
});

fuzz_target!(|bytes: &[u8]| {
    match parse_json::<CornersRequest>(bytes).and_then(|r| estimate_corners(&r, None)) {
        Ok(response) => {
            serde_json::to_vec(&response).expect("a pose serialises");
        }
        Err(problem) => assert!((400..500).contains(&problem.status), "{problem:?}"),
    }
    match parse_json::<ImageRequest>(bytes)
        .and_then(|r| estimate_image(&TINY_PNG, &r, &ImageLimits::default(), None))
    {
        Ok(response) => {
            serde_json::to_vec(&response).expect("an image answer serialises");
        }
        Err(problem) => assert!((400..500).contains(&problem.status), "{problem:?}"),
    }
});
