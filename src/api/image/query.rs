//! The image request as flat parameters: the query string of `POST /v1/pose/image` with a
//! raw image body, and the flags of `qrpose estimate --image`. One struct serves both
//! ([`ImageQuery`] derives serde's `Deserialize`, utoipa's `IntoParams` and clap's `Args`),
//! so every parameter has the same name, type, documentation and refusals in each.
//!
//! Validation runs on the JSON form ([`ImageRequest`]) that the parameters stand for; a
//! problem's `field`, a JSON pointer there (`/camera/fx_px`), is then renamed to the
//! parameter the client wrote (`fx_px`) by [`ImageQuery::problem_in_query_terms`].

use super::{DetectorDto, EffortDto, ImageRequest, PointsDto};
use crate::api::camera::DistortionModelDto;
use crate::api::camera::check_ranges;
use crate::api::problem::{ErrorCode, Problem};
use crate::api::request::{CameraDto, DistortionDto, MarkerDto, MethodDto, SolverDto};
use crate::app::{ImageLimits, ImageSetup};
use qrpose_site::Site;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::Duration;
use utoipa::IntoParams;

/// The image request as flat parameters (query string or command-line flags). Numeric flags
/// take negative values, so that `--fx-px -5` is refused by the same check, with the same
/// problem, as `fx_px=-5`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, IntoParams, clap::Args)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ImageQuery {
    /// A camera of the loaded site (`qrpose serve --site`), instead of the intrinsics and
    /// distortion.
    #[param(min_length = 1)]
    #[arg(long)]
    pub camera_id: Option<String>,
    /// Horizontal focal length, px.
    #[param(minimum = 1e-3, maximum = 1e9)]
    #[arg(long, allow_negative_numbers = true)]
    pub fx_px: Option<f64>,
    /// Vertical focal length, px.
    #[param(minimum = 1e-3, maximum = 1e9)]
    #[arg(long, allow_negative_numbers = true)]
    pub fy_px: Option<f64>,
    /// Principal point, horizontal, px (integer = pixel centre).
    #[arg(long, allow_negative_numbers = true)]
    pub cx_px: Option<f64>,
    /// Principal point, vertical, px.
    #[arg(long, allow_negative_numbers = true)]
    pub cy_px: Option<f64>,
    /// Lens focal length, mm (sensor form, with `pixel_size_um`).
    #[param(minimum = 1e-3, maximum = 1e5)]
    #[arg(long, allow_negative_numbers = true)]
    pub focal_length_mm: Option<f64>,
    /// Pixel pitch, µm (sensor form).
    #[param(minimum = 1e-3, maximum = 1e5)]
    #[arg(long, allow_negative_numbers = true)]
    pub pixel_size_um: Option<f64>,
    /// Radial distortion r² coefficient (OpenCV's k1).
    #[arg(long, allow_negative_numbers = true)]
    pub k1: Option<f64>,
    /// Radial r⁴ coefficient.
    #[arg(long, allow_negative_numbers = true)]
    pub k2: Option<f64>,
    /// Radial r⁶ coefficient.
    #[arg(long, allow_negative_numbers = true)]
    pub k3: Option<f64>,
    /// Tangential coefficient p1.
    #[arg(long, allow_negative_numbers = true)]
    pub p1: Option<f64>,
    /// Tangential coefficient p2.
    #[arg(long, allow_negative_numbers = true)]
    pub p2: Option<f64>,
    /// The lens model of the coefficients: `plumb_bob` when omitted (k1 k2 p1 p2 k3),
    /// `rational_polynomial` (k1 k2 p1 p2 k3 k4 k5 k6) or `equidistant` (fisheye: k1 k2 k3
    /// k4), as the JSON form's `camera.distortion.model`.
    #[arg(long, value_enum)]
    pub distortion_model: Option<DistortionModelDto>,
    /// `rational_polynomial`: the denominator's r² coefficient; `equidistant`: θ⁹.
    #[arg(long, allow_negative_numbers = true)]
    pub k4: Option<f64>,
    /// `rational_polynomial` only: the denominator's r⁴ coefficient.
    #[arg(long, allow_negative_numbers = true)]
    pub k5: Option<f64>,
    /// `rational_polynomial` only: the denominator's r⁶ coefficient.
    #[arg(long, allow_negative_numbers = true)]
    pub k6: Option<f64>,
    /// Side of the QR symbol, mm (finder edge to finder edge, quiet zone excluded). Required
    /// unless a site is loaded: then each code is sized by its payload.
    #[param(exclusive_minimum = 0)]
    #[arg(long, allow_negative_numbers = true)]
    pub marker_size_mm: Option<f64>,
    /// Solver: `paper`, `depth-newton` or `reprojection` (default).
    #[arg(long, value_enum)]
    pub method: Option<MethodDto>,
    /// Detector: `auto` (default), `rqrr`, `rxing`, `zxing-cpp`.
    #[arg(long, value_enum)]
    pub detector: Option<DetectorDto>,
    /// Points: `corners` or `finders` (default as in the JSON form).
    #[arg(long, value_enum)]
    pub points: Option<PointsDto>,
    /// Starting depth, mm (`paper`, `depth-newton`).
    #[param(exclusive_minimum = 0, maximum = 1e7)]
    #[arg(long, allow_negative_numbers = true)]
    pub initial_z_mm: Option<f64>,
    /// Gain k of the paper's Eq. 12 (`paper`).
    #[param(exclusive_minimum = 0, maximum = 10)]
    #[arg(long, allow_negative_numbers = true)]
    pub gain: Option<f64>,
    /// Convergence threshold, mm (`paper`).
    #[param(exclusive_minimum = 0, maximum = 1e6)]
    #[arg(long, allow_negative_numbers = true)]
    pub tolerance_mm: Option<f64>,
    /// Iteration limit, 1 to 10000.
    #[param(minimum = 1, maximum = 10000)]
    #[arg(long, allow_negative_numbers = true)]
    pub max_iterations: Option<u64>,
    /// Return the per-iteration trace.
    #[arg(long)]
    pub trace: Option<bool>,
    /// Corner noise σ for the covariance, px.
    #[param(exclusive_minimum = 0, maximum = 100)]
    #[arg(long, allow_negative_numbers = true)]
    pub corner_sigma_px: Option<f64>,
    /// Detection effort: `fast`, `balanced` (default) or `thorough`.
    #[arg(long, value_enum)]
    pub effort: Option<EffortDto>,
    /// Detection deadline, ms (> 0; default the effort's own, capped by the server).
    #[param(exclusive_minimum = 0)]
    #[arg(long, allow_negative_numbers = true)]
    pub max_detect_ms: Option<f64>,
}

/// The JSON pointer of the marker size, the one parameter whose name is not the last
/// segment of its pointer.
const MARKER_SIZE_POINTER: &str = "/marker/size_mm";
/// The JSON pointer of the site camera's id.
const CAMERA_ID_POINTER: &str = "/camera/id";
/// The query parameter of the site camera's id.
const CAMERA_ID_PARAMETER: &str = "camera_id";
/// The JSON pointer of the marker as a whole (a missing marker).
const MARKER_POINTER: &str = "/marker";
/// The query parameter of the marker size.
const MARKER_SIZE_PARAMETER: &str = "marker_size_mm";
/// The query parameter of the lens model, and the field it stands for.
const DISTORTION_MODEL_PARAMETER: &str = "distortion_model";
const DISTORTION_MODEL_POINTER: &str = "/camera/distortion/model";

impl ImageQuery {
    /// The JSON-form request these parameters stand for. Without `marker_size_mm` it has
    /// no marker: validation then needs a site (else `missing_field`, `marker_size_mm`).
    ///
    /// # Errors
    /// None today; the signature keeps room for checks of the flat form.
    pub fn into_request(self) -> Result<ImageRequest, Problem> {
        let coefficients = [
            self.k1, self.k2, self.k3, self.p1, self.p2, self.k4, self.k5, self.k6,
        ];
        let any_distortion =
            self.distortion_model.is_some() || coefficients.iter().any(Option::is_some);
        let distortion = any_distortion.then(|| DistortionDto {
            model: self.distortion_model,
            k1: self.k1.unwrap_or(0.0),
            k2: self.k2.unwrap_or(0.0),
            p1: self.p1.unwrap_or(0.0),
            p2: self.p2.unwrap_or(0.0),
            k3: self.k3.unwrap_or(0.0),
            k4: self.k4.unwrap_or(0.0),
            k5: self.k5.unwrap_or(0.0),
            k6: self.k6.unwrap_or(0.0),
        });
        let defaults = SolverDto::default();
        Ok(ImageRequest {
            camera: CameraDto {
                id: self.camera_id,
                fx_px: self.fx_px,
                fy_px: self.fy_px,
                cx_px: self.cx_px,
                cy_px: self.cy_px,
                focal_length_mm: self.focal_length_mm,
                pixel_size_um: self.pixel_size_um,
                distortion,
            },
            marker: self.marker_size_mm.map(|size_mm| MarkerDto { size_mm }),
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
            effort: self.effort.unwrap_or_default(),
            max_detect_ms: self.max_detect_ms,
            // A prior and a flange pose are structured: they travel in a JSON body or a
            // multipart `request` part, not in the flat query.
            prior: None,
            flange_pose: None,
            min_grasp_probability: None,
        })
    }

    /// Checks each parameter given against its own range, as the document states it, apart
    /// from the others: with a multipart body the `request` part may override a parameter
    /// (`merge`), and an out-of-range value is refused all the same. Whether the parameters
    /// make a whole request is not checked here (the part may give the rest). A problem's
    /// `field` names the parameter.
    ///
    /// # Errors
    /// `invalid_camera_parameter` or `non_finite_number` for a focal length or pixel size,
    /// `invalid_marker_size`, the solver's `solver_parameter_out_of_range`,
    /// `invalid_detection_budget`, `detector_unavailable`, and `unknown_camera` for an empty
    /// `camera_id`.
    pub fn check_values(&self) -> Result<(), Problem> {
        self.clone()
            .into_request()
            .and_then(|request| {
                check_ranges(&request.camera, "/camera")?;
                if request.camera.id.as_deref() == Some("") {
                    return Err(Problem::new(ErrorCode::UnknownCamera, "camera_id is empty")
                        .with_field(CAMERA_ID_POINTER));
                }
                request
                    .marker
                    .as_ref()
                    .map(MarkerDto::to_marker)
                    .transpose()?;
                request.solver.to_solver()?;
                // Only the range is checked: any cap will do.
                request.max_detect(Duration::ZERO)?;
                request.check_detector()
            })
            .map_err(Self::problem_in_query_terms)
    }

    /// Validates the request these parameters stand for ([`ImageRequest::setup`]); a
    /// problem's `field` names the parameter.
    ///
    /// # Errors
    /// As [`ImageRequest::setup`].
    pub fn setup(
        self,
        limits: &ImageLimits,
        site: Option<Arc<Site>>,
    ) -> Result<ImageSetup, Problem> {
        self.into_request()
            .and_then(|request| request.setup(limits, site))
            .map_err(Self::problem_in_query_terms)
    }

    /// The JSON pointer in [`ImageRequest`] of the value that parameter `name` gives
    /// (`fx_px` → `/camera/fx_px`); the inverse of [`Self::parameter_of_pointer`].
    pub fn pointer_of_parameter(name: &str) -> String {
        match name {
            CAMERA_ID_PARAMETER => CAMERA_ID_POINTER.to_owned(),
            MARKER_SIZE_PARAMETER => MARKER_SIZE_POINTER.to_owned(),
            "fx_px" | "fy_px" | "cx_px" | "cy_px" | "focal_length_mm" | "pixel_size_um" => {
                format!("/camera/{name}")
            }
            "k1" | "k2" | "k3" | "p1" | "p2" | "k4" | "k5" | "k6" => {
                format!("/camera/distortion/{name}")
            }
            DISTORTION_MODEL_PARAMETER => DISTORTION_MODEL_POINTER.to_owned(),
            "method" | "initial_z_mm" | "gain" | "tolerance_mm" | "max_iterations" | "trace"
            | "corner_sigma_px" => format!("/solver/{name}"),
            _ => format!("/{name}"),
        }
    }

    /// The names of the parameters, as documented (utoipa's `IntoParams`).
    pub fn parameter_names() -> Vec<String> {
        Self::into_params(|| None)
            .into_iter()
            .map(|p| p.name)
            .collect()
    }

    /// The parameter that stands for the value at `pointer` in [`ImageRequest`]: the last
    /// segment of the pointer (`/camera/distortion/k1` → `k1`), except the marker size and
    /// the camera id; a
    /// pointer that no single parameter stands for (`/camera`, the camera's form as a
    /// whole) has none.
    pub fn parameter_of_pointer(pointer: &str) -> Option<String> {
        if pointer == MARKER_SIZE_POINTER || pointer == MARKER_POINTER {
            return Some(MARKER_SIZE_PARAMETER.to_owned());
        }
        if pointer == CAMERA_ID_POINTER {
            return Some(CAMERA_ID_PARAMETER.to_owned());
        }
        if pointer == DISTORTION_MODEL_POINTER {
            return Some(DISTORTION_MODEL_PARAMETER.to_owned());
        }
        let last = pointer.rsplit('/').next()?;
        Self::parameter_names()
            .into_iter()
            .find(|name| name == last)
    }

    /// `problem` with its `field` turned from a JSON pointer into the [`ImageRequest`] into
    /// the query parameter a client sent (`/camera/fx_px` → `fx_px`). A field that is
    /// already a parameter name is kept; one that no parameter stands for is dropped.
    pub fn problem_in_query_terms(problem: Problem) -> Problem {
        let field = problem.field.as_deref().and_then(|field| {
            if field.starts_with('/') {
                Self::parameter_of_pointer(field)
            } else {
                Some(field.to_owned())
            }
        });
        Problem { field, ..problem }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::problem::ErrorCode;

    fn every_parameter_set() -> ImageQuery {
        ImageQuery {
            camera_id: Some("front".to_owned()),
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
            distortion_model: Some(DistortionModelDto::RationalPolynomial),
            k4: Some(0.5),
            k5: Some(0.5),
            k6: Some(0.5),
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
            effort: Some(EffortDto::Fast),
            max_detect_ms: Some(10.0),
        }
    }

    /// Every JSON pointer of a value in `value`, depth first.
    fn leaf_pointers(value: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
        match value {
            serde_json::Value::Object(map) => {
                for (key, v) in map {
                    leaf_pointers(v, &format!("{prefix}/{key}"), out);
                }
            }
            serde_json::Value::Null => {}
            _ => out.push(prefix.to_owned()),
        }
    }

    #[test]
    fn every_query_parameter_maps_to_one_request_value_and_back() {
        let all = every_parameter_set();
        let names = ImageQuery::parameter_names();
        let serialised = serde_json::to_value(&all).expect("serialisable");
        let mut serialised: Vec<&String> =
            serialised.as_object().expect("an object").keys().collect();
        serialised.sort();
        let mut documented: Vec<&String> = names.iter().collect();
        documented.sort();
        assert_eq!(
            serialised, documented,
            "documented = deserialised parameters"
        );
        let request =
            serde_json::to_value(all.into_request().expect("complete")).expect("serialisable");
        let mut pointers = Vec::new();
        leaf_pointers(&request, "", &mut pointers);
        let mut mapped: Vec<String> = pointers
            .iter()
            .map(|p| ImageQuery::parameter_of_pointer(p).unwrap_or_else(|| panic!("{p}")))
            .collect();
        mapped.sort();
        let mut expected = names.clone();
        expected.sort();
        assert_eq!(mapped, expected, "each request value has its parameter");
    }

    #[test]
    fn every_parameter_has_its_pointer_and_back() {
        for name in ImageQuery::parameter_names() {
            let pointer = ImageQuery::pointer_of_parameter(&name);
            assert_eq!(
                ImageQuery::parameter_of_pointer(&pointer).as_deref(),
                Some(name.as_str()),
                "{name} -> {pointer}"
            );
        }
    }

    #[test]
    fn problems_name_the_query_parameter() {
        let cases = [
            (Some("/camera/fx_px"), Some("fx_px")),
            (Some("/camera/distortion/k1"), Some("k1")),
            (Some("/camera/distortion/k6"), Some("k6")),
            (Some("/camera/distortion/model"), Some("distortion_model")),
            (Some("/marker/size_mm"), Some("marker_size_mm")),
            (Some("/marker"), Some("marker_size_mm")),
            (Some("/camera/id"), Some("camera_id")),
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

    /// Every lens model can be sent as query parameters: the flat form carries what the
    /// JSON form's `camera.distortion` does.
    #[test]
    fn a_fisheye_camera_comes_through_the_query() {
        let query: ImageQuery = serde_urlencoded::from_str(
            "fx_px=420&fy_px=420&cx_px=639.5&cy_px=399.5&marker_size_mm=50\
             &distortion_model=equidistant&k1=-0.0057&k2=0.0419&k3=-0.0387&k4=0.0067",
        )
        .expect("parses");
        let request = query.into_request().expect("a request");
        let distortion = request.camera.distortion.expect("a lens");
        assert_eq!(distortion.model, Some(DistortionModelDto::Equidistant));
        assert_eq!(
            [distortion.k1, distortion.k2, distortion.k3, distortion.k4],
            [-0.0057, 0.0419, -0.0387, 0.0067]
        );
        let lens = distortion
            .to_distortion("/camera")
            .expect("a valid fisheye");
        assert_eq!(
            lens.model(),
            crate::geometry::distortion::DistortionModel::Equidistant
        );
    }
}
