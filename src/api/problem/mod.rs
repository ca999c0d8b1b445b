//! RFC 9457 problem details: the one error body of the HTTP API and of the CLI.
//!
//! Every error has a stable snake_case [`ErrorCode`] that clients can switch on, the HTTP
//! status it maps to, and, where one field is at fault, `field` as a JSON pointer into the
//! request (`/corners_px/2`, `/camera/fx_px`), the name of a query parameter or the name of a
//! multipart part.
//!
//! Parse failures become problems here ([`parse_json`], [`parse_json_value`], and the query
//! strings of `crate::http::extract`): the detail is serde's message, the code of a shape
//! error its kind ([`ShapeKind`], the one place that reads serde's wording).

pub mod operations;
mod shape;
#[cfg(test)]
mod tests;

pub use shape::ShapeKind;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use serde_json::error::Category;
use utoipa::ToSchema;

/// Stable machine-readable error codes. New codes may be added; existing ones never change.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ErrorCode {
    /// 400: the body is not syntactically valid JSON (or is empty). Deeply nested JSON is
    /// refused as `invalid_type` (422) where the schema expects a number or object.
    MalformedJson,
    /// 400: a query parameter cannot be parsed.
    MalformedQuery,
    /// 400: a `multipart/form-data` body cannot be parsed (no boundary, broken framing, a
    /// part without a name or a part given twice).
    MalformedMultipart,
    /// 422: a required field is missing.
    MissingField,
    /// 422: a field the API does not know (a typo would otherwise be silently ignored).
    UnknownField,
    /// 422: a field has the wrong JSON type or shape (e.g. a corner with three numbers).
    InvalidType,
    /// 422: an enumerated field has a value outside its set (e.g. an unknown `method`).
    UnknownVariant,
    /// 422: a number is NaN or infinite.
    NonFiniteNumber,
    /// 422: neither or both of `corners_px` and `corners_mm` were given.
    CornersMissingOrConflicting,
    /// 422: not exactly four corners.
    CornerCount,
    /// 422: two corners coincide.
    DuplicateCorners,
    /// 422: three corners lie on one line.
    CollinearCorners,
    /// 422: the corner outline crosses itself (two corners swapped).
    SelfIntersectingCorners,
    /// 422: the corner outline is not convex.
    NonConvexCorners,
    /// 422: the corners run counter-clockwise on screen (reversed or mirrored order).
    MirroredCorners,
    /// 422: the camera is given in no complete form, or in two forms at once.
    IncompleteCamera,
    /// 422: a focal length or pixel size is zero or negative.
    InvalidCameraParameter,
    /// 422: a corner cannot be undistorted with the given distortion coefficients.
    UndistortionFailed,
    /// 422: the marker size is zero or negative.
    InvalidMarkerSize,
    /// 422: a solver parameter is outside its documented range.
    SolverParameterOutOfRange,
    /// 422: `max_detect_ms` is not a positive, finite number of milliseconds.
    InvalidDetectionBudget,
    /// 422: no pose fits the corners.
    NoSolution,
    /// 422: the inputs' magnitudes are beyond what double-precision arithmetic can solve
    /// (e.g. corners at 1e150 px): a computed number came out NaN or infinite.
    NumericallyDegenerate,
    /// 422: the image cannot be decoded (corrupt, truncated or not an image).
    UndecodableImage,
    /// 413: the image declares more pixels than the configured limit.
    ImageTooLarge,
    /// 422: the requested detector backend is not built into this server (zxing-cpp needs
    /// the `zxing-cpp` cargo feature).
    DetectorUnavailable,
    /// 422: `points = finders` was asked for with a method other than `reprojection`.
    PointsNeedReprojection,
    /// 422: `camera.id` (`camera_id`) names no camera of the loaded site, or no site is
    /// loaded.
    UnknownCamera,
    /// 422: no marker size for this code: the request gives none and the site has no rule
    /// for its payload and no default. In an image response, the marker's own problem (its
    /// `pose` is null; the other markers are unaffected).
    UnknownMarkerSize,
    /// 422: the `prior` is unusable: neither or both rotations, a zero quaternion, or
    /// `sigma_deg` outside (0, 180].
    InvalidPrior,
    /// 404: the service runs without a site (`qrpose serve --site`).
    NoSite,
    /// 422: the site file on disk was refused on reload; the site loaded before stays in
    /// use. `detail` says `FILE:LINE: reason`.
    InvalidSite,
    /// 413: the request body exceeds the configured limit.
    PayloadTooLarge,
    /// 415: the content type is not one this endpoint accepts.
    UnsupportedMediaType,
    /// 404: no such route.
    NotFound,
    /// 405: the route exists but not with this method.
    MethodNotAllowed,
    /// 503: all estimation workers are busy and the queue is full; retry after `Retry-After`.
    Overloaded,
    /// 503: the request took longer than the configured timeout.
    Timeout,
    /// 503: the service is shutting down and takes no new work; retry on another instance.
    ShuttingDown,
    /// 422: a calibration has fewer usable views than it needs: fewer than 3 photos, or
    /// fewer than 3 with a code that gives enough points, or fewer left once the views that
    /// do not fit are dropped.
    TooFewViews,
    /// 422: a calibration was sent more than 100 photos.
    TooManyImages,
    /// 422: the photos of a calibration are not all of one size.
    MixedImageSizes,
    /// 422: no QR code was decoded in any photo of a calibration.
    NoCodeFound,
    /// 422: the calibration's solve failed on these photos (e.g. every photo faces the
    /// code squarely, so that focal length and distance cannot be told apart).
    CalibrationFailed,
    /// 422: a tracker parameter of `GET /v1/stream` is outside its documented range.
    InvalidTrackerParameter,
    /// 422: a robot pose with no rotation or two rotation forms, or a quaternion whose norm
    /// is off 1 by more than 1e-3 (`docs/hand-eye.md`, Robot poses).
    InvalidRobotPose,
    /// 422: a hand-eye calibration was not sent one flange pose per photo.
    FlangePosesMismatch,
    /// 422: the motions between a hand-eye calibration's views turn about fewer than two
    /// distinct axes: the camera's mount cannot be told.
    DegenerateMotion,
    /// 422: `min_grasp_probability` outside [0, 1] (`docs/pick.md`).
    InvalidGraspProbability,
    /// 426: `GET /v1/stream` asked for without a WebSocket upgrade.
    UpgradeRequired,
    /// 401: the route needs a bearer token (`--auth-file`) and the request has none, or one
    /// that no client of the auth file holds. Sent with `WWW-Authenticate: Bearer`.
    Unauthorized,
    /// 403: the token is known but its client lacks the route's scope (`pose`, `site`,
    /// `admin` or `metrics`).
    Forbidden,
    /// 400: a plain-HTTP request reached the TLS port; use `https://` (`wss://`).
    TlsRequired,
    /// 500: a fault of the service, never of the request.
    Internal,
}

impl ErrorCode {
    /// The HTTP status this code is sent with.
    pub fn status(self) -> u16 {
        use ErrorCode::*;
        match self {
            MalformedJson | MalformedQuery | MalformedMultipart | TlsRequired => 400,
            Unauthorized => 401,
            Forbidden => 403,
            NotFound | NoSite => 404,
            MethodNotAllowed => 405,
            ImageTooLarge | PayloadTooLarge => 413,
            UnsupportedMediaType => 415,
            Overloaded | Timeout | ShuttingDown => 503,
            UpgradeRequired => 426,
            Internal => 500,
            _ => 422,
        }
    }

    /// A short human title, fixed per code.
    pub fn title(self) -> &'static str {
        use ErrorCode::*;
        match self {
            MalformedJson => "Malformed JSON",
            MalformedQuery => "Malformed query string",
            MalformedMultipart => "Malformed multipart body",
            MissingField => "Missing field",
            UnknownField => "Unknown field",
            InvalidType => "Invalid field type",
            UnknownVariant => "Unknown value",
            NonFiniteNumber => "Non-finite number",
            CornersMissingOrConflicting => "Give exactly one of corners_px and corners_mm",
            CornerCount => "Exactly four corners are needed",
            DuplicateCorners => "Duplicate corners",
            CollinearCorners => "Collinear corners",
            SelfIntersectingCorners => "Self-intersecting corners",
            NonConvexCorners => "Non-convex corners",
            MirroredCorners => "Mirrored corner order",
            IncompleteCamera => "Incomplete camera",
            InvalidCameraParameter => "Invalid camera parameter",
            UndistortionFailed => "Undistortion failed",
            InvalidMarkerSize => "Invalid marker size",
            SolverParameterOutOfRange => "Solver parameter out of range",
            InvalidDetectionBudget => "Invalid detection budget",
            NoSolution => "No pose fits the corners",
            NumericallyDegenerate => "Numerically degenerate input",
            UndecodableImage => "Undecodable image",
            ImageTooLarge => "Image too large",
            DetectorUnavailable => "Detector not available",
            PointsNeedReprojection => "Finder points need the reprojection method",
            UnknownCamera => "Unknown camera",
            UnknownMarkerSize => "Unknown marker size",
            InvalidPrior => "Invalid prior",
            InvalidRobotPose => "Invalid robot pose",
            FlangePosesMismatch => "Not one flange pose per photo",
            DegenerateMotion => "Degenerate motion",
            InvalidGraspProbability => "Invalid grasp probability",
            NoSite => "No site loaded",
            InvalidSite => "Invalid site file",
            PayloadTooLarge => "Payload too large",
            UnsupportedMediaType => "Unsupported media type",
            NotFound => "Not found",
            MethodNotAllowed => "Method not allowed",
            Overloaded => "Service overloaded",
            Timeout => "Request timed out",
            ShuttingDown => "Shutting down",
            TooFewViews => "Too few usable views",
            TooManyImages => "Too many images",
            MixedImageSizes => "Images of different sizes",
            NoCodeFound => "No QR code found",
            CalibrationFailed => "Calibration failed",
            InvalidTrackerParameter => "Invalid tracker parameter",
            UpgradeRequired => "WebSocket upgrade required",
            Unauthorized => "Unauthorized",
            Forbidden => "Forbidden",
            TlsRequired => "TLS required",
            Internal => "Internal error",
        }
    }

    /// The snake_case name, as on the wire.
    pub fn as_str(self) -> String {
        serde_json::to_value(self)
            .ok()
            .and_then(|v| v.as_str().map(str::to_owned))
            .unwrap_or_default()
    }
}

/// An RFC 9457 problem document (`application/problem+json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "type": "urn:qrpose:problem:duplicate_corners",
    "title": "Duplicate corners",
    "status": 422,
    "detail": "corners 0 and 2 coincide",
    "code": "duplicate_corners",
    "field": "/corners_px/2"
}))]
pub struct Problem {
    /// A URI naming the problem type: `urn:qrpose:problem:<code>`.
    #[serde(rename = "type")]
    pub type_uri: String,
    /// Short summary, fixed per `code`.
    pub title: String,
    /// The HTTP status code.
    pub status: u16,
    /// What exactly is wrong with this request, for a human.
    pub detail: String,
    /// Stable machine-readable code.
    pub code: ErrorCode,
    /// The field at fault: a JSON pointer into the request body (for a multipart body, into
    /// its `request` part), a query parameter name, or a multipart part name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
}

impl Problem {
    /// A problem with this code and detail.
    pub fn new(code: ErrorCode, detail: impl Into<String>) -> Self {
        Self {
            type_uri: format!("urn:qrpose:problem:{}", code.as_str()),
            title: code.title().to_owned(),
            status: code.status(),
            detail: detail.into(),
            code,
            field: None,
        }
    }

    /// The same problem, naming the field at fault.
    pub fn with_field(self, field: impl Into<String>) -> Self {
        Self {
            field: Some(field.into()),
            ..self
        }
    }

    /// Classifies `err`, met while parsing JSON with serde_json (as [`parse_json`] does),
    /// naming the field at fault.
    ///
    /// The detail is serde_json's message, position included. A syntax or end-of-input
    /// error is 400 `malformed_json`; a shape error (serde_json's `Data` category) is
    /// [`Problem::of_shape`].
    pub fn from_json_error(err: &serde_path_to_error::Error<serde_json::Error>) -> Self {
        let message = err.inner().to_string();
        if err.inner().classify() != Category::Data {
            return Self::new(ErrorCode::MalformedJson, message);
        }
        Self::of_shape(message, err.path())
    }

    /// A shape problem: serde's `message`, met at `path`.
    ///
    /// `missing_field` (the pointer then ends with the missing field's name, which serde's
    /// path leaves out), `unknown_field` and `unknown_variant` have their own codes; every
    /// other kind is `invalid_type`, the general code of a body whose shape does not fit.
    pub fn of_shape(message: String, path: &serde_path_to_error::Path) -> Self {
        let pointer = json_pointer(path);
        let (code, pointer) = match ShapeKind::of(&message) {
            ShapeKind::MissingField(field) => (
                ErrorCode::MissingField,
                format!("{pointer}/{}", pointer_token(&field)),
            ),
            ShapeKind::UnknownField(_) => (ErrorCode::UnknownField, pointer),
            ShapeKind::UnknownVariant => (ErrorCode::UnknownVariant, pointer),
            ShapeKind::DuplicateField(_) | ShapeKind::Other => (ErrorCode::InvalidType, pointer),
        };
        Self::new(code, message).with_field(pointer)
    }
}

/// A key as one JSON pointer reference token (RFC 6901: `~` as `~0`, `/` as `~1`).
fn pointer_token(key: &str) -> String {
    key.replace('~', "~0").replace('/', "~1")
}

/// The JSON pointer of a serde path (`/marker/size_mm`, `/corners_px/2`).
fn json_pointer(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut pointer = String::new();
    for segment in path.iter() {
        match segment {
            Segment::Seq { index } => pointer.push_str(&format!("/{index}")),
            Segment::Map { key } => pointer.push_str(&format!("/{}", pointer_token(key))),
            Segment::Enum { variant } => pointer.push_str(&format!("/{variant}")),
            Segment::Unknown => {}
        }
    }
    pointer
}

/// Parses JSON into `T`, turning any failure into a [`Problem`] that names the field.
///
/// # Errors
/// A 400 problem for syntax errors, a 422 problem for shape errors (see
/// [`Problem::from_json_error`]).
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, Problem> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value: T =
        serde_path_to_error::deserialize(&mut de).map_err(|e| Problem::from_json_error(&e))?;
    de.end()
        .map_err(|e| Problem::new(ErrorCode::MalformedJson, e.to_string()))?;
    Ok(value)
}

/// Deserialises `T` from a JSON document already parsed (a request assembled from several
/// sources), with the problems of [`parse_json`]: serde_json's message as the detail.
///
/// # Errors
/// A 422 problem naming the field at fault.
pub fn parse_json_value<T: DeserializeOwned>(value: &Value) -> Result<T, Problem> {
    serde_path_to_error::deserialize(value)
        .map_err(|e| Problem::of_shape(e.inner().to_string(), e.path()))
}
