//! What the wire types' derived schemas cannot say by themselves, declared beside the types:
//! the valid forms of an object whose fields exclude each other (a camera in pixels or by
//! sensor, a robot pose's one rotation), a cross-field rule, and what the server's
//! configuration changes (a site camera, the marker size without a site).
//!
//! The wire types are single structs (one deserialiser, one set of problem documents), so
//! their derived schema is one object with every field optional. Each type that has forms
//! declares them here as [`Rule`]s next to its fields ([`rules`] lists them all); the
//! OpenAPI and AsyncAPI documents apply them to the derived schemas and restate nothing: a
//! form names the fields that make it up, and each field's schema (type, description, range,
//! default) is the derived one. A test checks that every field of a split object is in some
//! form, so a new field cannot vanish from the document.

use super::camera::{camera_forms, distortion_forms};
use super::frames::prior_forms;
use super::image::finders_need_reprojection;
use super::request::corners_forms;
use super::robot::robot_pose_forms;
use serde_json::Value;

/// One alternative of a split object: a component made of some of the derived object's
/// fields, closed to the others.
#[derive(Debug, Clone)]
pub struct Form {
    /// The component's name.
    pub name: &'static str,
    /// What the alternative is, for people: the first line of its description.
    pub summary: &'static str,
    /// The derived object's fields that make it up.
    pub fields: Vec<&'static str>,
    /// The fields it requires (never null).
    pub required: &'static [&'static str],
    /// Fields whose schema this form narrows.
    pub narrowed: Vec<(&'static str, Narrowed)>,
}

/// How a form narrows one field's derived schema.
#[derive(Debug, Clone)]
pub enum Narrowed {
    /// This schema instead (keeping the derived description).
    To(Value),
    /// The derived schema with these keywords added.
    With(Value),
}

/// What the document says beyond the derived schemas, for one component.
#[derive(Debug, Clone)]
pub enum Rule {
    /// The component is a `oneOf` of these forms (each a component of its own); a form
    /// named in `only_within` is not among them and serves only as a narrowed field's
    /// schema elsewhere (the image-plane camera of corners in mm).
    Split {
        /// The split object.
        component: &'static str,
        /// Its forms.
        forms: Vec<Form>,
        /// Forms kept out of the union.
        only_within: &'static [&'static str],
    },
    /// The component's field is required (and never null).
    Require {
        /// The object.
        component: &'static str,
        /// The field.
        field: &'static str,
    },
    /// The component may not match this schema (a JSON Schema `not`).
    Not {
        /// The object.
        component: &'static str,
        /// What it may not be.
        schema: Value,
    },
    /// No operation takes this query parameter.
    NoParameter(&'static str),
    /// The enumeration of the component lacks this value.
    Without {
        /// The enumeration.
        component: &'static str,
        /// The value the server refuses.
        value: &'static str,
    },
}

/// Every rule of the wire model, for a server with or without a site and the zxing-cpp
/// detector.
#[must_use]
pub fn rules(site: bool, zxing_cpp: bool) -> Vec<Rule> {
    let mut rules = vec![
        camera_forms(site),
        corners_forms(site),
        prior_forms(),
        robot_pose_forms(),
        distortion_forms(),
        finders_need_reprojection(),
    ];
    if !site {
        rules.push(Rule::NoParameter("camera_id"));
        for component in ["ImageRequest", "HandEyeRequest"] {
            rules.push(Rule::Require {
                component,
                field: "marker",
            });
        }
    }
    if !zxing_cpp {
        rules.push(Rule::Without {
            component: "DetectorDto",
            value: "zxing-cpp",
        });
    }
    rules
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::camera::{CameraDto, DistortionDto};
    use crate::api::frames::PriorDto;
    use crate::api::request::CornersRequest;
    use crate::api::robot::RobotPoseDto;
    use utoipa::PartialSchema;

    /// The derived fields of `T`'s object schema.
    fn fields_of<T: PartialSchema>() -> Vec<String> {
        let schema = serde_json::to_value(T::schema()).expect("a schema");
        schema["properties"]
            .as_object()
            .expect("an object")
            .keys()
            .cloned()
            .collect()
    }

    #[test]
    fn every_field_of_a_split_object_is_in_one_of_its_forms() {
        let derived = [
            ("CameraDto", fields_of::<CameraDto>()),
            ("CornersRequest", fields_of::<CornersRequest>()),
            ("PriorDto", fields_of::<PriorDto>()),
            ("RobotPoseDto", fields_of::<RobotPoseDto>()),
            ("DistortionDto", fields_of::<DistortionDto>()),
        ];
        let mut split = 0;
        for rule in rules(true, true) {
            let Rule::Split {
                component, forms, ..
            } = rule
            else {
                continue;
            };
            split += 1;
            let (_, fields) = derived
                .iter()
                .find(|(name, _)| *name == component)
                .expect("a split object of the list");
            for field in fields {
                assert!(
                    forms.iter().any(|f| f.fields.contains(&field.as_str())),
                    "{component}.{field} is in none of its forms"
                );
            }
            for form in &forms {
                for field in form.fields.iter().chain(form.required) {
                    assert!(
                        fields.contains(&(*field).to_owned()),
                        "{}: {field}",
                        form.name
                    );
                }
            }
        }
        assert_eq!(split, derived.len());
    }
}
