//! Image decoding on arbitrary bytes: never a panic (the service contains a decoder's panic
//! as a 422, but it is still a bug; libFuzzer's panic hook aborts on it even inside
//! `catch_unwind`), never an image larger than the limits allow.
#![no_main]

use libfuzzer_sys::fuzz_target;
use qrpose_detect::decode::{DecodeLimits, decode_gray};

/// Small limits, so that a declared size cannot make the fuzzer allocate gigabytes.
const LIMITS: DecodeLimits = DecodeLimits {
    max_encoded_bytes: 1 << 20,
    max_pixels: 1 << 20,
};

fuzz_target!(|bytes: &[u8]| {
    if let Ok(image) = decode_gray(bytes, &LIMITS) {
        assert!(image.pixels().len() as u64 <= LIMITS.max_pixels);
        assert_eq!(image.pixels().len(), image.width() * image.height());
    }
});
