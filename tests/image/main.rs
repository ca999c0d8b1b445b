//! Images through the library: rendered photos through every detector backend to corners
//! and poses, the detection budget, small codes, a site's marker sizes on one photo, and
//! where a stream's tracker looks.

#[path = "../support/multicode.rs"]
mod multicode;

mod approach;
mod detect_budget;
mod path;
mod site_photo;
mod small_codes;
mod stream_search;
