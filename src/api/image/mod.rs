//! `POST /v1/pose/image` and `qrpose estimate --image`: one photo in, every QR code's
//! payload, sub-pixel corners and pose out.
//!
//! This is the wire layer only: the request forms, their validation into the pipeline's
//! types, and the response. The work is [`locate_markers`] of the detect crate. The request
//! comes as JSON ([`ImageRequest`], the multipart `request` part) or as flat parameters
//! ([`ImageQuery`]: the raw-body query string and the CLI's flags) and is validated before
//! the image is decoded.
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
//!   ([`DEFAULT_POINTS`]: on the 200-image benchmark finders did not win, see
//!   docs/detection.md). A marker whose finder corners could not all be measured falls back
//!   to its four corners, and `points_used` says so.

pub mod per_marker;
pub mod query;
pub mod response;

pub use query::ImageQuery;
pub use response::{
    ImageResponse, ImageSizeDto, ImageWarningDto, MarkerResultDto, PassDto, TimingDto,
};

use super::context::{missing_marker, resolve_camera};
use super::frames::{PriorDto, SiteView, ValidPrior};
use super::problem::{ErrorCode, Problem};
use super::refusal::{problem_from_decode_error, problem_from_detect_error};
use super::request::{CameraDto, CornersUnit, MarkerDto, PoseSetup, SolverDto};
use crate::detect::{
    Backend, Budget, DetectorChoice, Effort, decode,
    pipeline::{Options, Points, Setup, locate_markers},
};
use crate::estimate::Method;
use crate::geometry::marker::Marker;
use per_marker::MarkerContext;
use qrpose_site::{Site, SiteCamera};
use serde::{Deserialize, Serialize};
use std::time::Duration;
use std::time::Instant;
use utoipa::ToSchema;

/// Which detector library reads the image.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema, clap::ValueEnum,
)]
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

/// How hard detection looks (see `max_detect_ms` for the deadline).
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum EffortDto {
    /// One read of the frame at full resolution; cheapest.
    Fast,
    /// Full-resolution and half-scale reads, then more passes only where a finder-pattern
    /// triple was found but not read (default).
    #[default]
    Balanced,
    /// As balanced, then every detector and image variant on the whole frame.
    Thorough,
}

impl From<EffortDto> for Effort {
    fn from(e: EffortDto) -> Self {
        match e {
            EffortDto::Fast => Effort::Fast,
            EffortDto::Balanced => Effort::Balanced,
            EffortDto::Thorough => Effort::Thorough,
        }
    }
}

/// Limits of the image path that the server (or the CLI) sets, not the request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageLimits {
    /// Encoded size and pixel count.
    pub decode: decode::DecodeLimits,
    /// The largest detection deadline a request may ask for, ms; also the cap of the
    /// effort's default deadline.
    pub max_detect_ms: f64,
}

/// The default cap of `max_detect_ms`, ms (`qrpose serve --max-detect-ms`).
pub const DEFAULT_MAX_DETECT_MS: f64 = 5000.0;

impl Default for ImageLimits {
    fn default() -> Self {
        Self {
            decode: decode::DecodeLimits::default(),
            max_detect_ms: DEFAULT_MAX_DETECT_MS,
        }
    }
}

/// Which image points the pose is solved from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum PointsDto {
    /// The symbol's four corners.
    Corners,
    /// The twelve outer corners of the three finder patterns (`reprojection` only).
    Finders,
}

impl From<PointsDto> for Points {
    fn from(p: PointsDto) -> Self {
        match p {
            PointsDto::Corners => Points::Corners,
            PointsDto::Finders => Points::Finders,
        }
    }
}

impl From<Points> for PointsDto {
    fn from(p: Points) -> Self {
        match p {
            Points::Corners => PointsDto::Corners,
            Points::Finders => PointsDto::Finders,
        }
    }
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
    /// Camera intrinsics of the image, pixel or sensor form, or `{"id": …}` naming a camera
    /// of the loaded site.
    pub camera: CameraDto,
    /// The printed code: every code in the image is taken to have this size. Omit it with a
    /// site, to size each code by its payload (`marker_size_source` says how).
    #[serde(default)]
    pub marker: Option<MarkerDto>,
    /// Solver and parameters (all optional).
    #[serde(default)]
    pub solver: SolverDto,
    /// Detector library (default `auto`).
    #[serde(default)]
    pub detector: DetectorDto,
    /// Points to solve from (default `corners`; `finders` needs `reprojection`).
    #[serde(default)]
    pub points: Option<PointsDto>,
    /// How hard detection looks: `fast`, `balanced` (default) or `thorough`.
    #[serde(default)]
    pub effort: EffortDto,
    /// Detection deadline, ms (> 0): no detection pass starts after it, and the response
    /// carries the warning `detection_budget_exhausted` when one was skipped. Default: the
    /// effort's own, which grows with the image (about 85 ms for 1920 × 1080 at
    /// `balanced`); at most the server's `--max-detect-ms`.
    #[schema(example = 100.0, exclusive_minimum = 0.0)]
    pub max_detect_ms: Option<f64>,
    /// An expected orientation that picks between the two poses of the planar ambiguity of
    /// each code (`reprojection` only).
    #[serde(default)]
    pub prior: Option<PriorDto>,
}

/// A validated image request: what [`locate_markers`] takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValidImageRequest {
    /// Camera, marker, solver. Without a request size the marker is a stand-in, and each
    /// code is solved again with its site size.
    pub setup: Setup,
    /// Detector and points.
    pub options: Options,
    /// The request gave the marker size (else the site sizes each code).
    pub size_from_request: bool,
    /// The prior, validated.
    pub prior: Option<ValidPrior>,
}

/// The size the codes are first solved with when the site sizes each code, mm: any valid
/// size does, since each code is solved again with its own.
const STAND_IN_SIZE_MM: f64 = 100.0;

/// The default `points` with `method = reprojection`, chosen from the accuracy benchmark
/// (`docs/detection.md`).
pub const DEFAULT_POINTS: PointsDto = PointsDto::Corners;

impl ImageRequest {
    /// Validates the request (before any image is decoded); `max_detect_ms` caps the
    /// detection deadline.
    ///
    /// # Errors
    /// The corners request's camera / marker / solver problems; `detector_unavailable` for
    /// a backend not in this build; `points_need_reprojection` for `finders` with another
    /// method; `invalid_detection_budget` for a `max_detect_ms` that is not positive.
    pub fn validate(&self, max_detect_ms: f64) -> Result<ValidImageRequest, Problem> {
        self.validate_in(max_detect_ms, None)
            .map(|(valid, _)| valid)
    }

    /// [`ImageRequest::validate`] against `site`: `camera.id` names a site camera (also
    /// returned), and without `marker` the site sizes each code.
    ///
    /// # Errors
    /// As [`ImageRequest::validate`], and `unknown_camera`, `invalid_prior`, or
    /// `missing_field` (`/marker`) without a marker and without a site.
    pub fn validate_in<'a>(
        &self,
        max_detect_ms: f64,
        site: Option<&'a Site>,
    ) -> Result<(ValidImageRequest, Option<&'a SiteCamera>), Problem> {
        // Without a site a missing marker is refused first, as the required field it was.
        if self.marker.is_none() && site.is_none() {
            return Err(missing_marker());
        }
        let resolved = resolve_camera(&self.camera, CornersUnit::Px, site)?;
        let marker = match (&self.marker, site) {
            (Some(m), _) => m.to_marker()?,
            (None, Some(_)) => Marker::try_new(STAND_IN_SIZE_MM).map_err(|e| {
                Problem::new(ErrorCode::InvalidMarkerSize, e.to_string()).with_field("/marker")
            })?,
            (None, None) => return Err(missing_marker()),
        };
        let setup = PoseSetup {
            camera: resolved.camera,
            marker,
            solver: self.solver.to_solver()?,
            mm_per_px: None,
        };
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
        let reprojection = setup.solver.method() == Method::Reprojection;
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
        let budget = self.budget(max_detect_ms)?;
        let prior = self.prior.as_ref().map(PriorDto::validate).transpose()?;
        let valid = ValidImageRequest {
            setup: Setup {
                camera: setup.camera,
                marker: setup.marker,
                solver: setup.solver,
            },
            options: Options {
                detector,
                points: points.into(),
                budget,
            },
            size_from_request: self.marker.is_some(),
            prior,
        };
        Ok((valid, resolved.site_camera))
    }
}

impl ImageRequest {
    /// The detection budget: the effort, and the deadline asked for (or the effort's default
    /// for the image, decided once its size is known) capped at `cap_ms`.
    fn budget(&self, cap_ms: f64) -> Result<Budget, Problem> {
        let cap = Duration::from_secs_f64(cap_ms.max(0.0) / 1e3);
        let max_detect = match self.max_detect_ms {
            None => None,
            Some(ms) if ms.is_finite() && ms > 0.0 => {
                Some(Duration::from_secs_f64(ms.min(cap_ms) / 1e3))
            }
            Some(ms) => {
                return Err(Problem::new(
                    ErrorCode::InvalidDetectionBudget,
                    format!("max_detect_ms must be a positive number of milliseconds, got {ms}"),
                )
                .with_field("/max_detect_ms"));
            }
        };
        Ok(Budget {
            effort: self.effort.into(),
            max_detect: max_detect.or(Some(cap)),
        })
    }
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
    limits: &ImageLimits,
) -> Result<ImageResponse, Problem> {
    estimate_image_in(bytes, request, limits, None)
}

/// [`estimate_image`] against `site`: cameras by id, each code sized by its payload, poses
/// in the robot's and the warehouse's frame and the fused `localization`
/// (`docs/site.md`).
///
/// # Errors
/// As [`estimate_image`], and the site's refusals of the request (`unknown_camera`). A
/// code the site cannot size is not an error: it has `pose: null` and the problem
/// `unknown_marker_size`.
pub fn estimate_image_in(
    bytes: &[u8],
    request: &ImageRequest,
    limits: &ImageLimits,
    site: Option<&Site>,
) -> Result<ImageResponse, Problem> {
    let (mut valid, site_camera) = request.validate_in(limits.max_detect_ms, site)?;
    let started = Instant::now();
    let image =
        decode::decode_gray(bytes, &limits.decode).map_err(|e| problem_from_decode_error(&e))?;
    let decode_ms = started.elapsed().as_secs_f64() * 1e3;
    if request.max_detect_ms.is_none() {
        // The effort's default deadline for this image, within the cap.
        let default = valid
            .options
            .budget
            .effort
            .default_deadline(image.pixels().len());
        valid.options.budget.max_detect =
            valid.options.budget.max_detect.map(|cap| cap.min(default));
    }
    let located = locate_markers(&image, &valid.setup, &valid.options)
        .map_err(|e| problem_from_detect_error(&e))?;
    let size = ImageSizeDto {
        width_px: image.width(),
        height_px: image.height(),
    };
    let context = MarkerContext {
        valid: &valid,
        view: SiteView {
            site,
            camera: site_camera,
        },
    };
    Ok(ImageResponse::new(&located, &context, size, decode_ms))
}

/// [`estimate_image`] for a request given as flat parameters (the raw-body query string,
/// the CLI's flags): a problem's `field` names the parameter.
///
/// # Errors
/// As [`estimate_image`], and `missing_field` without the marker size.
pub fn estimate_image_from_query(
    bytes: &[u8],
    query: ImageQuery,
    limits: &ImageLimits,
) -> Result<ImageResponse, Problem> {
    estimate_image_from_query_in(bytes, query, limits, None)
}

/// [`estimate_image_from_query`] against `site` ([`estimate_image_in`]).
///
/// # Errors
/// As [`estimate_image_in`], with `field` naming the parameter.
pub fn estimate_image_from_query_in(
    bytes: &[u8],
    query: ImageQuery,
    limits: &ImageLimits,
    site: Option<&Site>,
) -> Result<ImageResponse, Problem> {
    query
        .into_request()
        .and_then(|request| estimate_image_in(bytes, &request, limits, site))
        .map_err(ImageQuery::problem_in_query_terms)
}
