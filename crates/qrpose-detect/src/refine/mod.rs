//! Sub-pixel geometry of a symbol found by any backend: its four corners and the twelve
//! finder-pattern corners ([`corners`]), from single edges measured to a fraction of a
//! pixel ([`profile`]) through the module-to-image homography ([`homography`]); where the
//! finder corners lie on the symbol and on the marker ([`finders`]).

pub mod corners;
pub mod finders;
pub mod homography;
pub mod profile;
