//! Where the codes are: the `auto` strategy that reads the whole frame and then looks
//! closer only where a code may be, within a [`crate::Budget`]; and the reads of the regions
//! a caller names ([`SearchRegion`], [`crate::detect_in_regions`]).
//!
//! - module `auto`: the passes of [`crate::DetectorChoice::Auto`], their order and their
//!   constants;
//! - module `given`: the crop reads of the regions a caller names (a stream's tracks);
//! - module `region`: the places of unread finder-pattern triples, and the crops read there;
//! - module `pairs`: the places of lone finder patterns and pairs of them (small blurred
//!   codes);
//! - module `merge`: the results of several passes merged by position ([`merge_candidates`]);
//! - module `reread`: a found-but-unread symbol read again through its refined module grid
//!   ([`reread()`]).

pub(crate) mod auto;
pub(crate) mod given;
pub(crate) mod merge;
pub(crate) mod pairs;
pub(crate) mod region;
pub(crate) mod reread;

pub use given::SearchRegion;
pub use merge::merge_candidates;
pub use reread::{Reread, reread};
