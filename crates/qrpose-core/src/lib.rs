//! qrpose-core: the pose of a square marker (a QR code) from its four image corners.
//!
//! | module | owns |
//! |---|---|
//! | [`geometry`] | frames, camera and distortion, marker, corner quadrilaterals, Euler angles, homography fit |
//! | [`estimate`] | pose from four corners: `paper`, `depth-newton`, `reprojection` |
//!
//! Conventions (frames, corner labels, Euler order, units) are those of the repository's
//! `docs/conventions.md`; the paper's method as implemented is `docs/paper-method.md`.
//! Nothing here is asynchronous or knows of HTTP: the dependencies are nalgebra and
//! thiserror.

#![warn(missing_docs)]

pub mod estimate;
pub mod geometry;

/// The README example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
