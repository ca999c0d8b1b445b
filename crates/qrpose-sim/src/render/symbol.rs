//! The symbol and where it lies: the module matrix of a payload ([`symbol_modules`]),
//! module coordinates on the marker plane ([`marker_point`]), and the ground truth of a
//! code (corners and finder corners projected by the camera, [`code_ground_truth`]; of a
//! single-code scene, [`ground_truth`]).

use super::{CodePlacement, EcLevel, GroundTruth, RenderError, Scene};
use qrpose_core::geometry::{camera::Camera, frames::MarkerPoint, marker::Marker};
use qrpose_detect::refine::{ModulePoint, finder_model_points, marker_point_of_module};

/// The module matrix of a payload: (N, row-major dark flags).
///
/// # Errors
/// [`RenderError::Encode`] when the payload does not fit.
pub fn symbol_modules(
    payload: &[u8],
    ec_level: EcLevel,
) -> Result<(usize, Vec<bool>), RenderError> {
    let level = match ec_level {
        EcLevel::L => qrcode::EcLevel::L,
        EcLevel::M => qrcode::EcLevel::M,
        EcLevel::Q => qrcode::EcLevel::Q,
        EcLevel::H => qrcode::EcLevel::H,
    };
    let code = qrcode::QrCode::with_error_correction_level(payload, level).map_err(|e| {
        RenderError::Encode {
            reason: e.to_string(),
        }
    })?;
    let n = code.width();
    let dark = code
        .to_colors()
        .into_iter()
        .map(|c| c == qrcode::Color::Dark)
        .collect();
    Ok((n, dark))
}

/// Where a marker-plane point (x, y) lies in module coordinates (u right, v down).
pub(super) fn module_coords(x_mm: f64, y_mm: f64, l_mm: f64, n: f64) -> (f64, f64) {
    ((x_mm + l_mm) / l_mm * n, y_mm / l_mm * n)
}

/// The marker-frame point of a module coordinate.
pub fn marker_point(u: f64, v: f64, marker: &Marker, n: usize) -> MarkerPoint {
    marker_point_of_module(ModulePoint::new(u, v), marker, n)
}

/// The ground truth of a scene: corners and finder corners projected by the camera.
///
/// # Errors
/// [`RenderError::Encode`], or [`RenderError::OutOfView`] when a corner is behind the
/// camera.
pub fn ground_truth(scene: &Scene) -> Result<GroundTruth, RenderError> {
    code_ground_truth(&scene.camera, &scene.code())
}

/// The ground truth of one code seen by a camera: its corners and finder corners projected,
/// and its pose. Where the code was placed, whatever else the frame holds.
///
/// # Errors
/// [`RenderError::Encode`], or [`RenderError::OutOfView`] when a corner is behind the
/// camera.
pub fn code_ground_truth(
    camera: &Camera,
    code: &CodePlacement,
) -> Result<GroundTruth, RenderError> {
    let (n, _) = symbol_modules(&code.payload, code.ec_level)?;
    let project = |u: f64, v: f64| -> Result<[f64; 2], RenderError> {
        let p = camera
            .project(&code.pose.transform(&marker_point(u, v, &code.marker, n)))
            .ok_or(RenderError::OutOfView)?;
        Ok([p.u(), p.v()])
    };
    let nf = n as f64;
    let corners_px = [
        project(0.0, 0.0)?,
        project(nf, 0.0)?,
        project(nf, nf)?,
        project(0.0, nf)?,
    ];
    let mut finder_corners_px = [[0.0; 2]; 12];
    let finder_points = finder_model_points(n);
    for (k, p) in finder_points.iter().enumerate() {
        finder_corners_px[k] = project(p.u, p.v)?;
    }
    let r = code.pose.rotation();
    let m = r.matrix();
    let t = code.pose.translation_mm();
    let centre = code.pose.transform(&code.marker.centre()).0;
    Ok(GroundTruth {
        module_count: n,
        corners_px,
        finder_corners_px,
        rotation_matrix: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
        reference_point_mm: [t.x, t.y, t.z],
        position_mm: [centre.x, centre.y, centre.z],
    })
}
