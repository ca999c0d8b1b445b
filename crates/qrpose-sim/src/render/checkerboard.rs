//! Printed checkerboards drawn by the codes' rasteriser: the reference target of the
//! calibration comparison (`scripts/calibration_compare.py`: OpenCV's checkerboard
//! calibration on the same views as a QR code's). [`Checkerboard`] (squares per side, outer
//! size, light border), [`BoardScene`], [`render_checkerboard`] and its truth
//! [`BoardTruth`].
//!
//! The board lies in the marker frame as a symbol does (docs/conventions.md): its top-left
//! corner at P3 = (−l, 0, 0), x to the right along its top edge, y down; square (i, j)
//! (column i, row j) of an S-square board covers x ∈ −l + l/S·[i, i + 1],
//! y ∈ l/S·[j, j + 1], and is dark when i + j is even (the top-left square is dark). The
//! squares are drawn exactly as a symbol's modules are (the same supersampled rays through
//! the lens model, the effects' dark and light levels); the border is light, and beyond it
//! lies the background. Clutter, background level, lighting and noise are drawn from the
//! effects' seed in the same order as for codes, so a board and a code rendered with the
//! same camera, effects and seed see the same background, lighting and noise field.

use super::raster::{Prepared, check_effects, check_size, draw_photo};
use super::symbol::marker_point;
use super::{Effects, RenderError};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::MarkerToCamera;
use qrpose_core::geometry::marker::Marker;
use qrpose_detect::decode::GrayImage;
use serde::{Deserialize, Serialize};

/// Most squares per side of a [`Checkerboard`].
pub const MAX_BOARD_SQUARES: u32 = 64;

/// A printed square checkerboard.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Checkerboard {
    /// Squares per side, 2-[`MAX_BOARD_SQUARES`] ((squares − 1)² inner corners).
    pub squares: u32,
    /// Outer side of the squares, mm (border excluded).
    pub size_mm: f64,
    /// Light margin around the squares, mm (takes the place of a code's quiet zone, whose
    /// [`Effects::quiet_zone_modules`] the board ignores).
    pub border_mm: f64,
}

impl Checkerboard {
    /// The side of one square, mm.
    pub fn square_mm(&self) -> f64 {
        self.size_mm / f64::from(self.squares)
    }

    /// The board as a marker of its outer size.
    ///
    /// # Errors
    /// [`RenderError::Checkerboard`] unless 2 ≤ squares ≤ [`MAX_BOARD_SQUARES`], the size
    /// is finite and positive and the border finite and not negative.
    fn marker(&self) -> Result<Marker, RenderError> {
        let invalid = RenderError::Checkerboard {
            squares: self.squares,
            size_mm: self.size_mm,
            border_mm: self.border_mm,
        };
        let border_ok = self.border_mm.is_finite() && self.border_mm >= 0.0;
        if !(2..=MAX_BOARD_SQUARES).contains(&self.squares) || !border_ok {
            return Err(invalid);
        }
        Marker::try_new(self.size_mm).map_err(|_| invalid)
    }

    /// The dark flags of the squares, row-major (top-left dark).
    fn squares_dark(&self) -> (usize, Vec<bool>) {
        let n = self.squares as usize;
        (
            n,
            (0..n * n)
                .map(|k| (k % n + k / n).is_multiple_of(2))
                .collect(),
        )
    }
}

/// A checkerboard seen by a camera.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardScene {
    /// The board.
    pub board: Checkerboard,
    /// The camera (intrinsics and distortion, px).
    pub camera: Camera,
    /// Image width, px.
    pub width_px: u32,
    /// Image height, px.
    pub height_px: u32,
    /// The board's pose (p_cam = R · p_board + t, the board's frame as a marker's).
    pub pose: MarkerToCamera,
}

/// Where a rendered board is. Pixels with integer pixel centres.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardTruth {
    /// Squares per side.
    pub squares: u32,
    /// Outer side of the squares, mm.
    pub size_mm: f64,
    /// The outer corners of the squares, px: top-left, top-right, bottom-right,
    /// bottom-left.
    pub corners_px: [[f64; 2]; 4],
    /// The (squares − 1)² inner corners, px, row by row from the top-left: index
    /// r · (squares − 1) + c is the corner (c + 1, r + 1) squares right of and below the
    /// top-left corner.
    pub inner_corners_px: Vec<[f64; 2]>,
    /// The same corners on the board, mm from its top-left corner, x right, y down.
    pub inner_corners_mm: Vec<[f64; 2]>,
    /// R of p_cam = R · p_marker + t, row-major.
    pub rotation_matrix: [[f64; 3]; 3],
    /// t: the board's top-right corner (the marker frame's origin) in the camera frame, mm.
    pub reference_point_mm: [f64; 3],
    /// The board's centre in the camera frame, mm.
    pub position_mm: [f64; 3],
}

/// A rendered board.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedBoard {
    /// The pixels before encoding.
    pub image: GrayImage,
    /// The encoded file (JPEG or PNG).
    pub encoded: Vec<u8>,
    /// Where the board is.
    pub truth: BoardTruth,
}

/// Where the board of `scene` is, without rendering.
///
/// # Errors
/// [`RenderError::Checkerboard`], or [`RenderError::OutOfView`] when a corner is behind
/// the camera.
pub fn board_truth(scene: &BoardScene) -> Result<BoardTruth, RenderError> {
    let board = scene.board;
    let marker = board.marker()?;
    let n = board.squares as usize;
    let project = |u: f64, v: f64| -> Result<[f64; 2], RenderError> {
        let p = scene
            .camera
            .project(&scene.pose.transform(&marker_point(u, v, &marker, n)))
            .ok_or(RenderError::OutOfView)?;
        Ok([p.u(), p.v()])
    };
    let nf = f64::from(board.squares);
    let corners_px = [
        project(0.0, 0.0)?,
        project(nf, 0.0)?,
        project(nf, nf)?,
        project(0.0, nf)?,
    ];
    let inner: Vec<(f64, f64)> = (1..board.squares)
        .flat_map(|r| (1..board.squares).map(move |c| (f64::from(c), f64::from(r))))
        .collect();
    let inner_corners_px = inner
        .iter()
        .map(|&(c, r)| project(c, r))
        .collect::<Result<Vec<_>, _>>()?;
    let square = board.square_mm();
    let inner_corners_mm = inner
        .iter()
        .map(|&(c, r)| [c * square, r * square])
        .collect();
    let m = *scene.pose.rotation().matrix();
    let t = scene.pose.translation_mm();
    let centre = scene.pose.transform(&marker.centre()).0;
    Ok(BoardTruth {
        squares: board.squares,
        size_mm: board.size_mm,
        corners_px,
        inner_corners_px,
        inner_corners_mm,
        rotation_matrix: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
        reference_point_mm: [t.x, t.y, t.z],
        position_mm: [centre.x, centre.y, centre.z],
    })
}

/// Renders a checkerboard with the codes' rasteriser and effects (the border of
/// [`Checkerboard::border_mm`] instead of the effects' quiet zone).
///
/// # Errors
/// [`RenderError::Checkerboard`], [`RenderError::Effect`], [`RenderError::ImageSize`],
/// [`RenderError::Image`], and [`RenderError::OutOfView`] when a corner of the squares is
/// behind the camera or outside the image.
pub fn render_checkerboard(
    scene: &BoardScene,
    effects: &Effects,
) -> Result<RenderedBoard, RenderError> {
    let (w, h) = (scene.width_px, scene.height_px);
    check_size(w, h)?;
    let truth = board_truth(scene)?;
    let inside = |p: &[f64; 2]| {
        p[0] >= -0.5 && p[1] >= -0.5 && p[0] <= f64::from(w) - 0.5 && p[1] <= f64::from(h) - 0.5
    };
    if !truth.corners_px.iter().all(inside) {
        return Err(RenderError::OutOfView);
    }
    let board = scene.board;
    let effects = Effects {
        quiet_zone_modules: board.border_mm / board.square_mm(),
        ..*effects
    };
    check_effects(&effects)?;
    let marker = board.marker()?;
    let prepared = Prepared::with_modules(
        &scene.camera,
        [w, h],
        (&marker, &scene.pose),
        board.squares_dark(),
        effects.quiet_zone_modules,
    );
    let (image, encoded) = draw_photo(&scene.camera, [w, h], &[prepared], &effects)?;
    Ok(RenderedBoard {
        image,
        encoded,
        truth,
    })
}
