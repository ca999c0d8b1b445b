//! Request bodies of `POST /v1/pose/corners` (and the CLI's `estimate`), and their
//! validation into core types.
//!
//! Validation happens once, here, and every refusal is a [`Problem`] with a stable code and
//! the JSON pointer of the field at fault. Unknown fields are refused rather than ignored, so
//! that a typo (`max_iteration`) cannot silently fall back to a default.

use super::alternatives::{Form, Narrowed, Rule};
use super::camera::IMAGE_PLANE;
pub use super::camera::{CameraDto, DistortionDto};
use super::context::{missing_marker, resolve_camera, resolve_marker};
pub use super::frames::PriorDto;
use super::problem::{ErrorCode, Problem};
use super::refusal::problem_from_quad_error;
use super::robot::{RobotPoseDto, pick_of};
pub use super::solver::SolverDto;
use crate::app::{Setup, Sizing};
use crate::estimate::Method;
use crate::geometry::{
    camera::Camera,
    frames::PixelPoint,
    marker::{CornerOrder, Marker, MarkerError},
    quad::ImageQuad,
};
use qrpose_site::Site;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::sync::Arc;
use std::time::Instant;
use utoipa::ToSchema;

/// How the four corners are listed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum CornerOrderDto {
    /// Top-left, top-right, bottom-right, bottom-left of the symbol (OpenCV, zxing, rqrr).
    #[default]
    Qr,
    /// The paper's P1, P2, P3, P4 (bottom-right, top-right, top-left, bottom-left).
    Paper,
}

impl From<CornerOrderDto> for CornerOrder {
    fn from(o: CornerOrderDto) -> Self {
        match o {
            CornerOrderDto::Qr => CornerOrder::Qr,
            CornerOrderDto::Paper => CornerOrder::Paper,
        }
    }
}

/// The pose solver.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum MethodDto {
    /// The paper's iterative estimator as printed (Teoh et al. 2022, Eqs. 6-13).
    Paper,
    /// The paper's unknowns and residuals solved by Levenberg-Marquardt.
    DepthNewton,
    /// IPPE closed form, both candidates refined on pixel error (default; most accurate).
    #[default]
    Reprojection,
}

impl From<MethodDto> for Method {
    fn from(m: MethodDto) -> Self {
        match m {
            MethodDto::Paper => Method::Paper,
            MethodDto::DepthNewton => Method::DepthNewton,
            MethodDto::Reprojection => Method::Reprojection,
        }
    }
}

impl From<Method> for MethodDto {
    fn from(m: Method) -> Self {
        match m {
            Method::Paper => MethodDto::Paper,
            Method::DepthNewton => MethodDto::DepthNewton,
            Method::Reprojection => MethodDto::Reprojection,
        }
    }
}

/// The printed code.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MarkerDto {
    /// Side of the QR symbol, mm: outer edge of one finder pattern to the outer edge of the
    /// other, quiet zone excluded.
    #[schema(example = 50.0, exclusive_minimum = 0)]
    pub size_mm: f64,
}

/// The documentation of `corners_px` and `corners_mm`, in the code and in the document (a
/// field with its own schema function gets no description from its doc comment).
macro_rules! corners_doc {
    (px) => {
        "Four corners in pixels, `[u, v]` each (u right, v down, integer = pixel centre), in \
         `corner_order`. Give this or `corners_mm`."
    };
    (mm) => {
        "Four corners in image-plane millimetres (the paper's form, x' = x_n · f), with \
         `camera.focal_length_mm`. Give this or `corners_px`."
    };
}

/// `POST /v1/pose/corners`: four corners of one QR code, the camera and the marker size.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({
    "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
    "corner_order": "qr",
    "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
    "marker": {"size_mm": 50.0},
    "solver": {"method": "reprojection"}
}))]
pub struct CornersRequest {
    #[doc = corners_doc!(px)]
    #[schema(schema_with = corners_px_schema)]
    pub corners_px: Option<Vec<Vec<f64>>>,
    #[doc = corners_doc!(mm)]
    #[schema(schema_with = corners_mm_schema)]
    pub corners_mm: Option<Vec<Vec<f64>>>,
    /// Order of the corners (default `qr`).
    #[serde(default)]
    #[schema(default = CornerOrderDto::default)]
    pub corner_order: CornerOrderDto,
    /// Camera intrinsics, or `{"id": …}` naming a camera of the loaded site.
    pub camera: CameraDto,
    /// The printed code. May be omitted when the loaded site gives the size (by `payload`,
    /// or its default).
    #[serde(default)]
    pub marker: Option<MarkerDto>,
    /// The code's payload: the site's size rules and map look it up (`docs/site.md`).
    #[serde(default)]
    #[schema(example = "LOC-0001")]
    pub payload: Option<String>,
    /// Solver and parameters (all optional).
    #[serde(default)]
    pub solver: SolverDto,
    /// An expected orientation that picks between the two poses of the planar ambiguity
    /// (`reprojection` only); `ambiguity.resolved_by` says when it decided.
    #[serde(default)]
    pub prior: Option<PriorDto>,
    /// The arm's pose (T_robot←flange, as the controller reports it) when the corners were
    /// seen: with a camera on the flange (`mount.parent: flange`), poses in the robot frame
    /// exist only with it (`docs/pick.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flange_pose: Option<RobotPoseDto>,
    /// The least probability of landing within tolerance for a grasp to be `graspable`
    /// (default 0.95).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 0, maximum = 1, example = 0.95)]
    pub min_grasp_probability: Option<f64>,
}

/// The fields of a corners request besides its corners, which both forms have.
const CORNERS_REQUEST_FIELDS: &[&str] = &[
    "corner_order",
    "camera",
    "marker",
    "payload",
    "solver",
    "prior",
    "flange_pose",
    "min_grasp_probability",
];

/// A corners request's forms in the document ([`crate::api::alternatives`]): corners in
/// pixels, or in image-plane mm with the image-plane camera; the marker required without a
/// site.
#[must_use]
pub fn corners_forms(site: bool) -> Rule {
    let (required_px, required_mm): (&'static [&str], &'static [&str]) = if site {
        (&["corners_px", "camera"], &["corners_mm", "camera"])
    } else {
        (
            &["corners_px", "camera", "marker"],
            &["corners_mm", "camera", "marker"],
        )
    };
    let image_plane = json!({"$ref": format!("#/components/schemas/{IMAGE_PLANE}")});
    Rule::Split {
        component: "CornersRequest",
        forms: vec![
            Form {
                name: "PixelCornersRequest",
                summary: "corners in pixels",
                fields: [&["corners_px"], CORNERS_REQUEST_FIELDS].concat(),
                required: required_px,
                narrowed: vec![],
            },
            Form {
                name: "PlaneCornersRequest",
                summary: "corners in image-plane mm",
                fields: [&["corners_mm"], CORNERS_REQUEST_FIELDS].concat(),
                required: required_mm,
                narrowed: vec![("camera", Narrowed::To(image_plane))],
            },
        ],
        only_within: &[],
    }
}

/// The schema of a corner list: four distinct `[u, v]` pairs of numbers (else
/// `corner_count`, `invalid_type` or `duplicate_corners`, [`four_corners`] and
/// [`ImageQuad::try_new`]), described as `description`.
fn corner_list_schema(description: &str) -> utoipa::openapi::schema::Array {
    use utoipa::openapi::schema::{ArrayBuilder, KnownFormat, ObjectBuilder, SchemaFormat, Type};
    let number = ObjectBuilder::new()
        .schema_type(Type::Number)
        .format(Some(SchemaFormat::KnownFormat(KnownFormat::Double)));
    let pair = ArrayBuilder::new()
        .items(number)
        .min_items(Some(2))
        .max_items(Some(2));
    ArrayBuilder::new()
        .items(pair)
        .min_items(Some(4))
        .max_items(Some(4))
        .unique_items(true)
        .description(Some(description))
        .build()
}

/// [`corner_list_schema`] of `corners_px`.
fn corners_px_schema() -> utoipa::openapi::schema::Array {
    corner_list_schema(corners_doc!(px))
}
/// [`corner_list_schema`] of `corners_mm`.
fn corners_mm_schema() -> utoipa::openapi::schema::Array {
    corner_list_schema(corners_doc!(mm))
}

/// Which unit corners come in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CornersUnit {
    /// Pixels.
    Px,
    /// Image-plane millimetres.
    Mm,
}

impl MarkerDto {
    /// The validated marker.
    ///
    /// # Errors
    /// `invalid_marker_size` unless the size is positive and finite.
    pub fn to_marker(&self) -> Result<Marker, Problem> {
        Marker::try_new(self.size_mm).map_err(|e: MarkerError| {
            Problem::new(ErrorCode::InvalidMarkerSize, e.to_string()).with_field("/marker/size_mm")
        })
    }
}

/// Exactly four `[u, v]` pairs, or the problem naming the list or the bad pair.
///
/// # Errors
/// `corner_count` for other than four corners, `invalid_type` for a corner that is not a
/// pair of numbers.
pub fn four_corners(corners: &[Vec<f64>], pointer: &str) -> Result<[[f64; 2]; 4], Problem> {
    if corners.len() != 4 {
        return Err(Problem::new(
            ErrorCode::CornerCount,
            format!("exactly 4 corners are needed, got {}", corners.len()),
        )
        .with_field(pointer));
    }
    let mut four = [[0.0; 2]; 4];
    for (i, corner) in corners.iter().enumerate() {
        four[i] = corner.as_slice().try_into().map_err(|_| {
            Problem::new(
                ErrorCode::InvalidType,
                format!("a corner is [u, v], 2 numbers; got {}", corner.len()),
            )
            .with_field(format!("{pointer}/{i}"))
        })?;
    }
    Ok(four)
}

/// A validated corners request: the setup, the quadrilateral and what names them.
#[derive(Debug, Clone)]
pub struct ValidCorners {
    /// Camera, size, solver, prior and site.
    pub setup: Setup,
    /// The four corners in the camera's image units.
    pub quad: ImageQuad,
    /// The code's payload, for the site's map and priors.
    pub payload: Option<String>,
    /// `/corners_px` or `/corners_mm`, to name corners in later errors.
    pub corners_pointer: &'static str,
    /// When validation began: the answer's `elapsed_us` counts from here.
    pub started: Instant,
}

impl CornersRequest {
    /// Validates the whole request against `site` (none: intrinsics and size must be in
    /// the request): `camera.id` names a site camera, and a missing marker size comes from
    /// the site's rules for `payload`.
    ///
    /// # Errors
    /// A [`Problem`] naming the first field at fault: `unknown_camera`,
    /// `unknown_marker_size` (field `/payload`), `invalid_prior`, `numerically_degenerate`
    /// among the others.
    pub fn validate(&self, site: Option<Arc<Site>>) -> Result<ValidCorners, Problem> {
        let started = Instant::now();
        // Without a site a missing marker is refused first, as the required field it was.
        if self.marker.is_none() && site.is_none() {
            return Err(missing_marker());
        }
        let (corners, unit, pointer) = match (&self.corners_px, &self.corners_mm) {
            (Some(px), None) => (px, CornersUnit::Px, "/corners_px"),
            (None, Some(mm)) => (mm, CornersUnit::Mm, "/corners_mm"),
            (None, None) => {
                return Err(Problem::new(
                    ErrorCode::CornersMissingOrConflicting,
                    "give corners_px or corners_mm",
                )
                .with_field("/corners_px"));
            }
            (Some(_), Some(_)) => {
                return Err(Problem::new(
                    ErrorCode::CornersMissingOrConflicting,
                    "give corners_px or corners_mm, not both",
                )
                .with_field("/corners_mm"));
            }
        };
        let resolved = resolve_camera(&self.camera, unit, site.as_deref())?;
        let (marker, source) = resolve_marker(
            self.marker.as_ref(),
            site.as_deref(),
            self.payload.as_deref(),
            "/payload",
        )?;
        let solver = self.solver.to_solver()?;
        let prior = self.prior.as_ref().map(PriorDto::validate).transpose()?;
        let four = four_corners(corners, pointer)?;
        let scale = resolved.mm_per_px.map_or(1.0, |mm_per_px| 1.0 / mm_per_px);
        let points = four.map(|[u, v]| PixelPoint::new(u * scale, v * scale));
        let overflowed = four.iter().zip(&points).any(|([u, v], p)| {
            u.is_finite() && v.is_finite() && !(p.u().is_finite() && p.v().is_finite())
        });
        if overflowed {
            // Finite millimetres over a tiny pixel pitch: the input is finite, its pixels
            // are not (not a `non_finite_number` of the client's).
            return Err(Problem::new(
                ErrorCode::NumericallyDegenerate,
                format!(
                    "the corners in pixels ({pointer} divided by the pixel size of {:e} mm) overflow double precision",
                    resolved.mm_per_px.unwrap_or(1.0)
                ),
            )
            .with_field(pointer));
        }
        let quad = ImageQuad::try_new(points, self.corner_order.into())
            .map_err(|e| problem_from_quad_error(e, pointer))?;
        check_arithmetic_range(&quad, &resolved.camera, &marker, pointer)?;
        let site_camera = resolved.site_camera.cloned();
        Ok(ValidCorners {
            setup: Setup {
                camera: resolved.camera,
                site_camera,
                site,
                sizing: Sizing::Fixed { marker, source },
                solver,
                prior,
                pick: pick_of(self.flange_pose.as_ref(), self.min_grasp_probability)?,
            },
            quad,
            payload: self.payload.clone(),
            corners_pointer: pointer,
            started,
        })
    }
}

/// Largest magnitude (and inverse of the smallest) of a ray coordinate, of the corners'
/// spread in ray space and of the marker size that the solvers are given. Their least
/// squares multiply up to four such numbers (and square the result), so each must keep its
/// fourth power well inside double precision (about 1e±308): 1e±75 does. Physical inputs
/// are nowhere near: a ray coordinate of 1e3 is 89.94° off axis.
pub const MAX_SOLVER_MAGNITUDE: f64 = 1e75;

/// Refuses a valid request whose scale the solvers' arithmetic cannot hold (corners at
/// 1e200 px, a focal length of 1e-200 px), before solving: the solvers would overflow to
/// infinity or underflow to zero and report a degenerate homography or a pose of NaNs.
///
/// # Errors
/// 422 `numerically_degenerate` naming the corner list.
fn check_arithmetic_range(
    quad: &ImageQuad,
    camera: &Camera,
    marker: &Marker,
    corners_pointer: &str,
) -> Result<(), Problem> {
    // A corner that cannot be undistorted is the estimator's to report.
    let Ok(rays) = quad
        .paper_order()
        .iter()
        .map(|p| camera.normalize(p))
        .collect::<Result<Vec<_>, _>>()
    else {
        return Ok(());
    };
    let largest = rays
        .iter()
        .flat_map(|r| [r.x().abs(), r.y().abs()])
        .fold(0.0, f64::max);
    let spread = rays
        .iter()
        .flat_map(|a| rays.iter().map(move |b| (a.0 - b.0).norm()))
        .fold(0.0, f64::max);
    let in_range = |v: f64| (1.0 / MAX_SOLVER_MAGNITUDE..=MAX_SOLVER_MAGNITUDE).contains(&v);
    let size = marker.size_mm();
    if largest <= MAX_SOLVER_MAGNITUDE && in_range(spread) && in_range(size) {
        return Ok(());
    }
    Err(Problem::new(
        ErrorCode::NumericallyDegenerate,
        format!(
            "the corners span {spread:e} and reach {largest:e} focal lengths off axis, and the \
             marker is {size:e} mm: beyond 1e±75, where the solvers' arithmetic overflows or \
             underflows in double precision"
        ),
    )
    .with_field(corners_pointer))
}
