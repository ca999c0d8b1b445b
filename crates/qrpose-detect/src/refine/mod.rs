//! Sub-pixel geometry of a symbol found by any backend: its four corners and the twelve
//! finder-pattern corners ([`refine_corners`], [`refine_corners_through`] for a lens that
//! distorts; module `corners`), from single edges measured to a fraction of a pixel
//! (module `profile`) through the module-to-image homography (module `homography`); where
//! the finder corners lie on the symbol and on the marker ([`finder_model_points`],
//! [`finder_marker_points`]; module `finders`).
//!
//! Module coordinates ([`ModulePoint`]) run right and down from the symbol's top-left
//! corner, in modules; image coordinates are pixels with integer pixel centres
//! (docs/conventions.md).

pub(crate) mod corners;
mod finders;
pub(crate) mod homography;
pub(crate) mod profile;
mod targets;

pub use corners::{RefineStatus, Refinement, refine_corners, refine_corners_through};
pub use finders::{finder_marker_points, finder_model_points, marker_point_of_module};
pub use homography::ModulePoint;
pub use targets::{
    MIN_TARGET_PX_PER_MODULE, TargetPoint, TargetPointKind, calibration_points, count_by_kind,
};
