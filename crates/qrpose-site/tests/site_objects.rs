//! The site file's `objects:` rules and camera mounts on the flange: good files resolve,
//! and every mistake is refused with the field's path and line.

use qrpose_site::{GraspKind, MountParent, Site, SiteError};
use std::path::Path;

const GOOD: &str = "\
cameras:
  wrist:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}
    mount:
      parent: flange
      translation_mm: [0, 60, 40]
      quaternion_wxyz: [1, 0, 0, 0]
      std: {rotation_deg: [0.1, 0.1, 0.2], translation_mm: [0.5, 0.5, 1]}
  fixed:
    intrinsics: {fx_px: 800, fy_px: 800, cx_px: 320, cy_px: 240}
    mount: {translation_mm: [250, 0, 400], quaternion_wxyz: [0.5, -0.5, 0.5, -0.5]}
objects:
  - prefix: \"SKU-\"
    box_mm: [200, 150, 100]
    code: {translation_mm: [0, 0, 50], quaternion_wxyz: [0, 1, 0, 0]}
    grasps:
      - name: top
        kind: suction
        translation_mm: [0, 0, 50]
        quaternion_wxyz: [0, 1, 0, 0]
        tolerance: {position_mm: 5, rotation_deg: 3}
        approach_mm: 80
      - name: sides
        kind: parallel
        translation_mm: [0, 0, 0]
        quaternion_wxyz: [0, 1, 0, 0]
        width_mm: 150
        tolerance: {position_mm: 4, rotation_deg: 2}
  - payload: \"SKU-9\"
    box_mm: [100, 100, 100]
    code: {translation_mm: [0, 0, 50], quaternion_wxyz: [1, 0, 0, 0]}
    grasps:
      - {name: top, kind: suction, translation_mm: [0, 0, 50], quaternion_wxyz: [1, 0, 0, 0],
         tolerance: {position_mm: 5, rotation_deg: 3}}
  - pattern: \"^BIN-[0-9]+$\"
    box_mm: [600, 400, 300]
    code: {translation_mm: [300, 0, 0], quaternion_wxyz: [0.5, 0.5, 0.5, 0.5]}
    grasps:
      - {name: rim, kind: parallel, width_mm: 420, translation_mm: [0, 0, 150],
         quaternion_wxyz: [0, 1, 0, 0], tolerance: {position_mm: 10, rotation_deg: 5}}
";

fn parse(text: &str) -> Result<Site, SiteError> {
    Site::parse(text, Path::new("/sites/objects.yaml"))
}

fn good_with(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from}");
    GOOD.replacen(from, to, 1)
}

#[test]
fn objects_resolve_and_the_first_matching_rule_wins() {
    let site = parse(GOOD).expect("a valid site");
    let (label, rule) = site.object_for("SKU-9").expect("matched");
    // The prefix rule comes first: it shadows the exact one, as size rules do.
    assert_eq!(label, "prefix:SKU-");
    assert_eq!(rule.box_mm, nalgebra::Vector3::new(200.0, 150.0, 100.0));
    assert_eq!(rule.grasps.len(), 2);
    assert_eq!(rule.grasps[0].kind, GraspKind::Suction);
    assert_eq!(rule.grasps[0].approach_mm, Some(80.0));
    assert_eq!(rule.grasps[1].kind, GraspKind::Parallel { width_mm: 150.0 });
    assert!((rule.grasps[1].tolerance.rotation_rad - 2f64.to_radians()).abs() < 1e-15);
    // [0, 1, 0, 0]: a half turn about x; the code faces up out of the box's top.
    let normal = rule.marker_in_object.rotation * nalgebra::Vector3::z();
    assert!((normal + nalgebra::Vector3::z()).norm() < 1e-12, "{normal}");
    let (label, _) = site.object_for("BIN-12").expect("matched");
    assert_eq!(label, "pattern:^BIN-[0-9]+$");
    assert!(site.object_for("BIN-12a").is_none());
    assert!(site.object_for("TOTE-1").is_none());
    assert_eq!(site.objects().len(), 3);
}

#[test]
fn a_flange_mount_has_no_robot_mount_until_a_flange_pose_is_given() {
    let site = parse(GOOD).expect("a valid site");
    let wrist = site.camera("wrist").expect("wrist");
    assert!(
        wrist.mount.is_none(),
        "a flange mount is not T_robot<-camera"
    );
    let mount = wrist.camera_mount.expect("a mount");
    assert_eq!(mount.parent, MountParent::Flange);
    let std = mount.std.expect("a std");
    assert!((std.rotation_rad.z - 0.2f64.to_radians()).abs() < 1e-15);
    assert!(mount.camera_in_robot(None).is_none());
    let flange = qrpose_site::transform::Rigid::identity();
    let in_robot = mount
        .camera_in_robot(Some(&flange))
        .expect("with a flange pose");
    assert_eq!(
        in_robot.pose.translation_mm,
        nalgebra::Vector3::new(0.0, 60.0, 40.0)
    );
    // The default parent is the robot: today's meaning.
    let fixed = site.camera("fixed").expect("fixed");
    assert_eq!(
        fixed.camera_mount.map(|m| m.parent),
        Some(MountParent::Robot)
    );
    assert_eq!(fixed.mount, fixed.camera_mount.map(|m| m.pose));
}

#[test]
fn every_object_mistake_names_its_field_and_line() {
    let cases: Vec<(&str, String, usize, &str)> = vec![
        (
            "unknown grasp kind",
            good_with("kind: suction", "kind: vacuum"),
            18,
            "objects[0].grasps[0].kind: unknown variant `vacuum`",
        ),
        (
            "rule without grasps",
            good_with(
                "    grasps:\n      - {name: top, kind: suction, translation_mm: [0, 0, 50], quaternion_wxyz: [1, 0, 0, 0],\n         tolerance: {position_mm: 5, rotation_deg: 3}}\n",
                "    grasps: []\n",
            ),
            29,
            "objects[1]: grasps: an object rule needs at least one grasp",
        ),
        (
            "duplicate grasp names",
            good_with("name: sides", "name: top"),
            13,
            "objects[0]: grasps: the name \"top\" is used twice",
        ),
        (
            "non-unit quaternion",
            good_with(
                "code: {translation_mm: [0, 0, 50], quaternion_wxyz: [0, 1, 0, 0]}",
                "code: {translation_mm: [0, 0, 50], quaternion_wxyz: [0, 1.01, 0, 0]}",
            ),
            15,
            "objects[0].code.quaternion_wxyz: quaternion_wxyz [0, 1.01, 0, 0] is not a unit quaternion",
        ),
        (
            "parallel grasp without width",
            good_with("        width_mm: 150\n", ""),
            23,
            "objects[0].grasps[1]: grasp \"sides\": width_mm is required for a parallel grasp",
        ),
        (
            "suction grasp with a width",
            good_with("        approach_mm: 80\n", "        width_mm: 80\n"),
            17,
            "objects[0].grasps[0]: grasp \"top\": width_mm is only for a parallel grasp",
        ),
        (
            "zero position tolerance",
            good_with("position_mm: 4", "position_mm: 0"),
            23,
            "objects[0].grasps[1]: tolerance.position_mm must be a positive number, got 0",
        ),
        (
            "negative approach",
            good_with("approach_mm: 80", "approach_mm: -1"),
            17,
            "objects[0].grasps[0]: approach_mm must be a number >= 0, got -1",
        ),
        (
            "box with a zero side",
            good_with("[200, 150, 100]", "[200, 0, 100]"),
            14,
            "objects[0].box_mm: box_mm must be three positive numbers",
        ),
        (
            "two matchers",
            good_with(
                "  - payload: \"SKU-9\"\n",
                "  - payload: \"SKU-9\"\n    prefix: \"X\"\n",
            ),
            29,
            "objects[1]: an object rule has exactly one of payload, prefix and pattern",
        ),
        (
            "no matcher",
            good_with("  - payload: \"SKU-9\"\n    box_mm", "  - box_mm"),
            29,
            "objects[1]: an object rule needs one of payload, prefix and pattern",
        ),
        (
            "grasp without a tolerance",
            good_with("        tolerance: {position_mm: 5, rotation_deg: 3}\n", ""),
            17,
            "objects[0].grasps[0]: missing field `tolerance`",
        ),
        (
            "unknown object key",
            good_with(
                "    box_mm: [200, 150, 100]\n",
                "    box_mm: [200, 150, 100]\n    weight_kg: 2\n",
            ),
            13,
            "objects[0]: unknown field `weight_kg`",
        ),
        (
            "unknown mount parent",
            good_with("parent: flange", "parent: tool"),
            5,
            "cameras.wrist.mount.parent: unknown variant `tool`",
        ),
        (
            "negative mount std",
            good_with(
                "rotation_deg: [0.1, 0.1, 0.2]",
                "rotation_deg: [0.1, -0.1, 0.2]",
            ),
            8,
            "cameras.wrist.mount.std.rotation_deg: a standard deviation must be three finite numbers >= 0",
        ),
        (
            "duplicate object rule",
            good_with("payload: \"SKU-9\"", "prefix: \"SKU-\""),
            29,
            "objects: prefix \"SKU-\" is listed twice",
        ),
    ];
    let mut failures = Vec::new();
    for (name, text, line, needle) in cases {
        let err = parse(&text).map(|_| ()).expect_err(name);
        let shown = err.to_string();
        if !shown.contains(needle) || err.line != Some(line) {
            failures.push(format!("{name} (line {line}, {needle:?}): {shown}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
