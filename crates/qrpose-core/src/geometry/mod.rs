//! Geometry shared by every part of qrpose: frames, camera, marker, corner quadrilaterals,
//! the Euler-angle convention and the plane-to-plane homography fit. Core: no I/O, no HTTP.

pub mod camera;
pub mod distortion;
pub mod euler;
pub mod frames;
pub mod homography;
pub mod marker;
pub mod quad;
