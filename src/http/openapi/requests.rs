//! The request bodies' alternatives ([`super::variants`]) and what the server's
//! configuration changes about them ([`Served`]): without a loaded site the camera cannot be
//! a site camera and the marker size is required; without the zxing-cpp detector built in,
//! `zxing-cpp` is not a detector to ask for.
//!
//! What stays outside any schema (the residue, `docs/service.md`, Fuzzing): a quadrilateral
//! that is not convex or whose corners coincide, a pose behind the camera, magnitudes beyond
//! double precision (`numerically_degenerate`), bytes that are not a JPEG or PNG, a camera id
//! or payload the loaded site does not know, and a coefficient the lens model does not have
//! given as 0 (accepted, though the model's schema leaves it out).

use super::variants::{Variant, non_null, reference, split};
use serde_json::{Value, json};

/// What the served document says depends on: the server's configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Served {
    /// A site file is loaded (`qrpose serve --site`): cameras by id, sizes by payload.
    pub site: bool,
    /// The zxing-cpp detector is built in (cargo feature `zxing-cpp`).
    pub zxing_cpp: bool,
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
    distortion(doc);
    if !served.site {
        require(doc, "ImageRequest", "marker");
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
            title: "pixels",
            fields: &["fx_px", "fy_px", "cx_px", "cy_px", "distortion"],
            required: &["fx_px", "fy_px", "cx_px", "cy_px"],
            overrides: vec![],
        },
        Variant {
            name: "CameraSensor",
            title: "sensor",
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
            title: "site camera",
            fields: &["id"],
            required: &["id"],
            overrides: vec![],
        });
    }
    forms.push(Variant {
        name: "CameraImagePlane",
        title: "image plane (corners_mm only)",
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
    // Corners that coincide are `duplicate_corners`.
    let corners = json!({"uniqueItems": true});
    split(
        doc,
        "CornersRequest",
        &[
            Variant {
                name: "PixelCornersRequest",
                title: "corners in pixels",
                fields: PIXEL_CORNERS,
                required: required_px,
                overrides: vec![(
                    "corners_px",
                    merged_with(doc, "CornersRequest", "corners_px", &corners),
                )],
            },
            Variant {
                name: "PlaneCornersRequest",
                title: "corners in image-plane mm",
                fields: PLANE_CORNERS,
                required: required_mm,
                overrides: vec![
                    (
                        "corners_mm",
                        merged_with(doc, "CornersRequest", "corners_mm", &corners),
                    ),
                    ("camera", reference("CameraImagePlane")),
                ],
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
                title: "the code's rotation",
                fields: &["marker_quaternion_wxyz", "sigma_deg"],
                required: &["marker_quaternion_wxyz", "sigma_deg"],
                overrides: vec![("marker_quaternion_wxyz", marker)],
            },
            Variant {
                name: "RobotPrior",
                title: "the robot's rotation",
                fields: &["robot_quaternion_wxyz", "sigma_deg"],
                required: &["robot_quaternion_wxyz", "sigma_deg"],
                overrides: vec![("robot_quaternion_wxyz", robot)],
            },
        ],
    );
}

/// The lens models, each with its own coefficients.
fn distortion(doc: &mut Value) {
    split(
        doc,
        "DistortionDto",
        &[
            Variant {
                name: "DistortionPlumbBob",
                title: "plumb_bob",
                fields: &["model", "k1", "k2", "p1", "p2", "k3"],
                required: &[],
                overrides: vec![("model", json!({"enum": ["plumb_bob", null]}))],
            },
            Variant {
                name: "DistortionRationalPolynomial",
                title: "rational_polynomial",
                fields: &["model", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"],
                required: &["model"],
                overrides: vec![("model", json!({"const": "rational_polynomial"}))],
            },
            Variant {
                name: "DistortionEquidistant",
                title: "equidistant",
                fields: &["model", "k1", "k2", "k3", "k4"],
                required: &["model"],
                overrides: vec![("model", json!({"const": "equidistant"}))],
            },
        ],
    );
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
