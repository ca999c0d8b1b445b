//! qrpose: where a QR code is in 3D and how it is turned, from one image of one camera.
//!
//! Module map (dependencies point downwards only; the core never names HTTP crates):
//!
//! | module | owns |
//! |---|---|
//! | [`geometry`] | frames, camera and distortion, marker, corner quadrilaterals, Euler angles (core) |
//! | [`estimate`] | pose from four corners: `paper`, `depth-newton`, `reprojection` (core) |
//! | [`detect`] | image bytes to QR codes: decoding, detector backends, sub-pixel corners |
//! | [`annotate`] | annotated images: the overlay of an image response drawn on the photo |
//! | [`app`] | the application layer: one validated `Setup`, one function per operation |
//! | [`api`] | wire types shared by the HTTP service and the CLI, and their validation |
//! | [`config`] | the settings of `qrpose serve`: flags, environment fallbacks, validation |
//! | [`telemetry`] | logging setup: text or JSON lines on standard error |
//! | [`http`] | the HTTP service: routes, errors, queue, metrics, OpenAPI (the only axum code) |

#![warn(missing_docs)]

pub mod annotate;
pub mod api;
pub mod app;
pub mod config;
pub mod http;
pub mod telemetry;

pub use qrpose_core::{estimate, geometry};
pub use qrpose_detect as detect;
