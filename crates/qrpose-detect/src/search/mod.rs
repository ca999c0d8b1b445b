//! Where the codes are: the `auto` strategy (module `auto`) that reads the whole frame and
//! then looks closer only where a code may be, within a [`crate::Budget`].
//!
//! - `auto`: the passes, their order and their constants;
//! - [`region`]: the places of unread finder-pattern triples, and the crops read there;
//! - [`pairs`]: the places of lone finder patterns and pairs of them (small blurred codes);
//! - `merge`: the results of several passes merged by position;
//! - [`reread`]: a found-but-unread symbol read again through its refined module grid.

pub(crate) mod auto;
pub(crate) mod merge;
pub mod pairs;
pub mod region;
pub mod reread;
