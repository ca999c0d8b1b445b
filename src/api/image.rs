//! `POST /v1/pose/image` and `qrpose estimate --image`: one photo in, every QR code's
//! payload, sub-pixel corners and pose out.
//!
//! [`estimate_image`] is CPU-bound and synchronous (the HTTP layer runs it on its
//! bounded worker queue, `http::queue`). Its request comes as JSON ([`ImageRequest`], the
//! multipart `request` part) or as flat query parameters ([`ImageQuery`], for a raw image
//! body) and is validated before the image is decoded.
//!
//! Decisions a client should know:
//! - No code found is a success with `markers: []`.
//! - `payload` is the content as text (decoded by the backend with the symbol's ECI /
//!   character set); `payload_base64` always carries the raw content bytes (standard
//!   base64, padded), so binary payloads survive. Both are `null` for a symbol that was
//!   found but could not be decoded.
//! - A marker whose pose cannot be computed has `pose: null` and a `problem` (the same
//!   problem document an error response would carry); the other markers are unaffected.
//! - `points = "finders"` solves the pose from the twelve finder-pattern corners. It needs
//!   `method = "reprojection"` (the other methods are defined on four corners): asking for
//!   both is a 422 `points_need_reprojection`. When `points` is omitted it is `corners`
//!   ([`DEFAULT_POINTS`]: on the 200-image benchmark finders did not win, see docs/detection.md). A marker whose finder corners could not all be
//!   measured falls back to its four corners, and `points_used` says so.

use super::problem::{ErrorCode, Problem};
use super::request::{
    CameraDto, CornersUnit, DistortionDto, MarkerDto, MethodDto, PoseSetup, SolverDto, pose_setup,
    problem_from_estimate_error, problem_from_quad_error,
};
use super::response::PoseResponse;
use crate::detect::{
    Backend, DetectedCode, DetectorChoice, corners::RefineStatus, decode, detect_codes,
    finders::finder_marker_points,
};
use crate::estimate::{Method, estimate_planar_points, estimate_pose};
use crate::geometry::{frames::PixelPoint, marker::CornerOrder, quad::ImageQuad};
use base64::Engine;
use serde::{Deserialize, Serialize};
use std::time::Instant;
use utoipa::{IntoParams, ToSchema};

/// Which detector library reads the image.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "kebab-case")]
pub enum DetectorDto {
    /// The best built-in detector (zxing-cpp when built, else rxing), falling back to the
    /// others and to a contrast-stretched or half-scale second pass when it reads nothing.
    #[default]
    Auto,
    /// rqrr (pure Rust).
    Rqrr,
    /// rxing (pure Rust port of ZXing).
    Rxing,
    /// zxing-cpp (only in builds with the `zxing-cpp` feature; otherwise a 422
    /// `detector_unavailable`).
    ZxingCpp,
}

impl From<DetectorDto> for DetectorChoice {
    fn from(d: DetectorDto) -> Self {
        match d {
            DetectorDto::Auto => DetectorChoice::Auto,
            DetectorDto::Rqrr => DetectorChoice::Only(Backend::Rqrr),
            DetectorDto::Rxing => DetectorChoice::Only(Backend::Rxing),
            DetectorDto::ZxingCpp => DetectorChoice::Only(Backend::ZxingCpp),
        }
    }
}

/// Which image points the pose is solved from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum PointsDto {
    /// The symbol's four corners.
    Corners,
    /// The twelve outer corners of the three finder patterns (`reprojection` only).
    Finders,
}

/// `POST /v1/pose/image` as JSON (the multipart `request` part): the corners request
/// without corners, plus the detector and the points to solve from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({
    "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
    "marker": {"size_mm": 50.0},
    "detector": "auto",
    "points": "finders"
}))]
pub struct ImageRequest {
    /// Camera intrinsics of the image, pixel or sensor form.
    pub camera: CameraDto,
    /// The printed code (every code in the image is assumed to have this size).
    pub marker: MarkerDto,
    /// Solver and parameters (all optional).
    #[serde(default)]
    pub solver: SolverDto,
    /// Detector library (default `auto`).
    #[serde(default)]
    pub detector: DetectorDto,
    /// Points to solve from (default `corners`; `finders` needs `reprojection`).
    #[serde(default)]
    pub points: Option<PointsDto>,
}

/// The same request as flat query parameters, for a raw image body.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ImageQuery {
    /// Horizontal focal length, px.
    pub fx_px: Option<f64>,
    /// Vertical focal length, px.
    pub fy_px: Option<f64>,
    /// Principal point, horizontal, px (integer = pixel centre).
    pub cx_px: Option<f64>,
    /// Principal point, vertical, px.
    pub cy_px: Option<f64>,
    /// Lens focal length, mm (sensor form, with `pixel_size_um`).
    pub focal_length_mm: Option<f64>,
    /// Pixel pitch, µm (sensor form).
    pub pixel_size_um: Option<f64>,
    /// Radial distortion r² coefficient (OpenCV's k1).
    pub k1: Option<f64>,
    /// Radial r⁴ coefficient.
    pub k2: Option<f64>,
    /// Radial r⁶ coefficient.
    pub k3: Option<f64>,
    /// Tangential coefficient p1.
    pub p1: Option<f64>,
    /// Tangential coefficient p2.
    pub p2: Option<f64>,
    /// Side of the QR symbol, mm (finder edge to finder edge, quiet zone excluded). Required.
    pub marker_size_mm: Option<f64>,
    /// Solver: `paper`, `depth-newton` or `reprojection` (default).
    pub method: Option<MethodDto>,
    /// Detector: `auto` (default), `rqrr`, `rxing`, `zxing-cpp`.
    pub detector: Option<DetectorDto>,
    /// Points: `corners` or `finders` (default as in the JSON form).
    pub points: Option<PointsDto>,
    /// Starting depth, mm (`paper`, `depth-newton`).
    pub initial_z_mm: Option<f64>,
    /// Gain k of the paper's Eq. 12 (`paper`).
    pub gain: Option<f64>,
    /// Convergence threshold, mm (`paper`).
    pub tolerance_mm: Option<f64>,
    /// Iteration limit, 1 to 10000.
    pub max_iterations: Option<u64>,
    /// Return the per-iteration trace.
    pub trace: Option<bool>,
    /// Corner noise σ for the covariance, px.
    pub corner_sigma_px: Option<f64>,
}

impl ImageQuery {
    /// The JSON-form request these parameters stand for.
    ///
    /// # Errors
    /// `missing_field` (field `marker_size_mm`) when the marker size is absent.
    pub fn into_request(self) -> Result<ImageRequest, Problem> {
        let size_mm = self.marker_size_mm.ok_or_else(|| {
            Problem::new(ErrorCode::MissingField, "marker_size_mm is required")
                .with_field("marker_size_mm")
        })?;
        let any_distortion = [self.k1, self.k2, self.k3, self.p1, self.p2]
            .iter()
            .any(Option::is_some);
        let distortion = any_distortion.then(|| DistortionDto {
            k1: self.k1.unwrap_or(0.0),
            k2: self.k2.unwrap_or(0.0),
            p1: self.p1.unwrap_or(0.0),
            p2: self.p2.unwrap_or(0.0),
            k3: self.k3.unwrap_or(0.0),
        });
        let defaults = SolverDto::default();
        Ok(ImageRequest {
            camera: CameraDto {
                fx_px: self.fx_px,
                fy_px: self.fy_px,
                cx_px: self.cx_px,
                cy_px: self.cy_px,
                focal_length_mm: self.focal_length_mm,
                pixel_size_um: self.pixel_size_um,
                distortion,
            },
            marker: MarkerDto { size_mm },
            solver: SolverDto {
                method: self.method.unwrap_or(defaults.method),
                initial_z_mm: self.initial_z_mm,
                gain: self.gain.unwrap_or(defaults.gain),
                tolerance_mm: self.tolerance_mm.unwrap_or(defaults.tolerance_mm),
                max_iterations: self.max_iterations.unwrap_or(defaults.max_iterations),
                trace: self.trace.unwrap_or(defaults.trace),
                corner_sigma_px: self.corner_sigma_px.unwrap_or(defaults.corner_sigma_px),
            },
            detector: self.detector.unwrap_or_default(),
            points: self.points,
        })
    }
}

/// Each query parameter and the JSON pointer of the same value in [`ImageRequest`].
const QUERY_PARAMETERS: [(&str, &str); 21] = [
    ("fx_px", "/camera/fx_px"),
    ("fy_px", "/camera/fy_px"),
    ("cx_px", "/camera/cx_px"),
    ("cy_px", "/camera/cy_px"),
    ("focal_length_mm", "/camera/focal_length_mm"),
    ("pixel_size_um", "/camera/pixel_size_um"),
    ("k1", "/camera/distortion/k1"),
    ("k2", "/camera/distortion/k2"),
    ("k3", "/camera/distortion/k3"),
    ("p1", "/camera/distortion/p1"),
    ("p2", "/camera/distortion/p2"),
    ("marker_size_mm", "/marker/size_mm"),
    ("method", "/solver/method"),
    ("detector", "/detector"),
    ("points", "/points"),
    ("initial_z_mm", "/solver/initial_z_mm"),
    ("gain", "/solver/gain"),
    ("tolerance_mm", "/solver/tolerance_mm"),
    ("max_iterations", "/solver/max_iterations"),
    ("trace", "/solver/trace"),
    ("corner_sigma_px", "/solver/corner_sigma_px"),
];

impl ImageQuery {
    /// `problem` with its `field` turned from a JSON pointer into the [`ImageRequest`] these
    /// parameters became (`/camera/fx_px`, `/marker/size_mm`) into the query parameter a
    /// client sent (`fx_px`, `marker_size_mm`). A pointer that no single parameter stands
    /// for (`/camera`: the camera's form as a whole) leaves no `field`; a field that is
    /// already a parameter name is kept.
    pub fn problem_in_query_terms(problem: Problem) -> Problem {
        let field = problem.field.as_deref().and_then(|field| {
            if !field.starts_with('/') {
                return Some(field.to_owned());
            }
            QUERY_PARAMETERS
                .iter()
                .find(|(_, pointer)| *pointer == field)
                .map(|(parameter, _)| (*parameter).to_owned())
        });
        Problem { field, ..problem }
    }
}

/// The image's size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct ImageSizeDto {
    /// Width, px.
    pub width_px: usize,
    /// Height, px.
    pub height_px: usize,
}

/// Time per stage, ms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TimingDto {
    /// Image decoding, ms.
    pub decode: f64,
    /// Detection, reading and corner refinement, ms.
    pub detect: f64,
    /// Pose estimation of every marker, ms.
    pub estimate: f64,
}

/// One QR code found in the image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MarkerResultDto {
    /// The content as text; null when the symbol was found but not decoded, or its bytes
    /// are not text.
    #[schema(example = "SKU-1")]
    pub payload: Option<String>,
    /// The raw content bytes, standard base64 with padding; null when not decoded.
    #[schema(example = "U0tVLTE=")]
    pub payload_base64: Option<String>,
    /// The symbol's corners, px, `"qr"` order (top-left, top-right, bottom-right,
    /// bottom-left), sub-pixel when `corners_refined` is true.
    pub corners_px: [[f64; 2]; 4],
    /// Whether the corners were refined from the image (false: the detector's whole-pixel
    /// corners, see `refinement`).
    pub corners_refined: bool,
    /// How corner refinement ended: `refined`, or why the detector's corners were kept
    /// (`too_few_edges`, `moved_too_far`, `too_small`, `unknown_module_count`).
    #[schema(example = "refined")]
    pub refinement: String,
    /// The twelve outer corners of the three finder patterns, px: top-left finder (its TL,
    /// TR, BR, BL), then the top-right finder, then the bottom-left finder; null when not
    /// all were measured.
    #[schema(value_type = Option<Vec<[f64; 2]>>)]
    pub finder_corners_px: Option<Vec<[f64; 2]>>,
    /// Modules per side (21 for version 1, 4 more per version).
    pub module_count: Option<usize>,
    /// The detector library that found the symbol: `rqrr`, `rxing` or `zxing-cpp`.
    #[schema(example = "rxing")]
    pub detector: String,
    /// The points the pose was solved from.
    pub points_used: PointsDto,
    /// The marker's pose; null when it could not be computed (see `problem`).
    pub pose: Option<PoseResponse>,
    /// Why `pose` is null: the problem document of this marker alone.
    pub problem: Option<Problem>,
}

/// `POST /v1/pose/image` response.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ImageResponse {
    /// The decoded image's size.
    pub image: ImageSizeDto,
    /// Every QR code found (empty when none).
    pub markers: Vec<MarkerResultDto>,
    /// Time per stage, ms.
    pub timing_ms: TimingDto,
}

/// A validated image request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValidImageRequest {
    /// Camera, marker, solver.
    pub setup: PoseSetup,
    /// The detector.
    pub detector: DetectorChoice,
    /// The points to solve from.
    pub points: PointsDto,
}

impl ImageRequest {
    /// Validates the request (before any image is decoded).
    ///
    /// # Errors
    /// The corners request's camera / marker / solver problems; `detector_unavailable` for
    /// a backend not in this build; `points_need_reprojection` for `finders` with another
    /// method.
    pub fn validate(&self) -> Result<ValidImageRequest, Problem> {
        let setup = pose_setup(&self.camera, &self.marker, &self.solver, CornersUnit::Px)?;
        let detector: DetectorChoice = self.detector.into();
        if let DetectorChoice::Only(backend) = detector
            && !backend.is_built()
        {
            return Err(Problem::new(
                ErrorCode::DetectorUnavailable,
                format!(
                    "the {} detector is not built into this server (cargo feature `zxing-cpp`); use auto, rqrr or rxing",
                    backend.as_str()
                ),
            )
            .with_field("/detector"));
        }
        let reprojection = setup.params.method == Method::Reprojection;
        let points = match self.points {
            Some(PointsDto::Finders) if !reprojection => {
                return Err(Problem::new(
                    ErrorCode::PointsNeedReprojection,
                    "points = finders needs method = reprojection: the paper and depth-newton methods are defined on the four corners",
                )
                .with_field("/points"));
            }
            Some(p) => p,
            None if reprojection => DEFAULT_POINTS,
            None => PointsDto::Corners,
        };
        Ok(ValidImageRequest {
            setup,
            detector,
            points,
        })
    }
}

/// The default `points` with `method = reprojection`, chosen from the accuracy benchmark
/// (`docs/detection.md`).
pub const DEFAULT_POINTS: PointsDto = PointsDto::Corners;

/// The problem for an image that could not be decoded.
pub fn problem_from_decode_error(err: &decode::DecodeError) -> Problem {
    use decode::DecodeError as E;
    let code = match err {
        E::EncodedTooLarge { .. } => ErrorCode::PayloadTooLarge,
        E::TooManyPixels { .. } => ErrorCode::ImageTooLarge,
        E::Empty | E::ZeroSize { .. } | E::UnsupportedFormat | E::Corrupt { .. } => {
            ErrorCode::UndecodableImage
        }
    };
    Problem::new(code, err.to_string())
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn pairs<const K: usize>(points: &[PixelPoint; K]) -> [[f64; 2]; K] {
    points.map(|p| [p.u(), p.v()])
}

/// The pose of one detected code, or the problem that prevents it, and the points used.
fn marker_pose(
    code: &DetectedCode,
    index: usize,
    valid: &ValidImageRequest,
) -> (PointsDto, Result<PoseResponse, Problem>) {
    let s = &valid.setup;
    let started = Instant::now();
    let pointer = format!("/markers/{index}/corners_px");
    let finders = match (
        valid.points,
        code.refinement.finder_corners_px,
        code.refinement.module_count,
    ) {
        (PointsDto::Finders, Some(image), Some(n)) => Some((image, n)),
        _ => None,
    };
    if let Some((image, n)) = finders {
        let model = finder_marker_points(&s.marker, n);
        let result = estimate_planar_points(&model, &image, &s.camera, &s.marker, &s.params)
            .map(|e| {
                PoseResponse::new(
                    &e,
                    &s.camera,
                    &s.marker,
                    started.elapsed().as_secs_f64() * 1e6,
                )
            })
            .map_err(|e| {
                problem_from_estimate_error(e, &format!("/markers/{index}/finder_corners_px"))
            });
        return (PointsDto::Finders, result);
    }
    let result = ImageQuad::try_new(*code.corners_px(), CornerOrder::Qr)
        .map_err(|e| problem_from_quad_error(e, &pointer))
        .and_then(|quad| {
            estimate_pose(&quad, &s.camera, &s.marker, &s.params)
                .map_err(|e| problem_from_estimate_error(e, &pointer))
        })
        .map(|e| {
            PoseResponse::new(
                &e,
                &s.camera,
                &s.marker,
                started.elapsed().as_secs_f64() * 1e6,
            )
        });
    (PointsDto::Corners, result)
}

/// Decodes an image, finds and reads every QR code, refines its corners and estimates its
/// pose. CPU-bound and synchronous.
///
/// # Errors
/// A [`Problem`] for an invalid request (422, before decoding), an image over `limits`
/// (413 `payload_too_large` / `image_too_large`) or one that cannot be decoded (422
/// `undecodable_image`). Finding no code is not an error; neither is a marker without a
/// pose (it carries its own `problem`).
pub fn estimate_image(
    bytes: &[u8],
    request: &ImageRequest,
    limits: &decode::DecodeLimits,
) -> Result<ImageResponse, Problem> {
    let valid = request.validate()?;
    let t_decode = Instant::now();
    let image = decode::decode_gray(bytes, limits).map_err(|e| problem_from_decode_error(&e))?;
    let decode_ms = ms_since(t_decode);
    let t_detect = Instant::now();
    let codes = detect_codes(&image, valid.detector).map_err(|e| {
        Problem::new(ErrorCode::DetectorUnavailable, e.to_string()).with_field("/detector")
    })?;
    let detect_ms = ms_since(t_detect);
    let t_estimate = Instant::now();
    let markers = codes
        .iter()
        .enumerate()
        .map(|(index, code)| {
            let (points_used, pose) = marker_pose(code, index, &valid);
            let (pose, problem) = match pose {
                Ok(p) => (Some(p), None),
                Err(p) => (None, Some(p)),
            };
            let c = &code.candidate;
            MarkerResultDto {
                payload: c.text.clone(),
                payload_base64: c
                    .payload
                    .as_ref()
                    .map(|b| base64::engine::general_purpose::STANDARD.encode(b)),
                corners_px: pairs(code.corners_px()),
                corners_refined: code.refinement.status == RefineStatus::Refined,
                refinement: code.refinement.status.as_str().to_owned(),
                finder_corners_px: code
                    .refinement
                    .finder_corners_px
                    .as_ref()
                    .map(|f| pairs(f).to_vec()),
                module_count: code.refinement.module_count,
                detector: c.backend.as_str().to_owned(),
                points_used,
                pose,
                problem,
            }
        })
        .collect();
    Ok(ImageResponse {
        image: ImageSizeDto {
            width_px: image.width(),
            height_px: image.height(),
        },
        markers,
        timing_ms: TimingDto {
            decode: decode_ms,
            detect: detect_ms,
            estimate: ms_since(t_estimate),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_query_parameter_has_its_pointer_and_every_pointer_its_parameter() {
        let all = ImageQuery {
            fx_px: Some(1.0),
            fy_px: Some(1.0),
            cx_px: Some(1.0),
            cy_px: Some(1.0),
            focal_length_mm: Some(1.0),
            pixel_size_um: Some(1.0),
            k1: Some(0.5),
            k2: Some(0.5),
            k3: Some(0.5),
            p1: Some(0.5),
            p2: Some(0.5),
            marker_size_mm: Some(1.0),
            method: Some(MethodDto::Paper),
            detector: Some(DetectorDto::Rqrr),
            points: Some(PointsDto::Corners),
            initial_z_mm: Some(1.0),
            gain: Some(1.0),
            tolerance_mm: Some(1.0),
            max_iterations: Some(1),
            trace: Some(true),
            corner_sigma_px: Some(1.0),
        };
        let names = serde_json::to_value(&all).expect("serialisable");
        let names: Vec<&String> = names.as_object().expect("an object").keys().collect();
        assert_eq!(names.len(), QUERY_PARAMETERS.len());
        let request =
            serde_json::to_value(all.into_request().expect("complete")).expect("serialisable");
        for (parameter, pointer) in QUERY_PARAMETERS {
            assert!(names.iter().any(|n| *n == parameter), "{parameter}");
            assert!(
                request.pointer(pointer).is_some_and(|v| !v.is_null()),
                "{parameter}: {pointer} is not in {request}"
            );
        }
    }

    #[test]
    fn problems_name_the_query_parameter() {
        let cases = [
            (Some("/camera/fx_px"), Some("fx_px")),
            (Some("/camera/distortion/k1"), Some("k1")),
            (Some("/marker/size_mm"), Some("marker_size_mm")),
            (Some("/solver/max_iterations"), Some("max_iterations")),
            (Some("/detector"), Some("detector")),
            (Some("marker_size_mm"), Some("marker_size_mm")),
            (Some("/camera"), None),
            (None, None),
        ];
        for (field, expected) in cases {
            let mut problem = Problem::new(ErrorCode::IncompleteCamera, "x");
            problem.field = field.map(str::to_owned);
            let renamed = ImageQuery::problem_in_query_terms(problem);
            assert_eq!(renamed.field.as_deref(), expected, "{field:?}");
        }
    }
}
