//! The application layer: what the service does, once, for every wire layer.
//!
//! The HTTP routes, the command line and the WebSocket stream all come through here. A wire
//! layer validates its request into a [`Setup`] (the camera, how each code is sized, the
//! solver, the prior: domain types, checked once by `api::`), then calls one operation:
//!
//! | operation | for |
//! |---|---|
//! | [`estimate_corners`] | `POST /v1/pose/corners`, `qrpose estimate REQUEST.json` |
//! | [`estimate_image`] | `POST /v1/pose/image` (and `/annotated`), `qrpose estimate --image` |
//! | [`TrackSession::frame`] | each frame of `GET /v1/stream`, `qrpose track` |
//! | [`calibrate_photos`] | `POST /v1/calibrate`, `qrpose calibrate` |
//! | [`calibrate_hand_eye_photos`] | `POST /v1/calibrate/hand-eye`, `qrpose calibrate hand-eye` |
//!
//! Each operation takes the loaded site, if any, inside its [`Setup`], and returns a domain
//! answer that `api::` maps to JSON. Nothing here names HTTP, JSON or a query parameter:
//! errors are the crates' own typed errors, and the one mapping to problem documents is
//! `api::refusal`.
//!
//! Every code is solved once, at its own size: the detector asks the setup's
//! [`SizeResolver`] for each code's size before it solves, and counts its solves
//! ([`ImageAnswer::solves`]). Cancellation and the detection deadline travel
//! in the detection budget ([`DetectSetup::budget`]).

mod calibrate;
mod corners;
mod frames;
mod hand_eye;
mod image;
mod prior;
mod setup;
mod track;

// What the wire layers name of the crates below: `crate::http` reaches them only through
// this layer (tests/structure.rs keeps the rule).
pub use qrpose_calib::handeye::MIN_HAND_EYE_VIEWS;
pub use qrpose_core::estimate::Method;
pub use qrpose_core::geometry::distortion::DistortionModel;
pub use qrpose_detect::Backend;
pub use qrpose_detect::cancel::CancelFlag;
pub use qrpose_detect::contain::contain;
pub use qrpose_detect::decode::{DecodeLimits, admission_pixels};
pub use qrpose_site::{Site, SiteError};

pub use calibrate::{
    CalibrateAnswer, CalibrateError, CalibrateSetup, MAX_PHOTOS, MIN_PHOTOS, PhotoError,
    PhotoReport, calibrate_photos,
};
pub use corners::{CornersAnswer, CornersError, estimate_corners};
pub use frames::{InFrames, Localization, SiteFrames};
pub use hand_eye::{
    HandEyeAnswer, HandEyeRequestError, HandEyeRequestSetup, MAX_HAND_EYE_PHOTOS,
    calibrate_hand_eye_photos,
};
pub use image::{ImageAnswer, ImageError, MarkerAnswer, Timing, estimate_decoded, estimate_image};
pub use prior::Prior;
pub use setup::{DetectSetup, ImageLimits, ImageSetup, Pick, Setup, SizeResolver, Sizing};
pub use track::{
    DEFAULT_FULL_SEARCH_EVERY, FrameIn, FullReason, Search, TrackAnswer, TrackSession, TrackSetup,
    TrackSetupError,
};
