//! One frame of a [`Sequence`]: its truth ([`Sequence::truth`]: which codes the camera sees
//! and where) and its picture ([`Sequence::render_frame`]).
//!
//! Drawing: every code whose face is towards the camera and whose outline may reach the
//! image, in the spec's order, over the wall (or the uniform background) and under the
//! image-fixed lighting, through the rasteriser of [`super::super::render_scene`]. With
//! motion blur the picture is the mean of `motion_samples` such drawings at times spread
//! evenly over the exposure, centred on the capture time (the frame's shake is the same in
//! each); then the lens blur, the frame's noise and 8-bit quantisation.

use super::super::raster::{Prepared, draw_plane, finish};
use super::super::symbol::code_ground_truth;
use super::super::{CodePlacement, Effects, GroundTruth, RenderError, quad_separation_px};
use super::trajectory::shaken;
use super::{CameraToWorld, Sequence, SequenceError, Stream, Wall, derived_seed};
use nalgebra::{Isometry3, Point3, Vector3};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::euler::quaternion_wxyz;
use qrpose_core::geometry::frames::{MarkerToCamera, PixelPoint};
use qrpose_detect::decode::GrayImage;
use rand::{SeedableRng, rngs::StdRng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Where the camera is in a frame, in the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraTruth {
    /// The camera centre in the world, mm.
    pub position_mm: [f64; 3],
    /// R_wc, row-major: the camera's axes in the world as columns.
    pub rotation_matrix: [[f64; 3]; 3],
}

/// One code in view in a frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CodeTruth {
    /// The code's position in the spec's `codes`, 0-based: tells apart two codes that say
    /// the same.
    pub code_index: usize,
    /// What the code says.
    pub payload: String,
    /// Side of the symbol, mm.
    pub size_mm: f64,
    /// Whether all four corners lie inside the image (else part of the symbol is cut off).
    pub fully_in_view: bool,
    /// The symbol's shortest side in the image, px.
    pub side_px: f64,
    /// The code's rotation in the camera frame as a unit quaternion (w, x, y, z), w ≥ 0.
    pub quaternion_wxyz: [f64; 4],
    /// Corners (px, qr order), finder corners and the pose in the camera frame.
    #[serde(flatten)]
    pub truth: GroundTruth,
}

/// What frame k shows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameTruth {
    /// The frame's index, 0-based.
    pub index: u32,
    /// When it was captured: index · 1000 / fps, ms.
    pub capture_time_ms: f64,
    /// Where the camera was.
    pub camera: CameraTruth,
    /// Every code in view (module doc of [`super`]), in the spec's order.
    pub codes: Vec<CodeTruth>,
}

/// A rendered frame and its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The pixels (encode them with [`super::super::encode`] and [`Sequence::encoding`]).
    pub image: GrayImage,
    /// What the frame shows.
    pub truth: FrameTruth,
}

/// Whether the camera sees the printed face of a code at `pose` (it lies on the side its
/// normal, marker z, points away from).
fn faces_camera(pose: &MarkerToCamera) -> bool {
    (pose.rotation() * Vector3::z()).dot(&pose.translation_mm()) > 0.0
}

/// Whether any corner of the symbol lies in front of the camera (else all of it is at or
/// behind the camera's plane and nothing of it can be seen).
fn partly_in_front(code: &CodePlacement) -> bool {
    code.marker
        .object_points()
        .iter()
        .any(|p| code.pose.transform(p).0.z > 0.0)
}

/// The shortest side of a quadrilateral, px.
fn shortest_side_px(q: &[[f64; 2]; 4]) -> f64 {
    (0..4)
        .map(|i| (q[i][0] - q[(i + 1) % 4][0]).hypot(q[i][1] - q[(i + 1) % 4][1]))
        .fold(f64::INFINITY, f64::min)
}

/// The image's outline, px (pixel centres at integers, so its edges at −0.5 and size − 0.5).
fn image_outline([w, h]: [u32; 2]) -> [[f64; 2]; 4] {
    let (r, b) = (f64::from(w) - 0.5, f64::from(h) - 0.5);
    [[-0.5, -0.5], [r, -0.5], [r, b], [-0.5, b]]
}

/// The wall as one camera sees it: its plane in the camera frame and the map back.
struct WallView<'a> {
    wall: &'a Wall,
    /// The wall's normal in the camera frame.
    normal: Vector3<f64>,
    /// normal · (the wall's centre in the camera frame), mm.
    offset_mm: f64,
    /// Camera frame to wall frame.
    to_wall: Isometry3<f64>,
}

impl<'a> WallView<'a> {
    /// The wall seen from `wall_pose` (wall frame to camera).
    fn new(wall: &'a Wall, wall_pose: &MarkerToCamera) -> Self {
        let normal = wall_pose.rotation() * Vector3::z();
        Self {
            wall,
            normal,
            offset_mm: normal.dot(&wall_pose.translation_mm()),
            to_wall: wall_pose.0.inverse(),
        }
    }

    /// The grey level the ray (x, y, 1) meets on the wall, or `far` off it.
    fn level(&self, dir: &Vector3<f64>, far: f64) -> f64 {
        let denom = self.normal.dot(dir);
        if denom.abs() < 1e-12 {
            return far;
        }
        let lambda = self.offset_mm / denom;
        if lambda <= 0.0 {
            return far;
        }
        let p = self.to_wall.transform_point(&Point3::from(dir * lambda));
        let [hw, hh] = self.wall.half_mm;
        if p.x.abs() > hw || p.y.abs() > hh {
            return far;
        }
        self.wall.level_at(p.x + hw, p.y + hh)
    }
}

/// The background of one drawing: the wall where a ray meets it, else the uniform level.
fn background<'a>(
    camera: &'a Camera,
    wall: Option<WallView<'a>>,
    far: f64,
) -> impl Fn(f64, f64) -> f64 + 'a {
    move |u, v| {
        let Some(wall) = &wall else {
            return far;
        };
        match camera.normalize(&PixelPoint::new(u, v)) {
            Ok(ray) => wall.level(&Vector3::new(ray.x(), ray.y(), 1.0), far),
            Err(_) => far,
        }
    }
}

impl Sequence {
    /// The truth of frame `index`, without rendering it.
    ///
    /// # Errors
    /// [`SequenceError::FrameIndex`] past the last frame.
    pub fn truth(&self, index: u32) -> Result<FrameTruth, SequenceError> {
        self.check_index(index)?;
        let pose = self.camera_pose(index);
        let size = [self.spec.width_px, self.spec.height_px];
        let image = image_outline(size);
        let inside = |p: &[f64; 2]| {
            p[0] >= image[0][0] && p[1] >= image[0][1] && p[0] <= image[2][0] && p[1] <= image[2][1]
        };
        let scene = self.scene(&pose);
        let codes = scene
            .codes
            .iter()
            .zip(&self.codes)
            .enumerate()
            .filter(|(_, (code, _))| faces_camera(&code.pose))
            .filter_map(|(i, (code, placed))| {
                // A corner at or behind the camera: not in view (Err).
                let truth = code_ground_truth(&self.camera, code).ok()?;
                let corners = truth.corners_px;
                (quad_separation_px(&corners, &image) < 0.0).then(|| CodeTruth {
                    code_index: i,
                    payload: placed.payload.clone(),
                    size_mm: code.marker.size_mm(),
                    fully_in_view: corners.iter().all(inside),
                    side_px: shortest_side_px(&corners),
                    quaternion_wxyz: quaternion_wxyz(&code.pose.rotation()),
                    truth,
                })
            })
            .collect();
        let r = pose.rotation();
        let m = r.matrix();
        let c = pose.centre_mm();
        Ok(FrameTruth {
            index,
            capture_time_ms: self.capture_time_ms(index),
            camera: CameraTruth {
                position_mm: [c.x, c.y, c.z],
                rotation_matrix: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
            },
            codes,
        })
    }

    /// Renders frame `index` (its pixels, before JPEG) with its truth. Frames are
    /// independent: any frame renders alone to the same pixels.
    ///
    /// # Errors
    /// [`SequenceError::FrameIndex`] past the last frame; [`SequenceError::Render`] if the
    /// rasteriser refuses (not for a sequence [`Sequence::new`] accepted).
    pub fn render_frame(&self, index: u32) -> Result<Frame, SequenceError> {
        let truth = self.truth(index)?;
        let size = [self.spec.width_px, self.spec.height_px];
        let e = &self.spec.effects;
        let t = self.capture_time_ms(index);
        let shake_seed = derived_seed(self.spec.seed, Stream::Shake, index);
        let samples = if e.shutter_ms > 0.0 {
            e.motion_samples
        } else {
            1
        };
        let mut plane: Vec<f64> = Vec::new();
        for k in 0..samples {
            let offset = if samples > 1 {
                e.shutter_ms * ((f64::from(k) + 0.5) / f64::from(samples) - 0.5)
            } else {
                0.0
            };
            let pose = shaken(
                &self.trajectory.pose_at(t + offset),
                &self.trajectory.shake(),
                shake_seed,
            );
            let drawn = self.draw(&pose)?;
            if plane.is_empty() {
                plane = drawn;
            } else {
                plane.iter_mut().zip(drawn).for_each(|(a, b)| *a += b);
            }
        }
        let n = f64::from(samples);
        plane.iter_mut().for_each(|p| *p /= n);
        let effects = Effects {
            seed: derived_seed(self.spec.seed, Stream::Noise, index),
            ..self.effects
        };
        let mut rng = StdRng::seed_from_u64(effects.seed);
        let image = finish(plane, size, &effects, &mut rng)?;
        Ok(Frame { image, truth })
    }

    /// Renders frames `indices` in parallel (on rayon's pool), in order: the same frames as
    /// [`Sequence::render_frame`] one by one.
    ///
    /// # Errors
    /// The first of [`Sequence::render_frame`]'s errors.
    pub fn render_frames(&self, indices: Range<u32>) -> Result<Vec<Frame>, SequenceError> {
        indices
            .into_par_iter()
            .map(|index| self.render_frame(index))
            .collect()
    }

    /// The reflectance × lighting plane a camera at `pose` sees.
    fn draw(&self, pose: &CameraToWorld) -> Result<Vec<f64>, RenderError> {
        let size = [self.spec.width_px, self.spec.height_px];
        let qz = self.effects.quiet_zone_modules;
        let scene = self.scene(pose);
        let mut prepared = Vec::with_capacity(scene.codes.len());
        let visible = |c: &&CodePlacement| faces_camera(&c.pose) && partly_in_front(c);
        for code in scene.codes.iter().filter(visible) {
            let p = Prepared::new(&self.camera, size, code, qz)?;
            if p.may_be_seen(size) {
                prepared.push(p);
            }
        }
        let wall = self
            .wall
            .as_ref()
            .map(|w| WallView::new(w, &pose.object_pose(&w.to_world)));
        let far = self.spec.effects.background_level;
        let background = background(&self.camera, wall, far);
        Ok(draw_plane(
            &self.camera,
            size,
            &prepared,
            &self.effects,
            &background,
            &self.lighting,
        ))
    }

    fn check_index(&self, index: u32) -> Result<(), SequenceError> {
        if index < self.frames {
            Ok(())
        } else {
            Err(SequenceError::FrameIndex {
                index,
                frames: self.frames,
            })
        }
    }
}
