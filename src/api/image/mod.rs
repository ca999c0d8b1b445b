//! `POST /v1/pose/image` and `qrpose estimate --image`: one photo in, every QR code's
//! payload, sub-pixel corners and pose out.
//!
//! This is the wire layer only: the request forms, their validation into the application
//! layer's [`ImageSetup`], and the response mapped from its answer. The work is
//! [`crate::app::estimate_image`]. The request comes as JSON ([`ImageRequest`], the
//! multipart `request` part), as flat parameters ([`ImageQuery`]: the raw-body query string
//! and the CLI's flags) or as both (a multipart body with query parameters, [`merge`]), and
//! is validated before the image is decoded.
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

pub mod merge;
pub mod query;
pub mod response;

pub use crate::app::ImageLimits;
pub use query::ImageQuery;
pub use response::{
    ImageResponse, ImageSizeDto, ImageWarningDto, MarkerResultDto, PassDto, TimingDto,
};

use super::alternatives::Rule;
use super::context::{missing_marker, resolve_camera};
use super::frames::PriorDto;
use super::problem::{ErrorCode, Problem};
use super::refusal::problem_from_image_error;
use super::request::{CameraDto, CornersUnit, MarkerDto, MethodDto, SolverDto};
use super::robot::{RobotPoseDto, pick_of};
use crate::app::{self, DetectSetup, ImageSetup, Setup, Sizing};
use crate::detect::{Backend, DetectorChoice, Effort, cancel::CancelFlag, pipeline::Points};
use crate::estimate::Method;
use qrpose_site::{Site, SizeSource};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::Duration;
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

/// The image request's cross-field rule in the document ([`crate::api::alternatives`]):
/// `points = finders` needs `method = reprojection` (else `points_need_reprojection`; an
/// omitted method is `reprojection`), so the request is not one with `points: finders` and
/// another `solver.method`.
#[must_use]
pub fn finders_need_reprojection() -> Rule {
    use clap::ValueEnum;
    let others: Vec<serde_json::Value> = MethodDto::value_variants()
        .iter()
        .filter(|m| Method::from(**m) != Method::Reprojection)
        .map(|m| serde_json::json!(m))
        .collect();
    Rule::Not {
        component: "ImageRequest",
        schema: serde_json::json!({
            "required": ["points", "solver"],
            "properties": {
                "points": {"const": PointsDto::Finders},
                "solver": {"required": ["method"], "properties": {"method": {"enum": others}}},
            },
        }),
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
    #[schema(default = DetectorDto::default)]
    pub detector: DetectorDto,
    /// Points to solve from (default `corners`; `finders` needs `reprojection`).
    #[serde(default)]
    pub points: Option<PointsDto>,
    /// How hard detection looks: `fast`, `balanced` (default) or `thorough`.
    #[serde(default)]
    #[schema(default = EffortDto::default)]
    pub effort: EffortDto,
    /// Detection deadline, ms (> 0): no detection pass starts after it, and the response
    /// carries the warning `detection_budget_exhausted` when one was skipped. Default: the
    /// effort's own, which grows with the image (about 85 ms for 1920 × 1080 at
    /// `balanced`); at most the server's `--max-detect-ms`.
    #[schema(example = 100.0, exclusive_minimum = 0)]
    pub max_detect_ms: Option<f64>,
    /// An expected orientation that picks between the two poses of the planar ambiguity of
    /// each code (`reprojection` only).
    #[serde(default)]
    pub prior: Option<PriorDto>,
    /// The arm's pose (T_robot←flange, as the controller reports it) when the photo was
    /// taken: with a camera on the flange (`mount.parent: flange`), poses in the robot frame
    /// exist only with it (`docs/pick.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flange_pose: Option<RobotPoseDto>,
    /// The least probability of landing within tolerance for a grasp to be `graspable`
    /// (default 0.95).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 0, maximum = 1, example = 0.95)]
    pub min_grasp_probability: Option<f64>,
}

/// The default `points` with `method = reprojection`, chosen from the accuracy benchmark
/// (`docs/detection.md`).
pub const DEFAULT_POINTS: PointsDto = PointsDto::Corners;

impl ImageRequest {
    /// Validates the request against `site` (none: intrinsics and size must be in the
    /// request), before any image is decoded: `camera.id` names a site camera, and without
    /// `marker` the site sizes each code by its payload. `limits` caps the detection
    /// deadline and bounds the decode.
    ///
    /// # Errors
    /// The corners request's camera / marker / solver problems; `detector_unavailable` for
    /// a backend not in this build; `points_need_reprojection` for `finders` with another
    /// method; `invalid_detection_budget` for a `max_detect_ms` that is not positive;
    /// `unknown_camera`, `invalid_prior`, or `missing_field` (`/marker`) without a marker
    /// and without a site.
    pub fn setup(
        &self,
        limits: &ImageLimits,
        site: Option<Arc<Site>>,
    ) -> Result<ImageSetup, Problem> {
        // Without a site a missing marker is refused first, as the required field it was.
        if self.marker.is_none() && site.is_none() {
            return Err(missing_marker());
        }
        let resolved = resolve_camera(&self.camera, CornersUnit::Px, site.as_deref())?;
        let sizing = match &self.marker {
            Some(m) => Sizing::Fixed {
                marker: m.to_marker()?,
                source: SizeSource::Request,
            },
            None => Sizing::BySite,
        };
        let solver = self.solver.to_solver()?;
        self.check_detector()?;
        let detector: DetectorChoice = self.detector.into();
        let reprojection = solver.method() == Method::Reprojection;
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
        let max_detect = self.max_detect(limits.max_detect)?;
        let prior = self.prior.as_ref().map(PriorDto::validate).transpose()?;
        let site_camera = resolved.site_camera.cloned();
        Ok(ImageSetup {
            pose: Setup {
                camera: resolved.camera,
                site_camera,
                site,
                sizing,
                solver,
                prior,
                pick: pick_of(self.flange_pose.as_ref(), self.min_grasp_probability)?,
            },
            detect: DetectSetup {
                detector,
                points: points.into(),
                effort: self.effort.into(),
                max_detect,
                max_detect_cap: limits.max_detect,
            },
            decode: limits.decode,
        })
    }

    /// Refuses a detector that is not built into this server.
    fn check_detector(&self) -> Result<(), Problem> {
        match DetectorChoice::from(self.detector) {
            DetectorChoice::Only(backend) if !backend.is_built() => Err(Problem::new(
                ErrorCode::DetectorUnavailable,
                format!(
                    "the {} detector is not built into this server (cargo feature `zxing-cpp`); use auto, rqrr or rxing",
                    backend.as_str()
                ),
            )
            .with_field("/detector")),
            _ => Ok(()),
        }
    }

    /// The detection deadline asked for, capped at `cap`; `None` for the effort's default
    /// (decided once the image's size is known, [`DetectSetup::budget`]).
    fn max_detect(&self, cap: Duration) -> Result<Option<Duration>, Problem> {
        match self.max_detect_ms {
            None => Ok(None),
            Some(ms) if ms.is_finite() && ms > 0.0 => {
                // Capped before the conversion, which panics past u64 seconds.
                let capped_ms = ms.min(cap.as_secs_f64() * 1e3);
                Ok(Some(Duration::from_secs_f64(capped_ms / 1e3)))
            }
            Some(ms) => Err(Problem::new(
                ErrorCode::InvalidDetectionBudget,
                format!("max_detect_ms must be a positive number of milliseconds, got {ms}"),
            )
            .with_field("/max_detect_ms")),
        }
    }
}

/// Finds every QR code in a photo and estimates its pose, as `setup` says, and maps the
/// answer; `cancel` stops detection before its next pass. CPU-bound and synchronous.
///
/// # Errors
/// 413 `payload_too_large` / `image_too_large` for an image over the setup's limits, 422
/// `undecodable_image` for one that cannot be decoded, 422 `detector_unavailable`. Finding
/// no code is not an error; neither is a marker without a pose (it carries its own
/// `problem`).
pub fn respond(
    setup: &ImageSetup,
    bytes: &[u8],
    cancel: CancelFlag,
) -> Result<ImageResponse, Problem> {
    answer(setup, bytes, cancel).map(|(_, response)| response)
}

/// [`respond`] with the application's answer the response was made from (what the
/// annotated image draws).
///
/// # Errors
/// As [`respond`].
pub fn answer(
    setup: &ImageSetup,
    bytes: &[u8],
    cancel: CancelFlag,
) -> Result<(app::ImageAnswer, ImageResponse), Problem> {
    let answer =
        app::estimate_image(setup, bytes, cancel).map_err(|e| problem_from_image_error(&e))?;
    let response = ImageResponse::from_answer(&answer, setup);
    Ok((answer, response))
}

/// Validates `request` against `site`, then [`respond`] (never cancelled): the image path
/// as one call, for the command line and tests.
///
/// # Errors
/// The request's problems (422, before decoding), then those of [`respond`].
pub fn estimate_image(
    bytes: &[u8],
    request: &ImageRequest,
    limits: &ImageLimits,
    site: Option<Arc<Site>>,
) -> Result<ImageResponse, Problem> {
    let setup = request.setup(limits, site)?;
    respond(&setup, bytes, CancelFlag::new())
}
