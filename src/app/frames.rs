//! What a site adds to a pose (`docs/site.md`, Frames): the code's pose in the robot frame
//! (the camera's mount), the robot's pose in the world (a mapped code), and the fused
//! localisation of a photo's mapped codes. The transforms are the site crate's.

use qrpose_core::estimate::PoseEstimate;
use qrpose_site::localize::{Fusion, fuse};
use qrpose_site::transform::{
    PoseWithCovariance, marker_in_camera, pose_in_robot, robot_pose_in_world,
};
use qrpose_site::{Site, SiteCamera};

/// The site and the request's site camera: what puts a pose into the robot's and the
/// world's frames.
#[derive(Debug, Clone, Copy, Default)]
pub struct SiteFrames<'a> {
    /// The loaded site.
    pub site: Option<&'a Site>,
    /// The request's site camera (`camera.id`).
    pub camera: Option<&'a SiteCamera>,
}

/// A pose carried into the site's frames.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct InFrames {
    /// The code in the robot frame (a site camera with a mount).
    pub in_robot: Option<PoseWithCovariance>,
    /// The robot in the world (also a mapped payload).
    pub in_world: Option<PoseWithCovariance>,
}

impl SiteFrames<'_> {
    /// The code's pose in the robot frame and the robot's pose in the world, as far as the
    /// site allows.
    #[must_use]
    pub fn of(&self, estimate: &PoseEstimate, payload: Option<&str>) -> InFrames {
        let Some(mount) = self.camera.and_then(|c| c.mount) else {
            return InFrames::default();
        };
        let in_camera = marker_in_camera(estimate);
        let in_robot = pose_in_robot(&mount, &in_camera);
        let in_world = payload
            .and_then(|p| self.site?.mapped(p))
            .map(|map| robot_pose_in_world(map, &in_camera, &mount));
        InFrames {
            in_robot: Some(in_robot),
            in_world,
        }
    }
}

/// The robot's pose in the world fused over a photo's mapped codes.
#[derive(Debug, Clone)]
pub struct Localization {
    /// The fused pose and each code's residual, in the order of `codes`.
    pub fusion: Fusion,
    /// Each fused code: its index among the photo's markers and its payload.
    pub codes: Vec<(usize, String)>,
}

/// Whether every number of `pose` is finite (a pose at magnitudes beyond double precision
/// is left out of the fusion).
fn is_finite(pose: &PoseWithCovariance) -> bool {
    pose.pose.translation_mm.iter().all(|v| v.is_finite())
        && pose.pose.rotation.matrix().iter().all(|v| v.is_finite())
        && pose
            .covariance
            .is_none_or(|c| c.iter().all(|v| v.is_finite()))
}

/// The fused localisation of `mapped` (marker index, payload, robot pose in the world)
/// when two or more of them have a covariance; `None` otherwise.
#[must_use]
pub fn localize(mapped: &[(usize, String, PoseWithCovariance)]) -> Option<Localization> {
    let usable: Vec<&(usize, String, PoseWithCovariance)> = mapped
        .iter()
        .filter(|(_, _, p)| p.covariance.is_some() && is_finite(p))
        .collect();
    let poses: Vec<PoseWithCovariance> = usable.iter().map(|(_, _, p)| *p).collect();
    let fusion = fuse(&poses).ok()?;
    Some(Localization {
        fusion,
        codes: usable
            .iter()
            .map(|(index, payload, _)| (*index, payload.clone()))
            .collect(),
    })
}
