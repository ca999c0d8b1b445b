//! What a site adds to a pose (`docs/site.md`, Frames): the code's pose in the robot frame
//! (the camera's mount, and for a camera on the flange the arm's pose), the robot's pose in
//! the world (a mapped code), the fused localisation of a photo's mapped codes, and the
//! product a code's payload names with its grasps (`docs/pick.md`). The transforms are the
//! site crate's.

use super::setup::Pick;
use qrpose_core::estimate::{PoseEstimate, Warning};
use qrpose_site::localize::{Fusion, fuse};
use qrpose_site::pick::{ObjectPlan, PickOptions, camera_in_robot, plan_pick};
use qrpose_site::transform::{PoseWithCovariance, compose, marker_in_camera, robot_pose_in_world};
use qrpose_site::{Site, SiteCamera};

/// The site and the request's site camera: what puts a pose into the robot's and the
/// world's frames.
#[derive(Debug, Clone, Copy, Default)]
pub struct SiteFrames<'a> {
    /// The loaded site.
    pub site: Option<&'a Site>,
    /// The request's site camera (`camera.id`).
    pub camera: Option<&'a SiteCamera>,
    /// The arm's pose and the grasp bar of the request.
    pub pick: Pick,
}

/// A pose carried into the site's frames.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InFrames {
    /// The code in the robot frame (a site camera with a mount; on the flange, with the
    /// request's flange pose).
    pub in_robot: Option<PoseWithCovariance>,
    /// The robot in the world (also a mapped payload).
    pub in_world: Option<PoseWithCovariance>,
    /// The product the payload names in the site's `objects`, with its grasps.
    pub object: Option<ObjectPlan>,
}

impl SiteFrames<'_> {
    /// The code's pose in the robot frame and the robot's pose in the world, as far as the
    /// site allows.
    #[must_use]
    pub fn of(&self, estimate: &PoseEstimate, payload: Option<&str>) -> InFrames {
        if self.site.is_none() && self.camera.is_none() {
            // No site: nothing to carry (the corners route's common case stays as cheap).
            return InFrames::default();
        }
        let in_camera = marker_in_camera(estimate);
        let camera_in_robot = self
            .camera
            .and_then(|c| camera_in_robot(c.camera_mount.as_ref(), self.pick.flange.as_ref()));
        let in_robot = camera_in_robot.as_ref().map(|c| compose(c, &in_camera));
        let in_world = camera_in_robot.as_ref().and_then(|c| {
            let map = self.site?.mapped(payload?)?;
            Some(robot_pose_in_world(map, &in_camera, &c.pose))
        });
        let object = payload
            .and_then(|p| self.site?.object_for(p))
            .and_then(|(_, rule)| {
                plan_pick(
                    &in_camera,
                    rule,
                    camera_in_robot.as_ref(),
                    &self.pick_options(estimate),
                )
                .ok()
            });
        InFrames {
            in_robot,
            in_world,
            object,
        }
    }

    /// What the estimate says about itself, for the grasps: whether it converged, whether
    /// its pose could be its mirror and how likely that is.
    fn pick_options(&self, estimate: &PoseEstimate) -> PickOptions {
        let ambiguity = estimate.diagnostics.ambiguity.as_ref();
        PickOptions {
            min_grasp_probability: self.pick.min_grasp_probability,
            pose_ambiguous: ambiguity.is_some_and(|a| a.ambiguous),
            not_converged: !estimate.diagnostics.converged,
            high_reprojection_error: estimate
                .diagnostics
                .warnings
                .contains(&Warning::HighReprojectionError),
            alternative_probability: ambiguity
                .and_then(|a| a.alternative_probability)
                .filter(|p| (0.0..=1.0).contains(p))
                .unwrap_or(0.0),
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
