//! The annotated JPEG's bytes, pinned: SHA-256 digests recorded from the splice as it was
//! inside the service crate (`src/annotate/jpeg_splice`), before it moved to its own crate
//! (`jpeg-overlay`, crates/jpeg-overlay), and unchanged by the move. Moving the code, or
//! reorganising it later, must not change a byte the service answers with: a client
//! comparing annotated images, or a cache keyed on them, would see every one change. A deliberate change of the output (another rounding, other ZRL placement)
//! records new digests here and says why in its commit.
//!
//! The inputs are made here with `jpeg-encoder` (its integer DCT, the same bytes with and
//! without its AVX2 path); their digests are pinned too, so that a failure says whether the
//! input or the splice changed.

use super::*;
use crate::annotate::{OutputFormat, annotated_with, redrawn};
use sha2::{Digest, Sha256};

/// The SHA-256 of `bytes`, in lower-case hex.
fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// One pinned case: how the photo is encoded, and the digests and lengths of the photo and
/// of its annotated version.
struct Pinned {
    name: &'static str,
    options: Options,
    input: (usize, &'static str),
    output: (usize, &'static str),
}

const PINNED: [Pinned; 4] = [
    Pinned {
        name: "colour 4:2:0",
        options: COLOUR_420,
        input: (
            10000,
            "88a57b34be45dd4a38af0a3e0576cd757c76eaf23cfc4b397fa0d1fe21c7d593",
        ),
        output: (
            12015,
            "2e21a42e12af01823f923200c07190cfd5f67939fc4feb91276bd5d39736df0b",
        ),
    },
    Pinned {
        name: "grey",
        options: Options {
            grey: true,
            ..COLOUR_420
        },
        input: (
            8656,
            "b2c0b166601b421121c1a145ea6ce45033e0b197fe53b497b7eef3ef0a054841",
        ),
        output: (
            13370,
            "e2ebf63a80bebdbbb52193cc519a387e0f5023f666ba05c8b924173012ab7b12",
        ),
    },
    Pinned {
        name: "colour 4:2:0, restart interval 3",
        options: Options {
            restart: Some(3),
            ..COLOUR_420
        },
        input: (
            10111,
            "24ebb3ec304e6f2ba2748b12b4ed4b21afb3a8a23e90d34cc0c3c00b08a2dd7c",
        ),
        output: (
            12110,
            "fe10c344aa81e3dbfaa107df63d332f6935475e3875ad1194c7b256688b25978",
        ),
    },
    Pinned {
        name: "colour 4:4:4, restart interval 5, quality 75",
        options: Options {
            sampling: SamplingFactor::F_1_1,
            restart: Some(5),
            quality: 75,
            ..COLOUR_420
        },
        input: (
            6787,
            "6ca4c3ade61a72bdca9edbce23ecfe78bb4a2b57b1b6527416f8c01c4cdcfc59",
        ),
        output: (
            9124,
            "60eb81983acde57a9ab74e76de72dc74a98d58598e92b6e02457168a5ef51c46",
        ),
    },
];

#[test]
fn annotated_jpegs_keep_their_pinned_bytes() {
    let mut failures = Vec::new();
    for case in &PINNED {
        let jpeg = encode(case.options, |_| {});
        let input = (jpeg.len(), sha256_hex(&jpeg));
        let annotated =
            annotated_with(&jpeg, OutputFormat::Jpeg, SIZE_PX, |_| overlay()).expect("annotated");
        // Spliced, not the whole-frame path (whose bytes would differ anyway).
        let whole = redrawn(&jpeg, OutputFormat::Jpeg, &|_| overlay()).expect("drawn");
        assert_ne!(annotated, whole, "{}: not spliced", case.name);
        let output = (annotated.len(), sha256_hex(&annotated));
        if (input.0, input.1.as_str()) != case.input {
            failures.push(format!("{}: input {input:?}", case.name));
        }
        if (output.0, output.1.as_str()) != case.output {
            failures.push(format!("{}: output {output:?}", case.name));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
