//! The request bodies' alternatives ([`super::variants`]) and what the server's
//! configuration changes about them ([`Served`]): without a loaded site the camera cannot be
//! a site camera and the marker size is required; without the zxing-cpp detector built in,
//! `zxing-cpp` is not a detector to ask for.
//!
//! The cross-field rule a schema can say is written here too: `points = finders` needs
//! `method = reprojection` (a `not` on the image request).
//!
//! What stays outside any schema (the residue, `docs/service.md`, Fuzzing), each refused
//! with its own code although the request is valid by the document:
//! - a quadrilateral that is not convex or not clockwise, or whose corners nearly coincide
//!   or nearly lie on a line (`non_convex_corners`, `mirrored_corners`,
//!   `duplicate_corners`, `collinear_corners`: relative tolerances no schema can state);
//! - corners no pose fits: the paper's iteration settles only on axis and square on, and
//!   elsewhere can drift until its corners are collinear (`no_solution`); a corner that
//!   cannot be undistorted with the given coefficients (`undistortion_failed`);
//! - magnitudes beyond double precision: corners that overflow once divided by the pixel
//!   size, a quaternion too small to normalise (`numerically_degenerate`, `invalid_prior`;
//!   a robot pose's quaternion whose norm is off 1 by more than 1e-3, `invalid_robot_pose`;
//!   focal lengths and pixel pitches have stated ranges, `camera::FOCAL_RANGE_PX`);
//! - bytes that are not a JPEG or PNG (`undecodable_image`); photos for `POST /v1/calibrate`
//!   that do not show one code, decoded in at least three of them, at one size
//!   (`no_code_found`, `too_few_views`, `mixed_image_sizes`);
//! - a camera id or payload the loaded site does not know (`unknown_camera`,
//!   `unknown_marker_size`);
//! - what OpenAPI cannot tie across the query and the body: with a raw image body the camera
//!   (in one of its forms) and, without a site, `marker_size_mm` are required; and
//!   `points = finders` with another method when one of them comes from the query.
//!
//! And one place where the server accepts more than the document: a multipart `request`
//! part without the camera or marker when the query parameters give them (the document
//! requires them in the part).

use super::variants::{Variant, non_null, reference, split};
use crate::api::image::PointsDto;
use crate::api::request::MethodDto;
use crate::app::{DistortionModel, Method};
use clap::ValueEnum;
use serde_json::{Value, json};

/// What the served document says depends on: the server's configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Served {
    /// A site file is loaded (`qrpose serve --site`): cameras by id, sizes by payload.
    pub site: bool,
    /// The zxing-cpp detector is built in (cargo feature `zxing-cpp`).
    pub zxing_cpp: bool,
    /// An auth file is loaded (`qrpose serve --auth-file`): the protected operations need
    /// a bearer token. Without one every operation is open and the document asks for none.
    pub auth: bool,
}

/// The fields of a corners request in pixels.
const PIXEL_CORNERS: &[&str] = &[
    "corners_px",
    "corner_order",
    "camera",
    "marker",
    "payload",
    "solver",
    "prior",
];
/// The fields of a corners request in image-plane mm: the same, but for the corners.
const PLANE_CORNERS: &[&str] = &[
    "corners_mm",
    "corner_order",
    "camera",
    "marker",
    "payload",
    "solver",
    "prior",
];

/// The component name of the camera given by a site id.
const SITE_CAMERA: &str = "CameraSiteId";

/// Splits the request objects into their alternatives, for `served`.
pub fn write_alternatives(doc: &mut Value, served: Served) {
    camera(doc, served);
    corners(doc, served);
    prior(doc);
    robot_pose(doc);
    distortion(doc);
    finders_need_reprojection(doc);
    if !served.site {
        require(doc, "ImageRequest", "marker");
        require(doc, "HandEyeRequest", "marker");
    }
    if !served.zxing_cpp {
        drop_enum_value(doc, "DetectorDto", "zxing-cpp");
    }
}

/// The camera in its forms: pixels, sensor, site id (with a site), and the paper's image
/// plane, which only corners in image-plane mm take.
fn camera(doc: &mut Value, served: Served) {
    let mut forms = vec![
        Variant {
            name: "CameraPixels",
            summary: "pixels",
            fields: &["fx_px", "fy_px", "cx_px", "cy_px", "distortion"],
            required: &["fx_px", "fy_px", "cx_px", "cy_px"],
            overrides: vec![],
        },
        Variant {
            name: "CameraSensor",
            summary: "sensor",
            fields: &[
                "focal_length_mm",
                "pixel_size_um",
                "cx_px",
                "cy_px",
                "distortion",
            ],
            required: &["focal_length_mm", "pixel_size_um", "cx_px", "cy_px"],
            overrides: vec![],
        },
    ];
    if served.site {
        forms.push(Variant {
            name: SITE_CAMERA,
            summary: "site camera",
            fields: &["id"],
            required: &["id"],
            overrides: vec![],
        });
    }
    forms.push(Variant {
        name: "CameraImagePlane",
        summary: "image plane (corners_mm only)",
        fields: &["focal_length_mm", "pixel_size_um", "distortion"],
        required: &["focal_length_mm"],
        overrides: vec![],
    });
    split(doc, "CameraDto", &forms);
    // The image plane is an alternative of image-plane corners alone.
    if let Some(Value::Array(one_of)) = doc.pointer_mut("/components/schemas/CameraDto/oneOf") {
        one_of.retain(|r| *r != reference("CameraImagePlane"));
    }
}

/// Corners in pixels or in image-plane mm.
fn corners(doc: &mut Value, served: Served) {
    let required_px: &'static [&'static str] = if served.site {
        &["corners_px", "camera"]
    } else {
        &["corners_px", "camera", "marker"]
    };
    let required_mm: &'static [&'static str] = if served.site {
        &["corners_mm", "camera"]
    } else {
        &["corners_mm", "camera", "marker"]
    };
    split(
        doc,
        "CornersRequest",
        &[
            Variant {
                name: "PixelCornersRequest",
                summary: "corners in pixels",
                fields: PIXEL_CORNERS,
                required: required_px,
                overrides: vec![],
            },
            Variant {
                name: "PlaneCornersRequest",
                summary: "corners in image-plane mm",
                fields: PLANE_CORNERS,
                required: required_mm,
                overrides: vec![("camera", reference("CameraImagePlane"))],
            },
        ],
    );
}

/// The derived schema of `object.field` with `extra`'s keys added.
fn merged_with(doc: &Value, object: &str, field: &str, extra: &Value) -> Value {
    let mut schema = doc["components"]["schemas"][object]["properties"][field].clone();
    if let (Some(map), Some(extra)) = (schema.as_object_mut(), extra.as_object()) {
        for (k, v) in extra {
            map.insert(k.clone(), v.clone());
        }
    }
    schema
}

/// A quaternion that is not all zero (it has no rotation).
fn rotation(doc: &Value, field: &str) -> Value {
    merged_with(
        doc,
        "PriorDto",
        field,
        &json!({"not": {"items": {"const": 0}}}),
    )
}

/// The prior: the code's rotation or the robot's.
fn prior(doc: &mut Value) {
    let marker = rotation(doc, "marker_quaternion_wxyz");
    let robot = rotation(doc, "robot_quaternion_wxyz");
    split(
        doc,
        "PriorDto",
        &[
            Variant {
                name: "MarkerPrior",
                summary: "the code's rotation",
                fields: &["marker_quaternion_wxyz", "sigma_deg"],
                required: &["marker_quaternion_wxyz", "sigma_deg"],
                overrides: vec![("marker_quaternion_wxyz", marker)],
            },
            Variant {
                name: "RobotPrior",
                summary: "the robot's rotation",
                fields: &["robot_quaternion_wxyz", "sigma_deg"],
                required: &["robot_quaternion_wxyz", "sigma_deg"],
                overrides: vec![("robot_quaternion_wxyz", robot)],
            },
        ],
    );
}

/// A robot pose: the translation and exactly one rotation form.
fn robot_pose(doc: &mut Value) {
    split(
        doc,
        "RobotPoseDto",
        &[
            Variant {
                name: "RobotPoseQuaternion",
                summary: "quaternion (ABB)",
                fields: &["translation_mm", "quaternion_wxyz"],
                required: &["translation_mm", "quaternion_wxyz"],
                overrides: vec![],
            },
            Variant {
                name: "RobotPoseRotationVector",
                summary: "rotation vector (Universal Robots)",
                fields: &["translation_mm", "rotation_vector_rad"],
                required: &["translation_mm", "rotation_vector_rad"],
                overrides: vec![],
            },
            Variant {
                name: "RobotPoseEulerZyx",
                summary: "Z-Y-X Euler angles (KUKA; Fanuc, Yaskawa)",
                fields: &["translation_mm", "euler_zyx_deg"],
                required: &["translation_mm", "euler_zyx_deg"],
                overrides: vec![],
            },
        ],
    );
}

/// Every field of a distortion: the model and the coefficients of the largest model
/// (`rational_polynomial`), in OpenCV's order.
const DISTORTION_FIELDS: &[&str] = &["model", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"];

/// The coefficients `model` does not have, each `0` or omitted (the server refuses any other
/// value, `invalid_camera_parameter`).
fn not_in(model: DistortionModel) -> Vec<(&'static str, Value)> {
    DistortionModel::RationalPolynomial
        .params()
        .iter()
        .filter(|p| !model.params().contains(p))
        .map(|p| {
            let description = format!("Not a coefficient of `{}`: 0 or omitted.", model.name());
            (p.name(), json!({"const": 0, "description": description}))
        })
        .collect()
}

/// The lens models, each with its own coefficients (and those it does not have, at 0).
fn distortion(doc: &mut Value) {
    let model = |value: Value, lacking: DistortionModel| {
        let mut overrides = vec![("model", value)];
        overrides.extend(not_in(lacking));
        overrides
    };
    split(
        doc,
        "DistortionDto",
        &[
            Variant {
                name: "DistortionPlumbBob",
                summary: "plumb_bob",
                fields: DISTORTION_FIELDS,
                required: &[],
                overrides: model(
                    json!({"enum": ["plumb_bob", null]}),
                    DistortionModel::PlumbBob,
                ),
            },
            Variant {
                name: "DistortionRationalPolynomial",
                summary: "rational_polynomial",
                fields: DISTORTION_FIELDS,
                required: &["model"],
                overrides: model(
                    json!({"const": "rational_polynomial"}),
                    DistortionModel::RationalPolynomial,
                ),
            },
            Variant {
                name: "DistortionEquidistant",
                summary: "equidistant",
                fields: DISTORTION_FIELDS,
                required: &["model"],
                overrides: model(
                    json!({"const": "equidistant"}),
                    DistortionModel::Equidistant,
                ),
            },
        ],
    );
}

/// `points = finders` needs `method = reprojection` (else `points_need_reprojection`; an
/// omitted method is `reprojection`): the image request is not one with `points: finders`
/// and another `solver.method`.
fn finders_need_reprojection(doc: &mut Value) {
    let others: Vec<Value> = MethodDto::value_variants()
        .iter()
        .filter(|m| Method::from(**m) != Method::Reprojection)
        .map(|m| json!(m))
        .collect();
    if let Some(schema) = doc.pointer_mut("/components/schemas/ImageRequest") {
        schema["not"] = json!({
            "required": ["points", "solver"],
            "properties": {
                "points": {"const": PointsDto::Finders},
                "solver": {"required": ["method"], "properties": {"method": {"enum": others}}},
            },
        });
    }
}

/// Makes `field` of component `object` required (and never null).
fn require(doc: &mut Value, object: &str, field: &str) {
    let Some(schema) = doc.pointer_mut(&format!("/components/schemas/{object}")) else {
        return;
    };
    if let Some(property) = schema.pointer_mut(&format!("/properties/{field}")) {
        *property = non_null(property.take());
    }
    match schema.get_mut("required").and_then(Value::as_array_mut) {
        Some(required) if !required.contains(&json!(field)) => required.push(json!(field)),
        Some(_) => {}
        None => schema["required"] = json!([field]),
    }
}

/// Removes `value` from the enumeration of component `name`.
fn drop_enum_value(doc: &mut Value, name: &str, value: &str) {
    if let Some(Value::Array(values)) = doc.pointer_mut(&format!("/components/schemas/{name}/enum"))
    {
        values.retain(|v| v != value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_corners_forms_share_every_field_but_the_corners() {
        assert_eq!(PIXEL_CORNERS[1..], PLANE_CORNERS[1..]);
    }

    /// A validator of component `name` of the document of `served`.
    fn validator(served: Served, name: &str) -> jsonschema::Validator {
        let json = crate::http::openapi::openapi_json(served).expect("a document");
        let mut root: Value = serde_json::from_str(&json).expect("JSON");
        root["$ref"] = json!(format!("#/components/schemas/{name}"));
        jsonschema::draft202012::new(&root).expect("a valid schema")
    }

    #[test]
    fn finders_are_valid_with_reprojection_only() {
        let camera = json!({"fx_px": 1000, "fy_px": 1000, "cx_px": 640, "cy_px": 360});
        let request = |points: &str, solver: Value| {
            json!({"camera": camera, "marker": {"size_mm": 50}, "points": points,
                   "solver": solver})
        };
        let image = validator(Served::default(), "ImageRequest");
        for (points, solver, valid) in [
            ("finders", json!({}), true),
            ("finders", json!({"method": "reprojection"}), true),
            ("finders", json!({"method": "paper"}), false),
            ("finders", json!({"method": "depth-newton"}), false),
            ("corners", json!({"method": "paper"}), true),
        ] {
            let r = request(points, solver);
            assert_eq!(image.is_valid(&r), valid, "{r}");
        }
    }

    #[test]
    fn a_corner_is_a_pair_and_corners_are_distinct() {
        let corners = validator(Served::default(), "CornersRequest");
        let request = |corners_px: Value| {
            json!({"corners_px": corners_px, "marker": {"size_mm": 50},
                   "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 640, "cy_px": 360}})
        };
        let square = json!([[0, 0], [10, 0], [10, 10], [0, 10]]);
        assert!(corners.is_valid(&request(square)));
        for bad in [
            json!([[0, 0], [10, 0], [10, 10], [0, 10, 1]]),
            json!([[0, 0], [10, 0], [10, 10], [0]]),
            json!([[0, 0], [10, 0], [10, 10], [0, 0]]),
            json!([[0, 0], [10, 0], [10, 10]]),
        ] {
            assert!(!corners.is_valid(&request(bad.clone())), "{bad}");
        }
    }

    #[test]
    fn every_model_lists_every_coefficient_and_fixes_those_it_lacks_at_0() {
        let names: Vec<&str> = DistortionModel::RationalPolynomial
            .params()
            .iter()
            .map(|p| p.name())
            .collect();
        assert_eq!(DISTORTION_FIELDS[1..], names[..]);
        let lens = validator(Served::default(), "DistortionDto");
        for (distortion, valid) in [
            (json!({"k1": 0.1, "k4": 0}), true),
            (json!({"k1": 0.1, "k4": 0.5}), false),
            (json!({"model": "equidistant", "k4": 0.5, "p1": 0.0}), true),
            (json!({"model": "equidistant", "p1": 0.1}), false),
            (json!({"model": "rational_polynomial", "k6": 0.5}), true),
        ] {
            assert_eq!(lens.is_valid(&distortion), valid, "{distortion}");
        }
    }

    #[test]
    fn a_required_field_loses_its_null() {
        let mut doc = json!({"components": {"schemas": {"R": {"type": "object",
            "required": ["camera"],
            "properties": {"marker": {"oneOf": [{"$ref": "#/components/schemas/M"},
                                                  {"type": "null"}]}}}}}});
        require(&mut doc, "R", "marker");
        let r = &doc["components"]["schemas"]["R"];
        assert_eq!(r["required"], json!(["camera", "marker"]));
        assert_eq!(r["properties"]["marker"], reference("M"));
    }
}
