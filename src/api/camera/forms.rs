//! The camera's and the lens's forms in the document ([`crate::api::alternatives`]): a
//! camera in pixels, by sensor, by site id (with a site), or on the paper's image plane
//! (corners in mm only); a lens model with its own coefficients, those it lacks at 0.

use crate::api::alternatives::{Form, Narrowed, Rule};
use crate::geometry::camera::DistortionModel;
use serde_json::json;

/// The camera's forms: pixels, sensor, site id (with a site), and the paper's image plane,
/// which only corners in image-plane mm take.
#[must_use]
pub fn camera_forms(site: bool) -> Rule {
    let mut forms = vec![
        Form {
            name: "CameraPixels",
            summary: "pixels",
            fields: vec!["fx_px", "fy_px", "cx_px", "cy_px", "distortion"],
            required: &["fx_px", "fy_px", "cx_px", "cy_px"],
            narrowed: vec![],
        },
        Form {
            name: "CameraSensor",
            summary: "sensor",
            fields: vec![
                "focal_length_mm",
                "pixel_size_um",
                "cx_px",
                "cy_px",
                "distortion",
            ],
            required: &["focal_length_mm", "pixel_size_um", "cx_px", "cy_px"],
            narrowed: vec![],
        },
    ];
    if site {
        forms.push(Form {
            name: "CameraSiteId",
            summary: "site camera",
            fields: vec!["id"],
            required: &["id"],
            narrowed: vec![],
        });
    }
    forms.push(Form {
        name: IMAGE_PLANE,
        summary: "image plane (corners_mm only)",
        fields: vec!["focal_length_mm", "pixel_size_um", "distortion"],
        required: &["focal_length_mm"],
        narrowed: vec![],
    });
    Rule::Split {
        component: "CameraDto",
        forms,
        only_within: &[IMAGE_PLANE],
    }
}

/// The component of the image-plane camera, which corners in mm narrow `camera` to.
pub const IMAGE_PLANE: &str = "CameraImagePlane";

/// Every field of a distortion: the model and the coefficients of the largest model
/// (`rational_polynomial`), in OpenCV's order.
const DISTORTION_FIELDS: &[&str] = &["model", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"];

/// The model field fixed to `model`, and the coefficients `lacking` does not have, each `0`
/// or omitted (the server refuses any other value, `invalid_camera_parameter`).
fn fixed(model: serde_json::Value, lacking: DistortionModel) -> Vec<(&'static str, Narrowed)> {
    let mut narrowed = vec![("model", Narrowed::To(model))];
    narrowed.extend(
        DistortionModel::RationalPolynomial
            .params()
            .iter()
            .filter(|p| !lacking.params().contains(p))
            .map(|p| {
                let description =
                    format!("Not a coefficient of `{}`: 0 or omitted.", lacking.name());
                (
                    p.name(),
                    Narrowed::To(json!({"const": 0, "description": description})),
                )
            }),
    );
    narrowed
}

/// The lens models, each with its own coefficients (and those it does not have, at 0).
#[must_use]
pub fn distortion_forms() -> Rule {
    let form = |name, summary, required, model, lacking| Form {
        name,
        summary,
        fields: DISTORTION_FIELDS.to_vec(),
        required,
        narrowed: fixed(model, lacking),
    };
    Rule::Split {
        component: "DistortionDto",
        forms: vec![
            form(
                "DistortionPlumbBob",
                "plumb_bob",
                &[],
                json!({"enum": ["plumb_bob", null]}),
                DistortionModel::PlumbBob,
            ),
            form(
                "DistortionRationalPolynomial",
                "rational_polynomial",
                &["model"],
                json!({"const": "rational_polynomial"}),
                DistortionModel::RationalPolynomial,
            ),
            form(
                "DistortionEquidistant",
                "equidistant",
                &["model"],
                json!({"const": "equidistant"}),
                DistortionModel::Equidistant,
            ),
        ],
        only_within: &[],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lens_forms_list_every_coefficient_in_opencv_s_order() {
        let names: Vec<&str> = DistortionModel::RationalPolynomial
            .params()
            .iter()
            .map(|p| p.name())
            .collect();
        assert_eq!(DISTORTION_FIELDS[1..], names[..]);
    }
}
