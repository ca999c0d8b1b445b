//! What the overlay shows, in pixel coordinates: built from the application's answer for the
//! photo ([`ImageAnswer`]: the codes, their poses and products) and the camera, drawn by
//! [`super::raster`]. Pure geometry, no pixels.
//!
//! Per code: its outline through the four refined corners, a mark on each corner, its
//! payload, and the marker frame's axes drawn from the marker centre (`position_mm`),
//! x red, y green, z blue, each as long as the marker's side (docs/conventions.md, Marker
//! frame: x to the symbol's right, y down the symbol, z into the printed face). The axes are
//! the pose projected through the camera, distortion included, so they stand where the pose
//! says, not where the corners are. A code without a pose gets its outline, marks and label.
//!
//! A code whose payload names a product of the site (`pose.object`, docs/pick.md) also gets
//! the product's box (its twelve edges, cyan) and each grasp's approach axis: a stroke along
//! the grasp frame's z ending at the grasp point, half the box's longest side long, green
//! when the grasp is `graspable`, orange when it is not.

use crate::app::{ImageAnswer, MarkerAnswer};
use crate::estimate::PoseEstimate;
use crate::geometry::camera::Camera;
use crate::geometry::frames::CameraPoint;
use nalgebra::{Matrix3, Point3, Vector3};
use qrpose_site::pick::ObjectPlan;

/// An sRGB colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rgb(pub [u8; 3]);

/// The marker frame's x axis.
pub const X_AXIS: Rgb = Rgb([255, 0, 0]);
/// The marker frame's y axis.
pub const Y_AXIS: Rgb = Rgb([0, 255, 0]);
/// The marker frame's z axis.
pub const Z_AXIS: Rgb = Rgb([0, 0, 255]);
/// The outline through the four corners.
pub const OUTLINE: Rgb = Rgb([255, 255, 0]);
/// The mark on each refined corner.
pub const CORNER_MARK: Rgb = Rgb([255, 0, 255]);
/// The payload's text.
pub const LABEL_TEXT: Rgb = Rgb([255, 255, 255]);
/// The box behind the payload's text.
pub const LABEL_BOX: Rgb = Rgb([0, 0, 0]);

/// A product's box.
pub const BOX: Rgb = Rgb([0, 255, 255]);
/// The approach axis of a grasp that is `graspable`.
pub const GRASPABLE: Rgb = Rgb([64, 255, 64]);
/// The approach axis of a grasp that is not.
pub const NOT_GRASPABLE: Rgb = Rgb([255, 128, 0]);

/// Text shown for a symbol that was found but not decoded.
pub const UNDECODED_LABEL: &str = "(not decoded)";
/// Longest payload shown, characters; longer ones end in `...`.
pub const MAX_LABEL_CHARS: usize = 48;

/// A straight stroke from `from_px` to `to_px` (pixel coordinates, integer = pixel centre).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Start, px.
    pub from_px: [f64; 2],
    /// End, px.
    pub to_px: [f64; 2],
    /// Colour.
    pub colour: Rgb,
}

/// Text in a box whose bottom-left corner is at `anchor_px` (or whose top-left corner is,
/// when `below` is set).
#[derive(Debug, Clone, PartialEq)]
pub struct Label {
    /// The box's left edge and its bottom edge (top edge when `below`), px.
    pub anchor_px: [f64; 2],
    /// Whether the box hangs below the anchor rather than standing on it.
    pub below: bool,
    /// The text (ASCII; other characters are drawn as `?`).
    pub text: String,
}

/// Everything drawn on one image, in drawing order: outlines, then axes, then labels, then
/// corner marks on top (so a mark is never covered).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overlay {
    /// Outline sides and axes, drawn in order.
    pub segments: Vec<Segment>,
    /// Payload labels.
    pub labels: Vec<Label>,
    /// Refined corners, px.
    pub corner_marks_px: Vec<[f64; 2]>,
}

/// The projected axes of one pose: the marker centre and the ends of x, y, z, px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectedAxes {
    /// The marker centre, px.
    pub origin_px: [f64; 2],
    /// Ends of the x, y and z axes, px.
    pub ends_px: [[f64; 2]; 3],
}

/// The marker's side, mm, from the pose alone: the centre lies at R·(−l/2, l/2, 0) from P2
/// (docs/conventions.md, Pose), so |centre − P2| = l/√2 whatever the method.
pub fn marker_side_mm(pose: &PoseEstimate) -> f64 {
    std::f64::consts::SQRT_2 * (pose.centre_mm - pose.pose.0.translation.vector).norm()
}

/// The axes of a pose with centre `centre_mm` and rotation `r`, each `length_mm` long,
/// projected through `camera`; `None` when a point is at or behind the camera.
pub fn project_axes(
    camera: &Camera,
    centre_mm: &Vector3<f64>,
    r: &Matrix3<f64>,
    length_mm: f64,
) -> Option<ProjectedAxes> {
    let centre = Point3::from(*centre_mm);
    let project = |p: Point3<f64>| camera.project(&CameraPoint(p)).map(|px| [px.u(), px.v()]);
    let origin_px = project(centre)?;
    let mut ends_px = [[0.0; 2]; 3];
    for (axis, end) in ends_px.iter_mut().enumerate() {
        // Column `axis` of R: the marker axis in camera coordinates.
        *end = project(centre + r.column(axis).into_owned() * length_mm)?;
    }
    Some(ProjectedAxes { origin_px, ends_px })
}

/// The axes of a marker's pose, if it is in front of the camera.
pub fn pose_axes(camera: &Camera, pose: &PoseEstimate) -> Option<ProjectedAxes> {
    let r = pose.pose.0.rotation.to_rotation_matrix().into_inner();
    project_axes(camera, &pose.centre_mm, &r, marker_side_mm(pose))
}

/// The edges of a box with centre `centre`, axes the columns of `matrix` and extents
/// `box_mm`, as pairs of corner indices into [`box_corners`]'s order.
const BOX_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (1, 3),
    (3, 2),
    (2, 0),
    (4, 5),
    (5, 7),
    (7, 6),
    (6, 4),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// The eight corners of a box posed at (`centre_mm`, `matrix`) with extents `box_mm`,
/// camera frame: corner k has sign (−, +) of x, y, z from bits 0, 1, 2 of k.
fn box_corners(
    centre_mm: &Vector3<f64>,
    r: &Matrix3<f64>,
    box_mm: &Vector3<f64>,
) -> [Point3<f64>; 8] {
    std::array::from_fn(|k| {
        let sign = |bit: usize| if k >> bit & 1 == 1 { 0.5 } else { -0.5 };
        let local = Vector3::new(sign(0) * box_mm.x, sign(1) * box_mm.y, sign(2) * box_mm.z);
        Point3::from(*centre_mm + r * local)
    })
}

/// The strokes of a product (module docs): its box's edges and each grasp's approach axis,
/// projected through `camera`; a stroke with an end at or behind the camera is left out.
pub fn object_segments(camera: &Camera, object: &ObjectPlan) -> Vec<Segment> {
    let project = |p: Point3<f64>| camera.project(&CameraPoint(p)).map(|px| [px.u(), px.v()]);
    let pose = &object.pose.pose;
    let corners = box_corners(&pose.translation_mm, pose.rotation.matrix(), &object.box_mm);
    let mut segments: Vec<Segment> = BOX_EDGES
        .iter()
        .filter_map(|&(a, b)| {
            Some(Segment {
                from_px: project(corners[a])?,
                to_px: project(corners[b])?,
                colour: BOX,
            })
        })
        .collect();
    let length_mm = 0.5 * object.box_mm.max();
    for grasp in &object.grasps {
        let approach = grasp.pose.pose.rotation.matrix().column(2).into_owned();
        let at = Point3::from(grasp.pose.pose.translation_mm);
        if let (Some(from_px), Some(to_px)) = (project(at - approach * length_mm), project(at)) {
            segments.push(Segment {
                from_px,
                to_px,
                colour: if grasp.graspable {
                    GRASPABLE
                } else {
                    NOT_GRASPABLE
                },
            });
        }
    }
    segments
}

/// The payload as shown: the text, `(not decoded)`, shortened to [`MAX_LABEL_CHARS`].
pub fn label_text(payload: Option<&str>) -> String {
    let text = payload.unwrap_or(UNDECODED_LABEL);
    if text.chars().count() <= MAX_LABEL_CHARS {
        return text.to_owned();
    }
    let kept: String = text.chars().take(MAX_LABEL_CHARS - 3).collect();
    format!("{kept}...")
}

/// The grid labels are placed on, px: a JPEG's 8 × 8 blocks. A label box whose sides lie
/// on block edges (its size is a multiple of 8 px at 720 p and 1440 p) leaves the blocks
/// around it as they were: no ringing of the box's edge into the photo, and fewer blocks
/// encoded anew when an annotated JPEG is spliced.
const LABEL_GRID_PX: f64 = 8.0;

/// A marker's label, placed by [`label_place`].
fn label_for(corners_px: &[[f64; 2]; 4], payload: Option<&str>, label_height_px: f64) -> Label {
    let (anchor_px, below) = label_place(corners_px, label_height_px);
    Label {
        anchor_px,
        below,
        text: label_text(payload),
    }
}

/// Where the label of a code with corners `corners_px` goes, and whether it hangs below the
/// code: above it, the box's left side on the last grid line at or left of the leftmost
/// corner, its bottom on the last grid line at least half a label height above the topmost
/// corner; or, when there is no room above, hanging from the first grid line half a label
/// height below the bottommost corner.
fn label_place(corners_px: &[[f64; 2]; 4], label_height_px: f64) -> ([f64; 2], bool) {
    let left = corners_px
        .iter()
        .map(|c| c[0])
        .fold(f64::INFINITY, f64::min);
    let top = corners_px
        .iter()
        .map(|c| c[1])
        .fold(f64::INFINITY, f64::min);
    let bottom = corners_px
        .iter()
        .map(|c| c[1])
        .fold(f64::NEG_INFINITY, f64::max);
    let gap_px = label_height_px / 2.0;
    let grid = |v: f64, round: fn(f64) -> f64| round(v / LABEL_GRID_PX) * LABEL_GRID_PX;
    let above = grid(top - gap_px, f64::floor);
    let below = above - label_height_px < 0.0;
    let y = if below {
        grid(bottom + gap_px, f64::ceil)
    } else {
        above
    };
    ([grid(left, f64::floor), y], below)
}

/// A code's refined corners, px, in the `qr` order of the answer.
fn corners_of(marker: &MarkerAnswer) -> [[f64; 2]; 4] {
    marker.code.corners_px().map(|p| [p.u(), p.v()])
}

/// The overlay of `answer`, whose poses were computed with `camera`; labels are
/// `label_height_px` tall (for placing them clear of the code).
pub fn overlay_of(answer: &ImageAnswer, camera: &Camera, label_height_px: f64) -> Overlay {
    let mut overlay = Overlay::default();
    for marker in &answer.markers {
        let corners = corners_of(marker);
        for k in 0..4 {
            overlay.segments.push(Segment {
                from_px: corners[k],
                to_px: corners[(k + 1) % 4],
                colour: OUTLINE,
            });
        }
        if let Some(object) = marker.frames.object.as_ref() {
            overlay.segments.extend(object_segments(camera, object));
        }
        if let Some(axes) = marker.pose.as_ref().ok().and_then(|p| pose_axes(camera, p)) {
            // z first, x last: x, the axis most often read, stays on top.
            for (axis, colour) in [(2, Z_AXIS), (1, Y_AXIS), (0, X_AXIS)] {
                overlay.segments.push(Segment {
                    from_px: axes.origin_px,
                    to_px: axes.ends_px[axis],
                    colour,
                });
            }
        }
        let payload = marker.code.candidate.text.as_deref();
        overlay
            .labels
            .push(label_for(&corners, payload, label_height_px));
        overlay.corner_marks_px.extend(corners);
    }
    overlay
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::camera::Camera;

    fn camera() -> Camera {
        Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a camera")
    }

    #[test]
    fn a_frontal_pose_projects_its_axes_right_down_and_onto_the_centre() {
        let centre = Vector3::new(0.0, 0.0, 500.0);
        let axes = project_axes(&camera(), &centre, &Matrix3::identity(), 50.0).expect("in front");
        assert_eq!(axes.origin_px, [639.5, 359.5]);
        assert_eq!(
            axes.ends_px[0],
            [739.5, 359.5],
            "x: 50 mm at 500 mm = 100 px right"
        );
        assert_eq!(axes.ends_px[1], [639.5, 459.5], "y: 100 px down");
        // z points away from the camera: its end lies on the centre's ray.
        assert_eq!(axes.ends_px[2], [639.5, 359.5]);
    }

    #[test]
    fn a_products_box_and_grasps_are_drawn_coloured_by_graspable() {
        use qrpose_site::objects::GraspKind;
        use qrpose_site::pick::GraspPlan;
        use qrpose_site::transform::{PoseWithCovariance, Rigid};
        let pose = |x: f64, z: f64| PoseWithCovariance {
            pose: Rigid {
                rotation: nalgebra::Rotation3::identity(),
                translation_mm: Vector3::new(x, 0.0, z),
            },
            covariance: None,
        };
        // The tool approaches along +z, into the scene.
        let grasp = |graspable: bool, x: f64| GraspPlan {
            name: "g".to_owned(),
            kind: GraspKind::Suction,
            pose: pose(x, 450.0),
            pose_in_robot: None,
            pre_grasp_in_robot: None,
            width_mm: None,
            within_tolerance_probability: Some(0.5),
            graspable,
            reasons: vec![],
        };
        let object = ObjectPlan {
            rule: "prefix:SKU-".to_owned(),
            box_mm: Vector3::new(200.0, 100.0, 100.0),
            pose: pose(0.0, 500.0),
            pose_in_robot: None,
            grasps: vec![grasp(true, -50.0), grasp(false, 50.0)],
        };
        let segments = object_segments(&camera(), &object);
        assert_eq!(segments.len(), 14);
        assert!(segments[..12].iter().all(|s| s.colour == BOX));
        // Corner 0 is (−100, −50, −50) mm from the centre: the near face's top left.
        let near = |px: [f64; 2], want: [f64; 2]| (px[0] - want[0]).hypot(px[1] - want[1]) < 1e-9;
        let top_left = [
            639.5 - 1000.0 * 100.0 / 450.0,
            359.5 - 1000.0 * 50.0 / 450.0,
        ];
        assert!(near(segments[0].from_px, top_left), "{:?}", segments[0]);
        let axes: Vec<&Segment> = segments[12..].iter().collect();
        assert_eq!((axes[0].colour, axes[1].colour), (GRASPABLE, NOT_GRASPABLE));
        // Each axis ends at its grasp point and starts 100 mm nearer the camera.
        assert!(near(axes[0].to_px, [639.5 - 1000.0 * 50.0 / 450.0, 359.5]));
        assert!(near(
            axes[0].from_px,
            [639.5 - 1000.0 * 50.0 / 350.0, 359.5]
        ));
    }

    #[test]
    fn axes_behind_the_camera_are_not_drawn() {
        let centre = Vector3::new(0.0, 0.0, 10.0);
        let flipped = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        assert!(project_axes(&camera(), &centre, &flipped, 50.0).is_none());
    }

    #[test]
    fn labels_sit_on_the_block_grid_clear_of_the_code() {
        let corners = [
            [101.3, 203.7],
            [180.2, 199.5],
            [185.0, 270.1],
            [99.9, 275.0],
        ];
        // Above: left side at x = 96 (≤ 99.9), bottom at y = 184 (≤ 199.5 − 12).
        assert_eq!(label_place(&corners, 24.0), ([96.0, 184.0], false));
        // No room above (the box would start above y = 0): below, from y = 288 (≥ 275 + 12).
        let high = corners.map(|[x, y]| [x, y - 180.0]);
        assert_eq!(label_place(&high, 24.0), ([96.0, 112.0], true));
        // Corners on grid lines stay put, and the gap is kept.
        let square = [[64.0, 96.0], [128.0, 96.0], [128.0, 160.0], [64.0, 160.0]];
        assert_eq!(label_place(&square, 24.0), ([64.0, 80.0], false));
    }

    #[test]
    fn long_payloads_are_shortened_and_missing_ones_named() {
        let long = "x".repeat(100);
        let text = label_text(Some(&long));
        assert_eq!(text.chars().count(), MAX_LABEL_CHARS);
        assert!(text.ends_with("..."));
        assert_eq!(label_text(Some("SKU-1")), "SKU-1");
        assert_eq!(label_text(None), UNDECODED_LABEL);
    }
}
