//! Geometry shared by every part of qrpose: frames, camera, marker, corner quadrilaterals
//! and the Euler-angle convention. Core: no I/O, no HTTP.

pub mod camera;
pub mod distortion;
pub mod euler;
pub mod frames;
pub mod marker;
pub mod quad;
