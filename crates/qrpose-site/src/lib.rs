//! A warehouse site for qrpose (`docs/site.md`): cameras by name from OpenCV `FileStorage` or
//! ROS `camera_info` calibration files, marker sizes by payload, camera mounts and a map of
//! codes in the warehouse frame, and the transforms that carry a pose (with its covariance)
//! from the camera frame into the robot's and the warehouse's.
//!
//! | module | owns |
//! |---|---|
//! | [`file`] | the YAML format: keys, value checks that keep the parser's line numbers |
//! | [`site`] | [`Site`]: loading and validating a site file, cameras, sizes, map, SHA-256 |
//! | [`sizes`] | marker size by payload: exact, prefix, pattern, default; and their source |
//! | [`transform`] | rigid transforms between frames and first-order covariance propagation |
//! | [`mount`] | a camera's mount: on the robot or the flange, its standard deviation |
//! | [`objects`] | products by payload: box, code on the box, grasps |
//! | [`pick`] | an object's pose and its grasps in the robot frame, with the probability that each is within its tolerance |
//! | [`localize`] | fusing several robot-pose-in-world estimates, residuals, outlier gate |
//! | [`prior`] | the planar ambiguity resolved by an expected rotation |
//! | [`calibration`] | OpenCV and ROS calibration files read into a camera, and written from one |
//! | [`error`] | [`SiteError`]: file, line, reason |
//!
//! No HTTP here: the service and the CLI load a [`Site`] and ask it questions.

#![warn(missing_docs)]

pub mod calibration;
pub mod error;
pub mod file;
pub mod localize;
pub mod mount;
pub mod objects;
pub mod pick;
pub mod prior;
pub mod site;
pub mod sizes;
pub mod transform;

pub use error::{Reason, SiteError};
pub use mount::{CameraMount, MountParent, MountStd};
pub use objects::{Grasp, GraspKind, ObjectRule, Tolerance};
pub use site::{CameraSource, MappedCode, Site, SiteCamera};
pub use sizes::{MarkerSizes, SizeLookup, SizeSource};

/// The README example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
