//! The HTTP API against a live server on a random port: one module per endpoint, plus the
//! service-wide behaviour (errors, overload, shutdown) and the CLI subcommands that talk to
//! or describe the server.

mod helpers;
#[path = "../support/mod.rs"]
mod support;

mod auth;
mod calibrate;
mod connections;
mod corners;
mod corners_bad_inputs;
mod docs;
mod hand_eye;
mod health;
mod healthcheck;
mod image;
mod image_bad_inputs;
mod metrics;
mod openapi;
mod pick;
mod routing;
mod saturation;
mod shutdown;
mod site;
mod site_reload;
mod stream;
mod tls;
