//! A picking study's scene (docs/rendering.md, Picking scenes): N picks of three products
//! (different boxes, codes on different faces, grasps 50-150 mm from the code) seen from a
//! wrist camera 0.25-0.9 m from the code, tilted up to 50° off the code's normal, the code
//! anywhere in the central part of the image, any roll; and an approach: the arm moving
//! from 0.8 m to 0.25 m of a product in [`APPROACH_FRAMES`] frames. Every pick has its own
//! product instance, [`PRODUCT_SPACING_MM`] from the next, so that each photo shows one
//! product. The same seed gives the same scene. [`study_site_yaml`] writes the matching site
//! file (docs/site.md): the camera on the flange, the code sizes, the objects with grasps.

use super::{
    CameraSpec, GraspSpec, LensModelName, LensSpec, PhotoSpec, PickScene, PickSceneError, PoseSpec,
    ProductSpec, products_in_view,
};
use crate::render::DEFAULT_QUIET_ZONE_MODULES;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::fmt::Write;

/// Frames of the approach sequence.
pub const APPROACH_FRAMES: usize = 20;
/// Distance between product instances, mm (a pick's camera must see its product alone).
pub const PRODUCT_SPACING_MM: f64 = 10000.0;
/// Camera-to-code distance of a pick, mm.
pub const PICK_DISTANCE_MM: [f64; 2] = [250.0, 900.0];
/// Largest angle between the line of sight and the code's normal of a pick, degrees.
pub const MAX_TILT_DEG: f64 = 50.0;
/// The approach's start and end distance from the code, mm.
pub const APPROACH_DISTANCE_MM: [f64; 2] = [800.0, 250.0];
/// Draws of a pick's camera before giving up on an instance (the code must be in view).
const MAX_DRAWS: usize = 200;

/// A grasp of a product type as the site file writes it.
#[derive(Debug, Clone, Copy)]
pub struct GraspType {
    /// Its name.
    pub name: &'static str,
    /// `Some(width)`: parallel; `None`: suction.
    pub width_mm: Option<f64>,
    /// T_object←grasp: translation, mm.
    pub translation_mm: [f64; 3],
    /// T_object←grasp: the grasp frame's axes in object axes (columns x, y, z).
    pub axes: [[f64; 3]; 3],
    /// Tolerance: position, mm.
    pub position_mm: f64,
    /// Tolerance: rotation, degrees.
    pub rotation_deg: f64,
    /// Pre-grasp distance, mm.
    pub approach_mm: f64,
}

/// A product type of the study.
#[derive(Debug, Clone, Copy)]
pub struct ProductType {
    /// The payload prefix (`SKU-A-`).
    pub prefix: &'static str,
    /// The box, mm.
    pub box_mm: [f64; 3],
    /// The code's side, mm.
    pub code_size_mm: f64,
    /// T_object←marker: the code's centre on a face, mm.
    pub code_translation_mm: [f64; 3],
    /// T_object←marker: the marker's axes in object axes (columns x, y, z; z into the face).
    pub code_axes: [[f64; 3]; 3],
    /// The grasps.
    pub grasps: [GraspType; 2],
}

/// Down the object's −z, the grasp's x along the object's x: a tool coming from above.
const FROM_ABOVE: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];

/// The three products: a code on the top, on the +x side and on the −y side.
pub const PRODUCT_TYPES: [ProductType; 3] = [
    ProductType {
        prefix: "SKU-A-",
        box_mm: [300.0, 200.0, 150.0],
        code_size_mm: 60.0,
        code_translation_mm: [60.0, 40.0, 75.0],
        // On the top face: x along the box's x, y along −y, z down into the box.
        code_axes: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
        grasps: [
            GraspType {
                name: "top",
                width_mm: None,
                translation_mm: [0.0, 0.0, 75.0],
                axes: FROM_ABOVE,
                position_mm: 5.0,
                rotation_deg: 3.0,
                approach_mm: 80.0,
            },
            GraspType {
                name: "across",
                width_mm: Some(220.0),
                translation_mm: [-20.0, 0.0, 40.0],
                axes: FROM_ABOVE,
                position_mm: 4.0,
                rotation_deg: 2.0,
                approach_mm: 120.0,
            },
        ],
    },
    ProductType {
        prefix: "SKU-B-",
        box_mm: [200.0, 150.0, 100.0],
        code_size_mm: 40.0,
        code_translation_mm: [100.0, 0.0, 0.0],
        // On the +x face, upright: x along the box's y, y down (−z), z into the box (−x).
        code_axes: [[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]],
        grasps: [
            GraspType {
                name: "top",
                width_mm: None,
                translation_mm: [0.0, 0.0, 50.0],
                axes: FROM_ABOVE,
                position_mm: 5.0,
                rotation_deg: 3.0,
                approach_mm: 80.0,
            },
            GraspType {
                name: "across",
                width_mm: Some(170.0),
                translation_mm: [40.0, 0.0, 20.0],
                axes: FROM_ABOVE,
                position_mm: 4.0,
                rotation_deg: 2.0,
                approach_mm: 100.0,
            },
        ],
    },
    ProductType {
        prefix: "SKU-C-",
        box_mm: [400.0, 300.0, 250.0],
        code_size_mm: 80.0,
        code_translation_mm: [-60.0, -150.0, 60.0],
        // On the −y face, upright: x along the box's x, y down (−z), z into the box (+y).
        code_axes: [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
        grasps: [
            GraspType {
                name: "top",
                width_mm: None,
                translation_mm: [-60.0, -60.0, 125.0],
                axes: FROM_ABOVE,
                position_mm: 6.0,
                rotation_deg: 3.0,
                approach_mm: 100.0,
            },
            GraspType {
                name: "rim",
                width_mm: Some(320.0),
                translation_mm: [0.0, -100.0, 100.0],
                axes: FROM_ABOVE,
                position_mm: 5.0,
                rotation_deg: 2.0,
                approach_mm: 150.0,
            },
        ],
    },
];

fn rotation_from_axes(axes: &[[f64; 3]; 3]) -> Rotation3<f64> {
    let m = Matrix3::from_columns(&axes.map(Vector3::from));
    Rotation3::from_matrix(&m)
}

fn iso(rotation: Rotation3<f64>, translation_mm: Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(translation_mm),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

/// T_object←marker of a product type.
pub fn marker_in_object(t: &ProductType) -> Isometry3<f64> {
    iso(
        rotation_from_axes(&t.code_axes),
        Vector3::from(t.code_translation_mm),
    )
}

/// T_object←grasp of a grasp type.
pub fn grasp_in_object(g: &GraspType) -> Isometry3<f64> {
    iso(rotation_from_axes(&g.axes), Vector3::from(g.translation_mm))
}

/// The study's camera: 1280 × 960, fx = fy = 1100 px, mild barrel distortion.
pub fn study_camera() -> CameraSpec {
    CameraSpec {
        fx_px: 1100.0,
        fy_px: 1100.0,
        cx_px: 639.5,
        cy_px: 479.5,
        width_px: 1280,
        height_px: 960,
        distortion: Some(LensSpec {
            model: LensModelName::PlumbBob,
            coefficients: vec![-0.05, 0.012, 0.0, 0.0, 0.0],
        }),
    }
}

/// The study's mount T_flange←camera: 60 mm off the flange axis, 45 mm forward, turned
/// 90° about it and tilted 3°.
pub fn study_mount() -> Isometry3<f64> {
    iso(
        Rotation3::from_euler_angles(0.0, 3f64.to_radians(), std::f64::consts::FRAC_PI_2),
        Vector3::new(30.0, -60.0, 45.0),
    )
}

/// T_robot←camera looking from `eye` at `target`, turned `roll` rad about the line of sight.
fn look_at(eye: &Vector3<f64>, target: &Vector3<f64>, roll: f64) -> Isometry3<f64> {
    let forward = target - eye;
    let up = if forward.cross(&Vector3::z()).norm() > 1e-6 * forward.norm() {
        Vector3::z()
    } else {
        Vector3::x()
    };
    // face_towards maps z to `forward`, y to `up` made orthogonal.
    let r = UnitQuaternion::face_towards(&forward, &up)
        * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll);
    Isometry3::from_parts(Translation3::from(*eye), r)
}

/// A unit vector within `max_tilt` rad of `normal`, uniform in azimuth and in angle.
fn tilted(normal: &Vector3<f64>, tilt: f64, azimuth: f64) -> Vector3<f64> {
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let a = normal.cross(&helper).normalize();
    let axis = Rotation3::from_axis_angle(&Unit::new_normalize(*normal), azimuth) * a;
    Rotation3::from_axis_angle(&Unit::new_normalize(axis), tilt) * normal
}

/// The product instance of `type_index` at instance `slot`, turned `yaw` rad.
fn product(type_index: usize, slot: usize, yaw: f64, serial: usize) -> ProductSpec {
    let t = &PRODUCT_TYPES[type_index % PRODUCT_TYPES.len()];
    let position = Vector3::new(
        PRODUCT_SPACING_MM * (slot % 25) as f64,
        PRODUCT_SPACING_MM * (slot / 25) as f64,
        t.box_mm[2] / 2.0,
    );
    ProductSpec {
        payload: format!("{}{serial:04}", t.prefix),
        code_size_mm: t.code_size_mm,
        box_mm: t.box_mm,
        object_in_robot: PoseSpec::from_isometry(&iso(
            Rotation3::from_axis_angle(&Vector3::z_axis(), yaw),
            position,
        )),
        marker_in_object: PoseSpec::from_isometry(&marker_in_object(t)),
        grasps: t
            .grasps
            .iter()
            .map(|g| GraspSpec {
                name: g.name.to_owned(),
                pose: PoseSpec::from_isometry(&grasp_in_object(g)),
            })
            .collect(),
    }
}

/// The code's centre and outward normal (towards a viewer) in the robot frame.
fn code_centre_and_normal(p: &ProductSpec) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let marker = p.object_in_robot.to_isometry()? * p.marker_in_object.to_isometry()?;
    Some((marker.translation.vector, -(marker.rotation * Vector3::z())))
}

/// A photo's flange pose for a camera at `camera_in_robot`.
fn flange_for(camera_in_robot: &Isometry3<f64>) -> PoseSpec {
    PoseSpec::from_isometry(&(camera_in_robot * study_mount().inverse()))
}

/// Whether a camera at `camera_in_robot` sees product `index` of `scene` and no other.
fn sees_only(
    scene: &PickScene,
    index: usize,
    camera_in_robot: &Isometry3<f64>,
) -> Result<bool, PickSceneError> {
    let seen = products_in_view(scene, camera_in_robot, DEFAULT_QUIET_ZONE_MODULES)?;
    Ok(seen == [index])
}

/// A random camera for product `index` of `scene` whose code it sees, `None` after
/// [`MAX_DRAWS`] misses.
fn pick_camera(
    scene: &PickScene,
    index: usize,
    rng: &mut StdRng,
) -> Result<Option<Isometry3<f64>>, PickSceneError> {
    let Some((centre, normal)) = code_centre_and_normal(&scene.products[index]) else {
        return Ok(None);
    };
    let half_fov = (f64::from(scene.camera.width_px) / 2.0 / scene.camera.fx_px).atan();
    for _ in 0..MAX_DRAWS {
        let distance = rng.gen_range(PICK_DISTANCE_MM[0]..PICK_DISTANCE_MM[1]);
        let tilt = rng.gen_range(0.0..MAX_TILT_DEG).to_radians();
        let azimuth = rng.gen_range(0.0..std::f64::consts::TAU);
        let eye = centre + distance * tilted(&normal, tilt, azimuth);
        // Aim beside the code so that it lands anywhere in the central part of the image.
        let off = distance * (0.6 * half_fov).tan();
        let aim = centre
            + Vector3::new(
                rng.gen_range(-off..off),
                rng.gen_range(-off..off),
                rng.gen_range(-off..off),
            );
        let roll = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
        let camera = look_at(&eye, &aim, roll);
        if sees_only(scene, index, &camera)? {
            return Ok(Some(camera));
        }
    }
    Ok(None)
}

/// The study's scene: `picks` picks (`pick-0000` …) then the approach (`approach-00` …),
/// drawn from `seed`.
///
/// # Errors
/// [`PickSceneError::NoView`] when no camera drawn for a pick saw its product alone (not
/// seen with the built-in products: they are 10 m apart); others only if the built-in
/// camera or products were refused.
pub fn study_scene(seed: u64, picks: usize) -> Result<PickScene, PickSceneError> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut scene = PickScene {
        camera: study_camera(),
        mount: PoseSpec::from_isometry(&study_mount()),
        products: Vec::with_capacity(picks + 1),
        photos: Vec::with_capacity(picks + APPROACH_FRAMES),
    };
    // Every product first, so that each pick's camera is checked against all of them.
    for i in 0..=picks {
        let yaw = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
        // The last one, of type A, is the approach's.
        let kind = if i == picks {
            0
        } else {
            i % PRODUCT_TYPES.len()
        };
        scene.products.push(product(kind, i, yaw, i));
    }
    for i in 0..picks {
        let camera =
            pick_camera(&scene, i, &mut rng)?.ok_or(PickSceneError::NoView { product: i })?;
        scene.photos.push(PhotoSpec {
            label: format!("pick-{i:04}"),
            flange_pose: flange_for(&camera),
        });
    }
    // The approach: product type A, the camera sliding in from 0.8 m to 0.25 m on a line
    // 20° off the code's normal, aimed at the code, with a slow roll.
    let index = picks;
    if let Some((centre, normal)) = code_centre_and_normal(&scene.products[index]) {
        let direction = tilted(
            &normal,
            20f64.to_radians(),
            rng.gen_range(0.0..std::f64::consts::TAU),
        );
        for k in 0..APPROACH_FRAMES {
            let f = k as f64 / (APPROACH_FRAMES - 1) as f64;
            let distance =
                APPROACH_DISTANCE_MM[0] + f * (APPROACH_DISTANCE_MM[1] - APPROACH_DISTANCE_MM[0]);
            let camera = look_at(&(centre + distance * direction), &centre, 0.3 + 0.4 * f);
            scene.photos.push(PhotoSpec {
                label: format!("approach-{k:02}"),
                flange_pose: flange_for(&camera),
            });
        }
    }
    Ok(scene)
}

/// The site file for a study's scene (docs/site.md): camera `wrist` on the flange with the
/// study's intrinsics, lens and mount, each product type's code size, and its object rule
/// with the grasps.
pub fn study_site_yaml(scene: &PickScene) -> String {
    let c = &scene.camera;
    let m = &scene.mount;
    let mut y = String::new();
    let _ = writeln!(y, "cameras:\n  wrist:");
    let _ = writeln!(
        y,
        "    intrinsics: {{fx_px: {}, fy_px: {}, cx_px: {}, cy_px: {}}}",
        c.fx_px, c.fy_px, c.cx_px, c.cy_px
    );
    if let Some(lens) = &c.distortion {
        let model = match lens.model {
            LensModelName::PlumbBob => "plumb_bob",
            LensModelName::RationalPolynomial => "rational_polynomial",
            LensModelName::Equidistant => "equidistant",
        };
        let _ = writeln!(
            y,
            "    distortion: {{model: {model}, coefficients: {:?}}}",
            lens.coefficients
        );
    }
    let _ = writeln!(
        y,
        "    mount:\n      parent: flange\n      translation_mm: {:?}\n      quaternion_wxyz: {:?}",
        m.translation_mm, m.quaternion_wxyz
    );
    let _ = writeln!(y, "markers:\n  sizes:");
    for t in &PRODUCT_TYPES {
        let _ = writeln!(
            y,
            "    - {{prefix: \"{}\", size_mm: {}}}",
            t.prefix, t.code_size_mm
        );
    }
    let _ = writeln!(y, "objects:");
    for t in &PRODUCT_TYPES {
        let code = PoseSpec::from_isometry(&marker_in_object(t));
        let _ = writeln!(
            y,
            "  - prefix: \"{}\"\n    box_mm: {:?}",
            t.prefix, t.box_mm
        );
        let _ = writeln!(
            y,
            "    code: {{translation_mm: {:?}, quaternion_wxyz: {:?}}}\n    grasps:",
            code.translation_mm, code.quaternion_wxyz
        );
        for g in &t.grasps {
            let pose = PoseSpec::from_isometry(&grasp_in_object(g));
            let _ = writeln!(y, "      - name: {}", g.name);
            match g.width_mm {
                Some(w) => {
                    let _ = writeln!(y, "        kind: parallel\n        width_mm: {w}");
                }
                None => {
                    let _ = writeln!(y, "        kind: suction");
                }
            }
            let _ = writeln!(
                y,
                "        translation_mm: {:?}\n        quaternion_wxyz: {:?}\n        tolerance: {{position_mm: {}, rotation_deg: {}}}\n        approach_mm: {}",
                pose.translation_mm,
                pose.quaternion_wxyz,
                g.position_mm,
                g.rotation_deg,
                g.approach_mm
            );
        }
    }
    y
}
