//! The calibration readers on files written by OpenCV itself (`cv2.FileStorage`, from
//! `scripts/make_calibration_fixtures.py`, which also wrote `opencv_expected.json`: what each
//! file holds and where OpenCV projects points with it), on ROS `camera_info` examples, and
//! on broken files, each refused with its reason and line.

use nalgebra::Point3;
use qrpose_core::geometry::camera::{Camera, CameraError, DistortionModel};
use qrpose_core::geometry::frames::CameraPoint;
use qrpose_site::calibration::{
    Calibration, CalibrationError, CalibrationFormat, parse_calibration, read_calibration_file,
};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Largest difference from OpenCV's projections allowed, px.
const MAX_OPENCV_DIFFERENCE_PX: f64 = 1e-6;

#[derive(Debug, Deserialize)]
struct Expected {
    files: BTreeMap<String, ExpectedFile>,
}

#[derive(Debug, Deserialize)]
struct ExpectedFile {
    model: String,
    image_size_px: Option<(u32, u32)>,
    fx_px: f64,
    fy_px: f64,
    cx_px: f64,
    cy_px: f64,
    coefficients: Vec<f64>,
    points_mm: Vec<[f64; 3]>,
    pixels_px: Vec<[f64; 2]>,
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn text(name: &str) -> String {
    std::fs::read_to_string(fixture(name)).expect("the fixture exists")
}

fn expected() -> Expected {
    serde_json::from_str(&text("opencv_expected.json")).expect("the committed fixture parses")
}

/// The largest distance between `camera`'s projections of `points_mm` and `pixels_px`, px.
fn worst_difference_px(camera: &Camera, points_mm: &[[f64; 3]], pixels_px: &[[f64; 2]]) -> f64 {
    points_mm
        .iter()
        .zip(pixels_px)
        .map(|(p, want)| {
            let got = camera
                .project(&CameraPoint(Point3::new(p[0], p[1], p[2])))
                .expect("in front");
            (got.u() - want[0]).hypot(got.v() - want[1])
        })
        .fold(0.0, f64::max)
}

fn assert_holds(name: &str, got: &Calibration, want: &ExpectedFile) {
    let c = &got.camera;
    assert_eq!(
        [c.fx(), c.fy(), c.cx(), c.cy()],
        [want.fx_px, want.fy_px, want.cx_px, want.cy_px],
        "{name}"
    );
    assert_eq!(c.distortion().model().name(), want.model, "{name}");
    assert_eq!(c.distortion().coefficients(), want.coefficients, "{name}");
    assert_eq!(got.image_size_px, want.image_size_px, "{name}");
    let worst_px = worst_difference_px(c, &want.points_mm, &want.pixels_px);
    assert!(
        worst_px <= MAX_OPENCV_DIFFERENCE_PX,
        "{name}: {worst_px} px from OpenCV"
    );
}

#[test]
fn reads_every_file_opencv_wrote_as_opencv_projects_with_it() {
    let expected = expected();
    assert_eq!(expected.files.len(), 4);
    for (name, want) in &expected.files {
        let got = read_calibration_file(&fixture(name)).expect("a readable calibration");
        assert_eq!(got.format, CalibrationFormat::OpenCv, "{name}");
        assert_holds(name, &got, want);
    }
}

#[test]
fn four_coefficients_are_plumb_bob_unless_the_file_names_the_fisheye_model() {
    let four = text("opencv_four_coefficients.yaml");
    let plumb_bob = parse_calibration(&four).expect("readable");
    assert_eq!(
        plumb_bob.camera.distortion().model(),
        DistortionModel::PlumbBob
    );
    for name in ["equidistant", "fisheye"] {
        let fisheye =
            parse_calibration(&format!("{four}distortion_model: {name}\n")).expect("readable");
        assert_eq!(
            fisheye.camera.distortion().model(),
            DistortionModel::Equidistant,
            "{name}"
        );
        assert_eq!(fisheye.camera.distortion().coefficients().len(), 4);
    }
}

#[test]
fn reads_the_opencv_5_header_too() {
    let v4 = text("opencv_plumb_bob.yaml");
    assert!(v4.starts_with("%YAML:1.0\n"));
    let v5 = v4.replacen("%YAML:1.0", "%YAML 1.2", 1);
    assert_eq!(parse_calibration(&v5).ok(), parse_calibration(&v4).ok());
}

#[test]
fn reads_the_ros_camera_info_examples_like_the_opencv_files_of_the_same_cameras() {
    let expected = expected();
    for (ros, opencv) in [
        ("ros_camera_info.yaml", "opencv_plumb_bob.yaml"),
        ("ros_camera_info_equidistant.yaml", "opencv_fisheye.yaml"),
    ] {
        let got = read_calibration_file(&fixture(ros)).expect("a readable calibration");
        assert_eq!(got.format, CalibrationFormat::RosCameraInfo, "{ros}");
        assert_holds(ros, &got, &expected.files[opencv]);
    }
}

/// A broken file: its name, text, the line the error must give, and words its message must
/// contain.
struct Broken {
    name: &'static str,
    text: String,
    line: Option<usize>,
    says: &'static [&'static str],
    is: fn(&CalibrationError) -> bool,
}

/// `text` with the first occurrence of `from` replaced by `to`, which must exist.
fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "{from:?} not in the fixture");
    text.replacen(from, to, 1)
}

fn broken_files() -> Vec<Broken> {
    let ros = text("ros_camera_info.yaml");
    let opencv = text("opencv_plumb_bob.yaml");
    let four = text("opencv_four_coefficients.yaml");
    vec![
        Broken {
            name: "no camera matrix",
            text: edit(&ros, "camera_matrix:", "intrinsics:"),
            line: None,
            says: &["missing key camera_matrix", "K"],
            is: |e| matches!(e, CalibrationError::MissingKey { .. }),
        },
        Broken {
            name: "no distortion",
            text: edit(&ros, "distortion_coefficients:", "distortion:"),
            line: None,
            says: &["missing key distortion_coefficients"],
            is: |e| matches!(e, CalibrationError::MissingKey { .. }),
        },
        Broken {
            name: "six coefficients",
            text: edit(
                &edit(&ros, "cols: 5", "cols: 6"),
                "-0.01874]",
                "-0.01874, 0.0]",
            ),
            line: Some(15),
            says: &["6 distortion coefficients", "plumb_bob"],
            is: |e| {
                matches!(
                    e,
                    CalibrationError::CoefficientCount {
                        model: Some(DistortionModel::PlumbBob),
                        count: 6,
                        ..
                    }
                )
            },
        },
        Broken {
            name: "rational model with five coefficients",
            text: edit(&ros, "model: plumb_bob", "model: rational_polynomial"),
            line: Some(15),
            says: &["5 distortion coefficients", "rational_polynomial", "8"],
            is: |e| matches!(e, CalibrationError::CoefficientCount { count: 5, .. }),
        },
        Broken {
            name: "seven coefficients and no model",
            text: edit(
                &edit(&four, "cols: 4", "cols: 7"),
                "-0.00042000000000000002 ]",
                "-0.00042000000000000002, 0., 0., 0. ]",
            ),
            line: Some(9),
            says: &["7 distortion coefficients fit no model"],
            is: |e| matches!(e, CalibrationError::CoefficientCount { model: None, .. }),
        },
        Broken {
            name: "fourteen coefficients",
            text: text("opencv_fourteen_coefficients.yaml"),
            line: Some(9),
            says: &["14 distortion coefficients", "thin-prism"],
            is: |e| matches!(e, CalibrationError::UnsupportedModel { count: 14, .. }),
        },
        Broken {
            name: "NaN written by OpenCV",
            text: text("opencv_nan.yaml"),
            line: Some(9),
            says: &[
                "distortion_coefficients",
                "element 1",
                "not a finite number",
            ],
            is: |e| matches!(e, CalibrationError::NonFinite { index: 1, .. }),
        },
        Broken {
            name: "infinite focal length",
            text: edit(&ros, "912.34", ".inf"),
            line: Some(8),
            says: &["camera_matrix", "element 0"],
            is: |e| matches!(e, CalibrationError::NonFinite { index: 0, .. }),
        },
        Broken {
            name: "rows × cols not the data's length",
            text: edit(&ros, "  rows: 1\n  cols: 5", "  rows: 2\n  cols: 5"),
            line: Some(15),
            says: &["2 × 5 = 10", "5 elements"],
            is: |e| matches!(e, CalibrationError::Shape { .. }),
        },
        Broken {
            name: "camera matrix 3 × 4",
            text: edit(
                &edit(&opencv, "   rows: 3\n   cols: 3", "   rows: 3\n   cols: 4"),
                "0., 0., 1. ]",
                "0., 0., 1., 0., 0., 0. ]",
            ),
            line: Some(11),
            says: &["camera_matrix", "must be 3 × 3, got 3 × 4"],
            is: |e| matches!(e, CalibrationError::Shape { .. }),
        },
        Broken {
            name: "projection matrix 3 × 3",
            text: edit(&ros, "  rows: 3\n  cols: 4", "  rows: 4\n  cols: 3"),
            line: Some(25),
            says: &["projection_matrix", "must be 3 × 4, got 4 × 3"],
            is: |e| matches!(e, CalibrationError::Shape { .. }),
        },
        Broken {
            name: "skew",
            text: edit(&ros, "912.34   ,    0.     ,", "912.34   ,    0.5    ,"),
            line: Some(8),
            says: &["skew 0.5 px", "no skew term"],
            is: |e| matches!(e, CalibrationError::Skew { .. }),
        },
        Broken {
            name: "negative focal length",
            text: edit(&ros, "912.34", "-912.34"),
            line: Some(8),
            says: &["fx_px must be positive"],
            is: |e| {
                matches!(
                    e,
                    CalibrationError::Camera {
                        source: CameraError::NonPositive { .. },
                        ..
                    }
                )
            },
        },
        Broken {
            name: "unknown model",
            text: edit(&ros, "model: plumb_bob", "model: kannala_brandt"),
            line: Some(14),
            says: &[
                "\"kannala_brandt\"",
                "plumb_bob, rational_polynomial or equidistant",
            ],
            is: |e| matches!(e, CalibrationError::UnknownModel { .. }),
        },
        Broken {
            name: "K and camera_matrix both",
            text: format!("{ros}K:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"),
            line: Some(31),
            says: &["both camera_matrix and K"],
            is: |e| matches!(e, CalibrationError::DuplicateKey { .. }),
        },
        Broken {
            name: "image width without height",
            text: edit(&ros, "image_height: 720\n", ""),
            line: None,
            says: &["missing key image_height"],
            is: |e| matches!(e, CalibrationError::MissingKey { .. }),
        },
        Broken {
            name: "image width not a whole number",
            text: edit(&ros, "image_width: 1280", "image_width: 1280.5"),
            line: Some(5),
            says: &["image_width", "positive whole number"],
            is: |e| matches!(e, CalibrationError::Shape { .. }),
        },
        Broken {
            name: "integer matrix type",
            text: edit(&opencv, "dt: d", "dt: u"),
            line: Some(11),
            says: &["dt", "floating-point"],
            is: |e| matches!(e, CalibrationError::Shape { .. }),
        },
        Broken {
            name: "distortion as a 5 × 5 matrix",
            text: edit(
                &edit(&ros, "  rows: 1\n  cols: 5", "  rows: 5\n  cols: 5"),
                "[-0.3121, 0.1083, 0.00061, -0.00042, -0.01874]",
                &format!("[{}]", ["0.0"; 25].join(", ")),
            ),
            line: Some(15),
            says: &["one row or one column"],
            is: |e| matches!(e, CalibrationError::Shape { .. }),
        },
        Broken {
            name: "not YAML",
            text: edit(&ros, "data: [-0.3121,", "data: [-0.3121,,"),
            line: Some(18),
            says: &["not valid YAML"],
            is: |e| matches!(e, CalibrationError::Syntax { .. }),
        },
        Broken {
            name: "not a mapping",
            text: "- 1\n- 2\n".to_owned(),
            line: None,
            says: &["not a list"],
            is: |e| matches!(e, CalibrationError::NotAMapping { .. }),
        },
    ]
}

#[test]
fn refuses_each_broken_file_with_its_reason_and_line() {
    for case in broken_files() {
        let err = parse_calibration(&case.text).expect_err(case.name);
        let message = err.to_string();
        eprintln!("{}: {message}", case.name);
        assert!((case.is)(&err), "{}: {err:?}", case.name);
        assert_eq!(err.line(), case.line, "{}: {message}", case.name);
        if let Some(line) = case.line {
            assert!(
                message.starts_with(&format!("line {line}: ")),
                "{}: {message}",
                case.name
            );
        }
        for words in case.says {
            assert!(
                message.contains(words),
                "{}: {message:?} lacks {words:?}",
                case.name
            );
        }
    }
}

#[test]
fn a_file_error_names_the_file_and_the_line() {
    let dir = std::env::temp_dir().join(format!("qrpose-calibration-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let path = dir.join("front.yaml");
    std::fs::write(
        &path,
        edit(&text("ros_camera_info.yaml"), "912.34", "-912.34"),
    )
    .expect("written");
    let err = read_calibration_file(&path).expect_err("negative fx");
    assert_eq!(err.line(), Some(8));
    assert!(
        err.to_string()
            .starts_with(&format!("{}: line 8: camera_matrix: ", path.display())),
        "{err}"
    );
    let missing = dir.join("absent.yaml");
    let err = read_calibration_file(&missing).expect_err("no such file");
    assert!(matches!(err, CalibrationError::Read { .. }), "{err:?}");
    assert!(err.to_string().contains("absent.yaml"), "{err}");
    std::fs::remove_dir_all(&dir).expect("removed");
}
