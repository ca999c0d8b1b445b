//! Calibration files read into a camera (`docs/calibration.md`, Calibration files):
//!
//! - OpenCV `FileStorage` YAML, as `cv2.FileStorage` and OpenCV's calibration sample write
//!   it: a `%YAML:1.0` header (OpenCV 5: `%YAML 1.2`), `camera_matrix` (or `K`,
//!   `cameraMatrix`) and `distortion_coefficients` (or `D`, `dist_coeffs`, `distCoeffs`) as
//!   `!!opencv-matrix` with `rows`, `cols`, `dt`, `data`; optional `image_width`,
//!   `image_height` and `distortion_model`.
//! - ROS `camera_info` YAML, as ROS `camera_calibration` writes it: `image_width`,
//!   `image_height`, `camera_name`, `camera_matrix`, `distortion_model`,
//!   `distortion_coefficients`, `rectification_matrix`, `projection_matrix`, each matrix
//!   `{rows, cols, data}`.
//!
//! A file is OpenCV's when it starts with a `%YAML` directive or its camera matrix has a
//! `dt`; otherwise it is read as ROS `camera_info`. Other keys (calibration time, board,
//! reprojection error) are ignored.
//!
//! The distortion model ([`model_rule`]): `distortion_model` when given (`plumb_bob`,
//! `rational_polynomial`, `equidistant`, or `fisheye` for `equidistant`); otherwise by the
//! number of coefficients: 5 → `plumb_bob`, 4 → `plumb_bob` with k3 = 0 (a 4-coefficient
//! fisheye file must say `distortion_model: equidistant`), 8 → `rational_polynomial`,
//! 0 → no distortion; 12 and 14 (thin prism, tilted sensor) are refused.
//!
//! The camera matrix must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0: qrpose's
//! camera has no skew term, so a non-zero skew is refused rather than dropped.
//!
//! [`opencv_yaml`] and [`ros_camera_info_yaml`] write a camera in the two formats, as files
//! this reader reads back as they are (module `writer`).

mod document;
mod error;
mod writer;

pub use error::CalibrationError;
pub use writer::{opencv_yaml, ros_camera_info_yaml};

use document::{Document, Matrix};
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use serde::Serialize;
use std::path::Path;

/// Names accepted for the camera matrix, the first being the standard one.
const CAMERA_MATRIX_KEYS: &[&str] = &["camera_matrix", "K", "cameraMatrix"];
/// Names accepted for the distortion coefficients.
const DISTORTION_KEYS: &[&str] = &["distortion_coefficients", "D", "dist_coeffs", "distCoeffs"];
/// The key that names the distortion model.
const MODEL_KEY: &str = "distortion_model";
/// ROS `camera_info` matrices that qrpose does not use, checked for shape: (key, rows, cols).
const ROS_EXTRA_MATRICES: [(&str, usize, usize); 2] =
    [("rectification_matrix", 3, 3), ("projection_matrix", 3, 4)];

/// Which kind of calibration file was read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum CalibrationFormat {
    /// OpenCV `FileStorage` YAML.
    #[serde(rename = "opencv")]
    OpenCv,
    /// ROS `camera_info` YAML.
    #[serde(rename = "ros_camera_info")]
    RosCameraInfo,
}

impl CalibrationFormat {
    /// The format's name: `opencv` or `ros_camera_info`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::OpenCv => "opencv",
            Self::RosCameraInfo => "ros_camera_info",
        }
    }
}

impl std::fmt::Display for CalibrationFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A calibration file, read and validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The intrinsics (px) and the lens distortion.
    pub camera: Camera,
    /// The calibrated image size (width, height), px, when the file gives it.
    pub image_size_px: Option<(u32, u32)>,
    /// Which kind of file it was.
    pub format: CalibrationFormat,
}

/// Reads the calibration file at `path` (see the module doc for the formats).
///
/// # Errors
/// [`CalibrationError::Read`] when the file cannot be read; otherwise
/// [`CalibrationError::InFile`] around [`parse_calibration`]'s error.
pub fn read_calibration_file(path: &Path) -> Result<Calibration, CalibrationError> {
    let text = std::fs::read_to_string(path).map_err(|source| CalibrationError::Read {
        path: path.to_owned(),
        source,
    })?;
    parse_calibration(&text).map_err(|e| CalibrationError::InFile {
        path: path.to_owned(),
        source: Box::new(e),
    })
}

/// Reads a calibration file's text (see the module doc for the formats and the rules).
///
/// # Errors
/// A [`CalibrationError`] naming the reason and, where known, the line: not YAML, a missing
/// camera matrix or distortion, a matrix of the wrong shape or with a non-finite element, a
/// skewed or non-positive camera matrix, an unknown model, or a coefficient count that fits
/// no model.
pub fn parse_calibration(text: &str) -> Result<Calibration, CalibrationError> {
    let doc = Document::parse(text)?;
    let (k_key, k_value) = doc
        .find(CAMERA_MATRIX_KEYS)?
        .ok_or(CalibrationError::MissingKey {
            key: CAMERA_MATRIX_KEYS[0],
            aliases: &CAMERA_MATRIX_KEYS[1..],
        })?;
    let k = doc.matrix(k_key, k_value)?;
    let format = if doc.yaml_directive || k.has_dt {
        CalibrationFormat::OpenCv
    } else {
        CalibrationFormat::RosCameraInfo
    };
    let camera = camera_from_matrix(&doc, k_key, &k)?;
    let (d_key, d_value) = doc
        .find(DISTORTION_KEYS)?
        .ok_or(CalibrationError::MissingKey {
            key: DISTORTION_KEYS[0],
            aliases: &DISTORTION_KEYS[1..],
        })?;
    let distortion = distortion_from_matrix(&doc, d_key, &doc.matrix(d_key, d_value)?)?;
    for (key, rows, cols) in ROS_EXTRA_MATRICES {
        if let Some(value) = doc.get(key) {
            let m = doc.matrix(key, value)?;
            check_shape(&doc, key, &m, rows, cols)?;
        }
    }
    Ok(Calibration {
        camera: camera.with_distortion(distortion),
        image_size_px: image_size_px(&doc)?,
        format,
    })
}

fn check_shape(
    doc: &Document<'_>,
    key: &str,
    m: &Matrix,
    rows: usize,
    cols: usize,
) -> Result<(), CalibrationError> {
    if (m.rows, m.cols) == (rows, cols) {
        Ok(())
    } else {
        Err(doc.shape(
            key,
            format!("must be {rows} × {cols}, got {} × {}", m.rows, m.cols),
        ))
    }
}

/// The pinhole camera of a 3 × 3 matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]].
fn camera_from_matrix(
    doc: &Document<'_>,
    key: &str,
    k: &Matrix,
) -> Result<Camera, CalibrationError> {
    check_shape(doc, key, k, 3, 3)?;
    let e = &k.data;
    if e[1] != 0.0 {
        return Err(CalibrationError::Skew {
            line: doc.line_of(key),
            key: key.to_owned(),
            skew_px: e[1],
        });
    }
    if e[3] != 0.0 || e[6] != 0.0 || e[7] != 0.0 || e[8] != 1.0 {
        return Err(doc.shape(
            key,
            format!(
                "is not a camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]: row 2 starts with {} and row 3 is [{}, {}, {}]",
                e[3], e[6], e[7], e[8]
            ),
        ));
    }
    Camera::from_pixels(e[0], e[4], e[2], e[5]).map_err(|source| CalibrationError::Camera {
        line: doc.line_of(key),
        key: key.to_owned(),
        source,
    })
}

/// The model the file names, if it names one.
fn named_model(doc: &Document<'_>) -> Result<Option<DistortionModel>, CalibrationError> {
    let Some(name) = doc.string(MODEL_KEY)? else {
        return Ok(None);
    };
    let model = match name {
        "fisheye" => Ok(DistortionModel::Equidistant),
        other => other.parse(),
    };
    model.map(Some).map_err(|_| CalibrationError::UnknownModel {
        line: doc.line_of(MODEL_KEY),
        name: name.to_owned(),
    })
}

/// How a model and a coefficient count become the coefficients of one of qrpose's models.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ModelChoice {
    /// No distortion (no coefficients).
    None,
    /// This model, with the coefficients as given.
    Exact(DistortionModel),
    /// `plumb_bob` from 4 coefficients, k3 = 0.
    PlumbBobWithoutK3,
}

/// The model-choice rule (module doc): the named model if any, else the count.
///
/// # Errors
/// [`CalibrationError::CoefficientCount`] when the count does not fit (the named model, or
/// any); [`CalibrationError::UnsupportedModel`] for 12 or 14 coefficients.
fn model_rule(
    named: Option<DistortionModel>,
    count: usize,
    line: Option<usize>,
) -> Result<ModelChoice, CalibrationError> {
    use DistortionModel::{Equidistant, PlumbBob, RationalPolynomial};
    match (named, count) {
        (None | Some(PlumbBob), 0) => Ok(ModelChoice::None),
        (None | Some(PlumbBob), 4) => Ok(ModelChoice::PlumbBobWithoutK3),
        (None | Some(PlumbBob), 5) => Ok(ModelChoice::Exact(PlumbBob)),
        (None | Some(RationalPolynomial), 8) => Ok(ModelChoice::Exact(RationalPolynomial)),
        (Some(Equidistant), 4) => Ok(ModelChoice::Exact(Equidistant)),
        (None | Some(RationalPolynomial), 12 | 14) => {
            Err(CalibrationError::UnsupportedModel { line, count })
        }
        (model, count) => Err(CalibrationError::CoefficientCount { line, model, count }),
    }
}

/// The distortion of a coefficient vector (1 × n or n × 1) under the model-choice rule.
fn distortion_from_matrix(
    doc: &Document<'_>,
    key: &str,
    d: &Matrix,
) -> Result<Distortion, CalibrationError> {
    if d.rows > 1 && d.cols > 1 {
        return Err(doc.shape(
            key,
            format!("must be one row or one column, got {} × {}", d.rows, d.cols),
        ));
    }
    let named = named_model(doc)?;
    let line = doc.line_of(key);
    let (model, coefficients) = match model_rule(named, d.data.len(), line)? {
        ModelChoice::None => return Ok(Distortion::NONE),
        ModelChoice::Exact(model) => (model, d.data.clone()),
        ModelChoice::PlumbBobWithoutK3 => {
            let mut five = d.data.clone();
            five.push(0.0);
            (DistortionModel::PlumbBob, five)
        }
    };
    // The count fits by construction and every element is finite (checked by the reader).
    Distortion::from_coefficients(model, &coefficients).map_err(|e| doc.shape(key, e.to_string()))
}

/// `image_width` and `image_height`: both or neither.
fn image_size_px(doc: &Document<'_>) -> Result<Option<(u32, u32)>, CalibrationError> {
    match (
        doc.positive_u32("image_width")?,
        doc.positive_u32("image_height")?,
    ) {
        (Some(w), Some(h)) => Ok(Some((w, h))),
        (None, None) => Ok(None),
        (Some(_), None) => Err(CalibrationError::MissingKey {
            key: "image_height",
            aliases: &[],
        }),
        (None, Some(_)) => Err(CalibrationError::MissingKey {
            key: "image_width",
            aliases: &[],
        }),
    }
}
