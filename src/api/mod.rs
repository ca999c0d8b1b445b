//! Wire types shared by the HTTP service, the CLI and the stream: the request DTOs and their
//! validation into the application layer's [`crate::app::Setup`], the answer DTOs mapped
//! from its answers, and the one mapping from domain errors to problem documents
//! ([`refusal`]).
//!
//! `qrpose estimate REQUEST.json` and `POST /v1/pose/corners` both call
//! [`estimate_corners`] (validate, [`crate::app::estimate_corners`], map), so their JSON is
//! the same field for field; the image forms do the same through [`image`]. Everything a
//! client can get wrong is refused here as a [`problem::Problem`]. No HTTP framework is
//! named in this module.

pub mod alternatives;
pub mod calibrate;
pub mod camera;
pub mod context;
pub mod corners;
pub mod finite;
pub mod frames;
pub mod hand_eye;
pub mod image;
mod integral;
pub mod pick;
pub mod problem;
pub mod refusal;
pub mod request;
pub mod response;
pub mod robot;
pub mod site;
pub mod solver;
pub mod stream;

pub use corners::estimate_corners;

#[cfg(test)]
mod tests {
    use super::problem::{ErrorCode, parse_json};
    use super::request::CornersRequest;
    use super::*;
    use serde_json::{Value, json};

    fn base() -> Value {
        json!({
            "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
            "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
            "marker": {"size_mm": 50.0}
        })
    }

    fn with(pointer: &str, value: Value) -> Value {
        let mut body = base();
        let (parent, key) = pointer.rsplit_once('/').expect("a pointer with a parent");
        let target = if parent.is_empty() {
            &mut body
        } else {
            body.pointer_mut(parent).expect("parent exists")
        };
        match (target, value) {
            (Value::Object(map), Value::Null) => {
                map.remove(key);
            }
            (Value::Object(map), v) => {
                map.insert(key.to_owned(), v);
            }
            (Value::Array(items), v) => {
                let i: usize = key.parse().expect("an index");
                items[i] = v;
            }
            _ => panic!("cannot set {pointer}"),
        }
        body
    }

    fn mm_corners_with_pixel_camera() -> Value {
        let mut body = with(
            "/corners_mm",
            json!([[0.1, 0.1], [0.2, 0.1], [0.2, 0.2], [0.1, 0.2]]),
        );
        body.as_object_mut().expect("object").remove("corners_px");
        body
    }

    /// k1 = −2 folds over at r = 0.41: corners 0.56 off-axis have no undistorted ray.
    fn far_corners_with_strong_barrel() -> Value {
        let mut body = with("/camera/distortion", json!({"k1": -2.0}));
        body["corners_px"] = json!([
            [1000.0, 300.0],
            [1200.0, 300.0],
            [1200.0, 500.0],
            [1000.0, 500.0]
        ]);
        body
    }

    fn run(body: &Value) -> Result<response::PoseResponse, problem::Problem> {
        let bytes = serde_json::to_vec(body).expect("serialisable");
        parse_json::<CornersRequest>(&bytes).and_then(|r| estimate_corners(&r, None))
    }

    #[test]
    fn accepts_the_base_request() {
        let r = run(&base()).expect("valid request");
        assert_eq!(r.diagnostics.method, request::MethodDto::Reprojection);
        assert!(r.diagnostics.converged);
    }

    #[test]
    fn every_validation_error_has_its_code_and_field() {
        let square_px = json!([
            [100.0, 100.0],
            [200.0, 100.0],
            [200.0, 200.0],
            [100.0, 200.0]
        ]);
        let cases: Vec<(&str, Value, ErrorCode, &str)> = vec![
            (
                "no corners",
                with("/corners_px", Value::Null),
                ErrorCode::CornersMissingOrConflicting,
                "/corners_px",
            ),
            (
                "both corner forms",
                with("/corners_mm", square_px.clone()),
                ErrorCode::CornersMissingOrConflicting,
                "/corners_mm",
            ),
            (
                "three corners",
                with("/corners_px", json!([[1.0, 1.0], [2.0, 1.0], [2.0, 2.0]])),
                ErrorCode::CornerCount,
                "/corners_px",
            ),
            (
                "five corners",
                with(
                    "/corners_px",
                    json!([[1, 1], [2, 1], [2, 2], [1, 2], [0, 0]]),
                ),
                ErrorCode::CornerCount,
                "/corners_px",
            ),
            (
                "corner with three numbers",
                with("/corners_px/1", json!([1, 2, 3])),
                ErrorCode::InvalidType,
                "/corners_px/1",
            ),
            (
                "duplicate corners",
                with("/corners_px/2", json!([589.2, 309.8])),
                ErrorCode::DuplicateCorners,
                "/corners_px/2",
            ),
            (
                "collinear corners",
                with("/corners_px", json!([[0, 0], [100, 0], [200, 0], [0, 100]])),
                ErrorCode::CollinearCorners,
                "/corners_px/2",
            ),
            (
                "crossed corners",
                with(
                    "/corners_px",
                    json!([[100, 100], [200, 200], [200, 100], [100, 200]]),
                ),
                ErrorCode::SelfIntersectingCorners,
                "/corners_px",
            ),
            (
                "non-convex corners",
                with(
                    "/corners_px",
                    json!([[100, 100], [200, 100], [130, 130], [100, 200]]),
                ),
                ErrorCode::NonConvexCorners,
                "/corners_px/2",
            ),
            (
                "mirrored order",
                with(
                    "/corners_px",
                    json!([[100, 100], [100, 200], [200, 200], [200, 100]]),
                ),
                ErrorCode::MirroredCorners,
                "/corners_px",
            ),
            (
                "zero focal length",
                with("/camera/fx_px", json!(0.0)),
                ErrorCode::InvalidCameraParameter,
                "/camera/fx_px",
            ),
            (
                "negative focal length",
                with("/camera/fy_px", json!(-1000.0)),
                ErrorCode::InvalidCameraParameter,
                "/camera/fy_px",
            ),
            (
                "missing principal point",
                with("/camera/cy_px", Value::Null),
                ErrorCode::IncompleteCamera,
                "/camera/cy_px",
            ),
            (
                "no intrinsics",
                with("/camera", json!({})),
                ErrorCode::IncompleteCamera,
                "/camera",
            ),
            (
                "two camera forms",
                with("/camera/focal_length_mm", json!(4.0)),
                ErrorCode::IncompleteCamera,
                "/camera",
            ),
            (
                "zero pixel size",
                with(
                    "/camera",
                    json!({"focal_length_mm": 4.0, "pixel_size_um": 0.0, "cx_px": 640, "cy_px": 360}),
                ),
                ErrorCode::InvalidCameraParameter,
                "/camera/pixel_size_um",
            ),
            (
                "negative sensor focal length",
                with(
                    "/camera",
                    json!({"focal_length_mm": -4.0, "pixel_size_um": 2.0, "cx_px": 640, "cy_px": 360}),
                ),
                ErrorCode::InvalidCameraParameter,
                "/camera/focal_length_mm",
            ),
            (
                "zero marker size",
                with("/marker/size_mm", json!(0.0)),
                ErrorCode::InvalidMarkerSize,
                "/marker/size_mm",
            ),
            (
                "negative marker size",
                with("/marker/size_mm", json!(-50.0)),
                ErrorCode::InvalidMarkerSize,
                "/marker/size_mm",
            ),
            (
                "missing marker size",
                with("/marker", json!({})),
                ErrorCode::MissingField,
                "/marker/size_mm",
            ),
            (
                "unknown method",
                with("/solver", json!({"method": "magic"})),
                ErrorCode::UnknownVariant,
                "/solver/method",
            ),
            (
                "unknown field",
                with("/solver", json!({"max_iteration": 5})),
                ErrorCode::UnknownField,
                "/solver/max_iteration",
            ),
            (
                "zero iterations",
                with("/solver", json!({"max_iterations": 0})),
                ErrorCode::SolverParameterOutOfRange,
                "/solver/max_iterations",
            ),
            (
                "absurd iterations",
                with("/solver", json!({"max_iterations": 1_000_000_000_000_u64})),
                ErrorCode::SolverParameterOutOfRange,
                "/solver/max_iterations",
            ),
            (
                "negative iterations",
                with("/solver", json!({"max_iterations": -5})),
                ErrorCode::InvalidType,
                "/solver/max_iterations",
            ),
            (
                "fractional iterations",
                with("/solver", json!({"max_iterations": 2.5})),
                ErrorCode::InvalidType,
                "/solver/max_iterations",
            ),
            (
                "iterations past u64",
                with("/solver", json!({"max_iterations": 1e20})),
                ErrorCode::InvalidType,
                "/solver/max_iterations",
            ),
            (
                "zero iterations written as a float",
                with("/solver", json!({"max_iterations": 0.0})),
                ErrorCode::SolverParameterOutOfRange,
                "/solver/max_iterations",
            ),
            (
                "zero gain",
                with("/solver", json!({"method": "paper", "gain": 0.0})),
                ErrorCode::SolverParameterOutOfRange,
                "/solver/gain",
            ),
            (
                "huge gain",
                with("/solver", json!({"gain": 11.0})),
                ErrorCode::SolverParameterOutOfRange,
                "/solver/gain",
            ),
            (
                "zero tolerance",
                with("/solver", json!({"tolerance_mm": 0.0})),
                ErrorCode::SolverParameterOutOfRange,
                "/solver/tolerance_mm",
            ),
            (
                "negative initial depth",
                with("/solver", json!({"initial_z_mm": -450.0})),
                ErrorCode::SolverParameterOutOfRange,
                "/solver/initial_z_mm",
            ),
            (
                "zero corner sigma",
                with("/solver", json!({"corner_sigma_px": 0.0})),
                ErrorCode::SolverParameterOutOfRange,
                "/solver/corner_sigma_px",
            ),
            (
                "mm corners with pixel intrinsics",
                mm_corners_with_pixel_camera(),
                ErrorCode::IncompleteCamera,
                "/camera/fx_px",
            ),
            (
                "undistortion beyond the fold",
                far_corners_with_strong_barrel(),
                ErrorCode::UndistortionFailed,
                // P1 (bottom-right, corner 2 in qr order) is undistorted first.
                "/corners_px/2",
            ),
        ];
        for (name, body, code, field) in cases {
            match run(&body) {
                Ok(_) => panic!("{name}: accepted"),
                Err(p) => {
                    assert_eq!(p.code, code, "{name}: {p:?}");
                    assert_eq!(p.field.as_deref(), Some(field), "{name}: {p:?}");
                    assert_eq!(p.status, code.status(), "{name}");
                    if matches!(
                        code,
                        ErrorCode::InvalidCameraParameter | ErrorCode::SolverParameterOutOfRange
                    ) {
                        // The detail names the parameter as the API spells it.
                        let leaf = field.rsplit('/').next().unwrap_or(field);
                        assert!(p.detail.contains(leaf), "{name}: {}", p.detail);
                    }
                    assert!(
                        (400..500).contains(&p.status),
                        "{name}: status {}",
                        p.status
                    );
                }
            }
        }
    }

    #[test]
    fn non_finite_numbers_are_refused_with_their_field() {
        // JSON cannot carry NaN, but library callers can.
        let camera = request::CameraDto {
            fx_px: Some(f64::NAN),
            fy_px: Some(1.0),
            cx_px: Some(0.0),
            cy_px: Some(0.0),
            ..Default::default()
        };
        let p = camera
            .to_camera(request::CornersUnit::Px)
            .expect_err("NaN focal length");
        assert_eq!(
            (p.code, p.field.as_deref()),
            (ErrorCode::NonFiniteNumber, Some("/camera/fx_px"))
        );
        let mut req: CornersRequest = serde_json::from_value(base()).expect("valid base");
        req.corners_px = Some(vec![
            vec![1.0, 1.0],
            vec![2.0, f64::INFINITY],
            vec![2.0, 2.0],
            vec![1.0, 2.0],
        ]);
        let p = estimate_corners(&req, None).expect_err("infinite corner");
        assert_eq!(
            (p.code, p.field.as_deref()),
            (ErrorCode::NonFiniteNumber, Some("/corners_px/1"))
        );
    }

    #[test]
    fn mm_corners_give_pixel_diagnostics_only_with_a_pixel_size() {
        // The same view in image-plane mm (f = 4 mm, 4 µm pixels = 1000 px focal length).
        let pitch_mm = 0.004;
        let px: Vec<[f64; 2]> = vec![
            [589.2, 309.8],
            [689.9, 311.4],
            [688.1, 411.6],
            [588.0, 409.5],
        ];
        let mm: Vec<[f64; 2]> = px
            .iter()
            .map(|[u, v]| [(u - 639.5) * pitch_mm, (v - 359.5) * pitch_mm])
            .collect();
        let mut body = base();
        body.as_object_mut().expect("object").remove("corners_px");
        body["corners_mm"] = json!(mm);
        body["camera"] = json!({"focal_length_mm": 4.0});
        let without = run(&body).expect("paper form");
        assert!(
            without.diagnostics.reprojection_rms_px.is_none()
                && without.diagnostics.covariance.is_none()
        );
        body["camera"]["pixel_size_um"] = json!(4.0);
        let with_pitch = run(&body).expect("paper form with pixel size");
        let reference = run(&base()).expect("pixel form");
        assert!((with_pitch.position_mm.z - reference.position_mm.z).abs() < 1e-6);
        assert!((without.position_mm.z - reference.position_mm.z).abs() < 1e-6);
        let (a, b) = (
            with_pitch.diagnostics.reprojection_rms_px,
            reference.diagnostics.reprojection_rms_px,
        );
        assert!(
            a.zip(b).is_some_and(|(a, b)| (a - b).abs() < 1e-6),
            "{a:?} vs {b:?}"
        );
    }
}
