//! The Pose tab and a product (docs/pick.md) in headless Chromium: a server with a site file
//! whose `objects` rule names the code's payload and whose camera `fixed` stands on the robot
//! (`tests/support/pick.rs`); a rendered photo of the product's code goes in through the
//! page with that camera named and a least grasp probability between the two grasps'. The
//! page must draw the product's box and each grasp's approach axis where the server's
//! overlay puts them (`src/annotate/overlay.rs`), in its colours (cyan; green for the
//! graspable grasp, orange for the other), and list each grasp with the answer's numbers.

use super::support::{Server, client, scratch_dir};
use super::webdriver::Browser;
use super::{DESKTOP, PROJECTION_TOL_PX, lock, open_page, severe};
use qrpose::annotate::overlay::{BOX, GRASPABLE, NOT_GRASPABLE, Rgb, Segment, object_segments};
use qrpose::api::image::ImageResponse;
use qrpose::geometry::camera::Camera;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

#[path = "../support/pick.rs"]
mod scene;

/// Least distance of a sampled pixel from every other stroke and from the code's marks and
/// label, px: the page's strokes are 3 px wide on a 720 px photo.
const CLEARANCE_PX: f64 = 8.0;
/// Room kept around the code's corners for its corner marks and payload label, px.
const CODE_MARGIN_PX: f64 = 60.0;
/// Largest difference of a sampled pixel's channel from the stroke's colour.
const COLOUR_TOL: i64 = 8;

/// The request the page sends for the site camera `fixed`, the site's marker size and the
/// least grasp probability `least`.
fn page_request(least: Option<f64>) -> Value {
    let mut request = json!({"camera": {"id": "fixed"}, "effort": "balanced"});
    if let Some(least) = least {
        request["min_grasp_probability"] = json!(least);
    }
    request
}

/// `POST /v1/pose/image` as the page sends it.
fn api_answer(server: &Server, file: &Path, request: &Value) -> ImageResponse {
    let form = reqwest::blocking::multipart::Form::new()
        .part(
            "image",
            reqwest::blocking::multipart::Part::bytes(std::fs::read(file).expect("the photo"))
                .file_name("product.png")
                .mime_str("image/png")
                .expect("a media type"),
        )
        .part(
            "request",
            reqwest::blocking::multipart::Part::text(request.to_string())
                .mime_str("application/json")
                .expect("a media type"),
        );
    let response = client()
        .post(server.url("/v1/pose/image"))
        .multipart(form)
        .send()
        .expect("the server answers");
    assert_eq!(response.status(), 200);
    response.json().expect("the API's JSON")
}

fn near(a: &Value, b: [f64; 2]) -> bool {
    let (u, v) = (a[0].as_f64().expect("u"), a[1].as_f64().expect("v"));
    (u - b[0]).hypot(v - b[1]) < PROJECTION_TOL_PX
}

/// Distance of `p` from the segment `a`-`b`, px.
fn distance_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length2 = dx * dx + dy * dy;
    let t = if length2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// A point of `segment` at least [`CLEARANCE_PX`] from every one of `others`, outside
/// `code_box` (left, top, right, bottom, px) and inside the `width` × `height` photo.
fn clear_point(
    segment: &Segment,
    others: &[[[f64; 2]; 2]],
    code_box: [f64; 4],
    (width, height): (f64, f64),
) -> Option<[f64; 2]> {
    (1..20)
        .map(|k| {
            let t = f64::from(k) / 20.0;
            [
                segment.from_px[0] + t * (segment.to_px[0] - segment.from_px[0]),
                segment.from_px[1] + t * (segment.to_px[1] - segment.from_px[1]),
            ]
        })
        .find(|p| {
            let inside_code = p[0] > code_box[0] - CODE_MARGIN_PX
                && p[0] < code_box[2] + CODE_MARGIN_PX
                && p[1] > code_box[1] - CODE_MARGIN_PX
                && p[1] < code_box[3] + CODE_MARGIN_PX;
            let on_photo = p[0] > CLEARANCE_PX
                && p[1] > CLEARANCE_PX
                && p[0] < width - CLEARANCE_PX
                && p[1] < height - CLEARANCE_PX;
            on_photo
                && !inside_code
                && others
                    .iter()
                    .all(|[a, b]| distance_to_segment(*p, *a, *b) > CLEARANCE_PX)
        })
}

/// The overlay canvas's pixel under the point `p` (pixel coordinates: the page draws the
/// pixel (u, v) at canvas (u + 0.5, v + 0.5)).
fn pixel(browser: &Browser, p: [f64; 2]) -> [i64; 3] {
    let rgba = browser.run(
        "return [...document.getElementById('overlay').getContext('2d')
           .getImageData(Math.floor(arguments[0] + 0.5), Math.floor(arguments[1] + 0.5), 1, 1).data];",
        &[json!(p[0]), json!(p[1])],
    );
    std::array::from_fn(|k| rgba[k].as_i64().expect("a channel"))
}

fn assert_colour(browser: &Browser, p: [f64; 2], colour: Rgb, what: &str) {
    let got = pixel(browser, p);
    let want = colour.0.map(i64::from);
    assert!(
        got.iter()
            .zip(want)
            .all(|(g, w)| (g - w).abs() <= COLOUR_TOL),
        "{what} at {p:?} is {got:?}, not {want:?}"
    );
}

fn product_photo() -> PathBuf {
    let dir = scratch_dir("browser-pick");
    let file = dir.join("product.png");
    std::fs::write(&file, scene::photo(&scene::flange_pose())).expect("the photo is written");
    file
}

#[test]
fn a_products_box_and_grasp_axes_are_drawn_where_the_server_draws_them_and_its_grasps_listed() {
    let _one = lock();
    let dir = scratch_dir("browser-pick");
    let site = dir.join("site.yaml");
    std::fs::write(&site, scene::SITE).expect("the site is written");
    let server = Server::start_with(&["--site", &site.display().to_string()]);
    let file = product_photo();

    // A least probability between the two grasps' makes one graspable and the other not.
    let plain = api_answer(&server, &file, &page_request(None));
    let object = plain.markers[0]
        .pose
        .as_ref()
        .and_then(|p| p.object.as_ref())
        .expect("the code names a product");
    let [p0, p1] = [0, 1].map(|k| {
        object.grasps[k]
            .within_tolerance_probability
            .expect("a probability")
    });
    assert!((p0 - p1).abs() > 1e-6, "the grasps are alike: {p0}, {p1}");
    let least = 0.5 * (p0 + p1);
    let api = api_answer(&server, &file, &page_request(Some(least)));

    let browser = Browser::start(DESKTOP.0, DESKTOP.1);
    open_page(&browser, &server);
    browser.click(&browser.find("#camera-mode-id"));
    browser.wait_for(
        "the site's cameras are read",
        "return document.getElementById('site-status').textContent.includes('in the site file');",
    );
    browser.type_into(&browser.find("#camera-id"), "fixed");
    browser.run(
        "document.getElementById('marker-size-mm').value = '';
         document.getElementById('min-grasp-probability').value = arguments[0];",
        &[json!(least)],
    );
    browser.type_into(&browser.find("#photo"), &file.display().to_string());
    browser.click(&browser.find("#send"));
    browser.wait_for(
        "the overlay is drawn",
        "return document.getElementById('overlay').dataset.state === 'drawn';",
    );

    // The page's answer is the API's, with one grasp of each kind.
    let page: ImageResponse = serde_json::from_str(
        browser
            .run(
                "return document.getElementById('raw-json').textContent;",
                &[],
            )
            .as_str()
            .expect("the raw JSON"),
    )
    .expect("the raw JSON parses");
    let marker = &page.markers[0];
    let object = marker
        .pose
        .as_ref()
        .and_then(|p| p.object.as_ref())
        .expect("the page's answer names the product");
    let api_object = api.markers[0]
        .pose
        .as_ref()
        .and_then(|p| p.object.as_ref())
        .expect("a product");
    assert_eq!(object.grasps.len(), 2);
    for (shown, api) in object.grasps.iter().zip(&api_object.grasps) {
        assert_eq!(
            (&shown.name, shown.graspable, &shown.reasons),
            (&api.name, api.graspable, &api.reasons)
        );
    }
    let graspable: Vec<bool> = object.grasps.iter().map(|g| g.graspable).collect();
    assert!(
        graspable.contains(&true) && graspable.contains(&false),
        "{graspable:?} at least {least}"
    );

    // The strokes: the server's overlay of the same answer, through the site's camera.
    let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a camera");
    let expected = object_segments(&camera, &plan_of(object));
    let drawn = browser.run(
        "return JSON.parse(document.getElementById('overlay').dataset.axes)[0].object;",
        &[],
    );
    let edges = drawn["edges"].as_array().expect("edges");
    let grasps = drawn["grasps"].as_array().expect("grasp axes");
    assert_eq!(edges.len() + grasps.len(), expected.len(), "{drawn}");
    assert_eq!(edges.len(), 12, "every edge is in front of the camera");
    for (k, (page, server)) in edges.iter().chain(grasps).zip(&expected).enumerate() {
        assert!(
            near(&page["from"], server.from_px) && near(&page["to"], server.to_px),
            "stroke {k}: the page draws {page}, the server {server:?}"
        );
    }
    for (axis, grasp) in grasps.iter().zip(&object.grasps) {
        let colour = if grasp.graspable {
            "#40ff40"
        } else {
            "#ff8000"
        };
        assert_eq!(axis["colour"], colour, "{}", grasp.name);
    }

    // The colours on the canvas, where no other stroke, mark or label covers them.
    let corners = marker.corners_px;
    let code_box = [
        corners.iter().map(|c| c[0]).fold(f64::INFINITY, f64::min),
        corners.iter().map(|c| c[1]).fold(f64::INFINITY, f64::min),
        corners
            .iter()
            .map(|c| c[0])
            .fold(f64::NEG_INFINITY, f64::max),
        corners
            .iter()
            .map(|c| c[1])
            .fold(f64::NEG_INFINITY, f64::max),
    ];
    let size = (page.image.width_px as f64, page.image.height_px as f64);
    let all: Vec<[[f64; 2]; 2]> = expected.iter().map(|s| [s.from_px, s.to_px]).collect();
    let mut box_sampled = false;
    for (k, segment) in expected.iter().enumerate() {
        let others: Vec<[[f64; 2]; 2]> = all
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != k)
            .map(|(_, s)| *s)
            .collect();
        let point = clear_point(segment, &others, code_box, size);
        if segment.colour == BOX {
            if let Some(p) = point {
                assert_colour(&browser, p, BOX, &format!("box edge {k}"));
                box_sampled = true;
            }
        } else {
            let p = point.unwrap_or_else(|| panic!("no clear point on grasp axis {segment:?}"));
            assert!(segment.colour == GRASPABLE || segment.colour == NOT_GRASPABLE);
            assert_colour(&browser, p, segment.colour, &format!("grasp axis {k}"));
        }
    }
    assert!(box_sampled, "no box edge was clear of the rest");

    // The grasps listed beside the code's numbers.
    let rows = browser.run(
        "return [...document.querySelectorAll('[data-marker-index=\"0\"] table.grasps tbody tr')].map(r =>
           ({name: r.querySelector('[data-field=\"name\"]').textContent,
             probability: Number(r.querySelector('[data-field=\"within_tolerance_probability\"]').dataset.value),
             graspable: r.querySelector('[data-field=\"graspable\"]').textContent,
             reasons: r.querySelector('[data-field=\"reasons\"]').dataset.codes}));",
        &[],
    );
    // WebDriver writes a whole number without its fraction: compare the numbers as f64.
    let mut rows = rows;
    for row in rows.as_array_mut().expect("rows") {
        row["probability"] = json!(row["probability"].as_f64());
    }
    let expected_rows: Vec<Value> = api_object
        .grasps
        .iter()
        .map(|g| {
            let reasons: Vec<String> = g
                .reasons
                .iter()
                .map(|r| {
                    serde_json::to_value(r)
                        .expect("a code")
                        .as_str()
                        .expect("text")
                        .to_owned()
                })
                .collect();
            json!({"name": g.name, "probability": g.within_tolerance_probability,
                   "graspable": if g.graspable { "yes" } else { "no" },
                   "reasons": reasons.join(" ")})
        })
        .collect();
    assert_eq!(rows, json!(expected_rows));
    let not_graspable = &api_object.grasps[graspable.iter().position(|g| !g).expect("one")];
    assert!(
        not_graspable
            .reasons
            .iter()
            .any(|r| serde_json::to_value(r).is_ok_and(|v| v == "below_probability")),
        "{:?}",
        not_graspable.reasons
    );
    assert_eq!(severe(&browser.log()), Vec::<&(String, String)>::new());
}

/// A pose of the answer's JSON as the site crate's.
fn rigid_of(
    pose: &qrpose::api::frames::FramePoseDto,
) -> qrpose_site::transform::PoseWithCovariance {
    let m = pose.rotation.matrix;
    qrpose_site::transform::PoseWithCovariance {
        pose: qrpose_site::transform::Rigid {
            rotation: nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_fn(
                |i, j| m[i][j],
            )),
            translation_mm: nalgebra::Vector3::new(
                pose.position_mm.x,
                pose.position_mm.y,
                pose.position_mm.z,
            ),
        },
        covariance: None,
    }
}

/// The product of the answer's JSON as the plan the server's overlay draws.
fn plan_of(object: &qrpose::api::pick::ObjectDto) -> qrpose_site::pick::ObjectPlan {
    qrpose_site::pick::ObjectPlan {
        rule: object.rule.clone(),
        box_mm: nalgebra::Vector3::from(object.box_mm),
        pose: rigid_of(&object.pose),
        pose_in_robot: None,
        grasps: object
            .grasps
            .iter()
            .map(|g| qrpose_site::pick::GraspPlan {
                name: g.name.clone(),
                kind: qrpose_site::objects::GraspKind::Suction,
                pose: rigid_of(&g.pose),
                pose_in_robot: None,
                pre_grasp_in_robot: None,
                width_mm: g.width_mm,
                within_tolerance_probability: g.within_tolerance_probability,
                graspable: g.graspable,
                reasons: Vec::new(),
            })
            .collect(),
    }
}
