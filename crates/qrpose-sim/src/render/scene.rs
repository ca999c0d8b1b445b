//! Several codes in one frame: [`MultiScene`] (one camera and image, a list of
//! [`CodePlacement`]s), its result [`RenderedScene`], and the helpers that tell whether two
//! codes' image outlines overlap ([`code_outline_px`], [`quad_separation_px`],
//! [`quads_overlap`], [`codes_overlap`], [`MultiScene::overlapping_pairs`]).
//!
//! Codes are drawn in the order given, a later one over an earlier one, quiet zone included.
//! Each code's ground truth is where it was placed, hidden or not: occlusion is the caller's
//! business (check [`MultiScene::overlapping_pairs`] before rendering, or place codes with
//! [`super::random_scene`], which never overlaps them).

use super::symbol::{code_ground_truth, marker_point, symbol_modules};
use super::{EcLevel, GroundTruth, RenderError, Scene};
use qrpose_core::geometry::{camera::Camera, frames::MarkerToCamera, marker::Marker};
use qrpose_detect::decode::GrayImage;

/// One code of a [`MultiScene`]: what it says and where it is.
#[derive(Debug, Clone, PartialEq)]
pub struct CodePlacement {
    /// The symbol's content.
    pub payload: Vec<u8>,
    /// Error correction level.
    pub ec_level: EcLevel,
    /// The printed code.
    pub marker: Marker,
    /// The marker's pose.
    pub pose: MarkerToCamera,
}

/// Several codes seen by one camera, drawn in order (a later code hides an earlier one where
/// they overlap). An empty list renders the background alone.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiScene {
    /// The camera (intrinsics and distortion, px).
    pub camera: Camera,
    /// Image width, px.
    pub width_px: u32,
    /// Image height, px.
    pub height_px: u32,
    /// The codes, bottom first.
    pub codes: Vec<CodePlacement>,
}

/// A rendered multi-code photo.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedScene {
    /// The pixels before encoding.
    pub image: GrayImage,
    /// The encoded file (JPEG or PNG).
    pub encoded: Vec<u8>,
    /// Where each code was placed, in the order of [`MultiScene::codes`].
    pub truth: Vec<GroundTruth>,
}

impl Scene {
    /// The scene's one code.
    pub fn code(&self) -> CodePlacement {
        CodePlacement {
            payload: self.payload.clone(),
            ec_level: self.ec_level,
            marker: self.marker,
            pose: self.pose,
        }
    }
}

impl From<&Scene> for MultiScene {
    fn from(scene: &Scene) -> Self {
        Self {
            camera: scene.camera,
            width_px: scene.width_px,
            height_px: scene.height_px,
            codes: vec![scene.code()],
        }
    }
}

/// Wraps the error of code `index` as [`RenderError::Code`].
pub(super) fn at_code(index: usize) -> impl Fn(RenderError) -> RenderError {
    move |error| RenderError::Code {
        index,
        error: Box::new(error),
    }
}

impl MultiScene {
    /// The ground truth of every code, in order (see [`code_ground_truth`]).
    ///
    /// # Errors
    /// [`RenderError::Code`] around the first code's [`code_ground_truth`] error.
    pub fn ground_truth(&self) -> Result<Vec<GroundTruth>, RenderError> {
        self.codes
            .iter()
            .enumerate()
            .map(|(i, code)| code_ground_truth(&self.camera, code).map_err(at_code(i)))
            .collect()
    }

    /// Every pair (i, j), i < j, of codes whose image outlines with `quiet_zone_modules` of
    /// quiet zone overlap or touch ([`codes_overlap`]). Empty when no code hides another.
    ///
    /// # Errors
    /// [`RenderError::Code`] around the first code's [`code_outline_px`] error.
    pub fn overlapping_pairs(
        &self,
        quiet_zone_modules: f64,
    ) -> Result<Vec<(usize, usize)>, RenderError> {
        let outlines = self
            .codes
            .iter()
            .enumerate()
            .map(|(i, code)| {
                code_outline_px(&self.camera, code, quiet_zone_modules).map_err(at_code(i))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut pairs = Vec::new();
        for (i, a) in outlines.iter().enumerate() {
            for (j, b) in outlines.iter().enumerate().skip(i + 1) {
                if quads_overlap(a, b) {
                    pairs.push((i, j));
                }
            }
        }
        Ok(pairs)
    }
}

/// The image outline of a code with `quiet_zone_modules` of quiet zone around it: its four
/// outer corners projected, px, qr order (TL, TR, BR, BL). With lens distortion the sides
/// bow slightly between these corners.
///
/// # Errors
/// [`RenderError::Encode`], or [`RenderError::OutOfView`] when a corner is behind the
/// camera.
pub fn code_outline_px(
    camera: &Camera,
    code: &CodePlacement,
    quiet_zone_modules: f64,
) -> Result<[[f64; 2]; 4], RenderError> {
    let (n, _) = symbol_modules(&code.payload, code.ec_level)?;
    let (lo, hi) = (-quiet_zone_modules, n as f64 + quiet_zone_modules);
    let mut outline = [[0.0; 2]; 4];
    for (corner, (u, v)) in outline
        .iter_mut()
        .zip([(lo, lo), (hi, lo), (hi, hi), (lo, hi)])
    {
        let p = camera
            .project(&code.pose.transform(&marker_point(u, v, &code.marker, n)))
            .ok_or(RenderError::OutOfView)?;
        *corner = [p.u(), p.v()];
    }
    Ok(outline)
}

/// How far apart two convex quadrilaterals are, px: the largest gap between their
/// projections on the normal of any of their sides (either winding). Positive: at least that
/// far apart; zero or negative: they touch or overlap. For non-convex input the answer errs
/// towards overlap.
pub fn quad_separation_px(a: &[[f64; 2]; 4], b: &[[f64; 2]; 4]) -> f64 {
    let span = |q: &[[f64; 2]; 4], n: [f64; 2]| {
        q.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                let d = p[0] * n[0] + p[1] * n[1];
                (lo.min(d), hi.max(d))
            })
    };
    let mut best = f64::NEG_INFINITY;
    for q in [a, b] {
        for i in 0..4 {
            let (p, r) = (q[i], q[(i + 1) % 4]);
            let (ex, ey) = (r[0] - p[0], r[1] - p[1]);
            let len = ex.hypot(ey);
            // Skip repeated corners (and NaN sides).
            if len.is_nan() || len <= 1e-12 {
                continue;
            }
            let normal = [-ey / len, ex / len];
            let ((alo, ahi), (blo, bhi)) = (span(a, normal), span(b, normal));
            best = best.max((blo - ahi).max(alo - bhi));
        }
    }
    best
}

/// Whether two convex quadrilaterals (image outlines, px) overlap or touch.
pub fn quads_overlap(a: &[[f64; 2]; 4], b: &[[f64; 2]; 4]) -> bool {
    quad_separation_px(a, b) <= 0.0
}

/// Whether two codes' image outlines with `quiet_zone_modules` of quiet zone overlap or
/// touch, so that rendering one after the other would hide part of the first (pass the
/// [`super::Effects::quiet_zone_modules`] of the render; 0 compares the symbols alone).
///
/// # Errors
/// [`code_outline_px`]'s, wrapped as [`RenderError::Code`] with index 0 for `a` and 1 for
/// `b`.
pub fn codes_overlap(
    camera: &Camera,
    a: &CodePlacement,
    b: &CodePlacement,
    quiet_zone_modules: f64,
) -> Result<bool, RenderError> {
    let qa = code_outline_px(camera, a, quiet_zone_modules).map_err(at_code(0))?;
    let qb = code_outline_px(camera, b, quiet_zone_modules).map_err(at_code(1))?;
    Ok(quads_overlap(&qa, &qb))
}
