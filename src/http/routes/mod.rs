//! One file per endpoint: the handler and its `#[utoipa::path]`.

pub mod annotated;
pub mod calibrate;
pub mod corners;
pub mod docs;
pub mod hand_eye;
pub mod health;
pub mod image;
pub mod metrics;
pub mod page;
pub mod site;
