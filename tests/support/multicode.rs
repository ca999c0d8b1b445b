//! Frames of `scripts/multicode_bench.py`, rendered at test time for the detector tests
//! (`detect_budget`, `detect_small_codes`): the scene of a seed, rendered with the
//! benchmark's effects (blur σ, noise, JPEG quality), and decoded as the service decodes it.

use qrpose::detect::decode::{DecodeLimits, GrayImage, decode_gray};
use qrpose_sim::render::{
    Effects, Encoding, MultiScene, RenderedScene, SceneRanges, random_scene, render_scene,
};

/// One benchmark frame: its scene, the render (encoded bytes, truth per code) and the grey
/// image decoded from the bytes (a test that reads only the image leaves the rest unread).
#[allow(dead_code)]
pub struct Frame {
    pub scene: MultiScene,
    pub rendered: RenderedScene,
    pub image: GrayImage,
}

/// Frame `seed` of the benchmark with its effects.
pub fn frame(seed: u64, blur_px: f64, noise: f64, quality: u8) -> Frame {
    let scene = random_scene(seed, &SceneRanges::default()).expect("a scene");
    let effects = Effects {
        supersample: 4,
        blur_px,
        noise,
        encoding: Encoding::Jpeg(quality),
        seed,
        ..Effects::default()
    };
    let rendered = render_scene(&scene, &effects).expect("renders");
    let image = decode_gray(&rendered.encoded, &DecodeLimits::default()).expect("decodes");
    Frame {
        scene,
        rendered,
        image,
    }
}
