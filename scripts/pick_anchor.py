#!/usr/bin/env python3
"""The picking anchor (docs/measurements/pick.md): what an off-the-shelf pipeline gets on a
rendered picking study, so that qrpose's picking can be measured against it on the same
photos.

For each photo of DIR (written by `qrpose-sim render --pick-study SEED --out DIR`, or
`--pick-scene`): zxing-cpp's four corners of the product's code, shifted by -0.5 px into
qrpose's pixel convention (docs/conventions.md, Pixels: zxing-cpp puts (0, 0) at the outer
corner of the top-left pixel), OpenCV's solvePnP with SOLVEPNP_IPPE_SQUARE (with the
camera's lens), composed with the photo's flange pose, the mount and the product's
T_object<-marker and T_object<-grasp: each grasp's pose in the robot frame, compared with the
truth. Prints the grasp position and rotation errors (median, p90, and how many are off by
more than 20 degrees: the mirror poses of the planar ambiguity), for the picks and the
approach, and a check of the corner order and offset against the truth.

    scripts/pick_anchor.sh DIR       # makes the venv (target/pick-anchor-venv), then this
    python3 scripts/pick_anchor.py DIR [--json OUT.json]

Corner order: zxing-cpp's position is top_left, top_right, bottom_right, bottom_left of the
symbol, which is qrpose's "qr" order (TL, TR, BR, BL = P3, P2, P1, P4); the truth's
`corners_px` are in the same order. IPPE_SQUARE wants the object points
(-l/2, l/2), (l/2, l/2), (l/2, -l/2), (-l/2, -l/2) in that order: qrpose's centred marker
frame (x right, y down the symbol, z into the face) turned half a turn about x, so the
pose it returns is multiplied by diag(1, -1, -1) on the right.
"""
import argparse, json, sys
from importlib.metadata import version
from pathlib import Path

import cv2
import numpy as np
import zxingcpp

from rigid import angle_deg, rigid

MIRROR_DEG = 20.0
ZXING_SHIFT_PX = -0.5
# T_F'<-marker: IPPE_SQUARE's square frame from qrpose's centred marker frame.
FLIP = np.diag([1.0, -1.0, -1.0])


def pct(values, q):
    if not values:
        return float("nan")
    v = sorted(values)
    return v[round((len(v) - 1) * q)]


def camera_model(cam):
    k = np.array([[cam["fx_px"], 0, cam["cx_px"]], [0, cam["fy_px"], cam["cy_px"]], [0, 0, 1.0]])
    lens = cam.get("distortion")
    if lens is None:
        return k, None
    if lens["model"] != "plumb_bob" and lens["model"] != "rational_polynomial":
        sys.exit(f"lens model {lens['model']} is not one solvePnP takes")
    return k, np.array(lens["coefficients"], dtype=np.float64)


def marker_in_camera(corners_qr, size_mm, k, dist):
    h = size_mm / 2
    obj = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], dtype=np.float64)
    ok, rvec, tvec = cv2.solvePnP(obj, np.asarray(corners_qr, dtype=np.float64), k, dist,
                                  flags=cv2.SOLVEPNP_IPPE_SQUARE)
    if not ok:
        return None
    r, _ = cv2.Rodrigues(rvec)
    m = np.eye(4)
    m[:3, :3] = r @ FLIP
    m[:3, 3] = tvec.ravel()
    return m


def zxing_codes(gray):
    out = {}
    for b in zxingcpp.read_barcodes(gray, formats=zxingcpp.BarcodeFormat.QRCode):
        if not b.valid:
            continue
        p = b.position
        out[b.text] = np.array([[p.top_left.x, p.top_left.y], [p.top_right.x, p.top_right.y],
                                [p.bottom_right.x, p.bottom_right.y],
                                [p.bottom_left.x, p.bottom_left.y]], dtype=np.float64)
    return out


def best_cyclic_shift(found, truth):
    """The rotation k of the found corners (and whether reversed) closest to the truth."""
    best = None
    for reverse in (False, True):
        seq = found[::-1] if reverse else found
        for k in range(4):
            d = float(np.linalg.norm(np.roll(seq, -k, axis=0) - truth, axis=1).mean())
            if best is None or d < best[0]:
                best = (d, k, reverse)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", type=Path)
    ap.add_argument("--json", type=Path, help="also write every grasp's errors here")
    ap.add_argument("--truth-corners", action="store_true",
                    help="use the truth's corners instead of zxing-cpp's: a check of the chain "
                         "(the errors must vanish)")
    args = ap.parse_args()
    truth = json.loads((args.dir / "truth.json").read_text())
    scene = truth["scene"]
    k, dist = camera_model(scene["camera"])
    mount = rigid(scene["mount"])
    products = scene["products"]

    rows = []
    photos = {"pick": 0, "approach": 0}
    read = {"pick": 0, "approach": 0}
    offsets, order_shifts = [], 0
    for photo in truth["photos"]:
        group = "approach" if photo["label"].startswith("approach") else "pick"
        gray = cv2.imread(str(args.dir / photo["image"]), cv2.IMREAD_GRAYSCALE)
        codes = {} if args.truth_corners else zxing_codes(gray)
        flange = rigid(photo["flange_pose"])
        for seen in photo["products"]:
            photos[group] += 1
            product = products[seen["product"]]
            true_corners = np.array(seen["code"]["corners_px"])
            if args.truth_corners:
                corners = true_corners
            else:
                corners = codes.get(product["payload"])
                if corners is None:
                    continue
                _, shift, reverse = best_cyclic_shift(corners, true_corners)
                order_shifts += int(shift != 0 or reverse)
                corners = corners + ZXING_SHIFT_PX
                offsets.append((corners - true_corners).mean(axis=0))
            read[group] += 1
            m = marker_in_camera(corners, product["code_size_mm"], k, dist)
            if m is None:
                continue
            marker_in_robot = flange @ mount @ m
            object_in_robot = marker_in_robot @ np.linalg.inv(rigid(product["marker_in_object"]))
            true_marker = rigid(seen["marker_in_camera"])
            marker_rot = angle_deg(m[:3, :3], true_marker[:3, :3])
            for g, gt in zip(product["grasps"], seen["grasps"]):
                est = object_in_robot @ rigid(g["pose"])
                true = rigid(gt["in_robot"])
                rows.append({
                    "photo": photo["label"], "group": group, "payload": product["payload"],
                    "grasp": g["name"],
                    "distance_mm": float(np.linalg.norm(true_marker[:3, 3])),
                    "position_error_mm": float(np.linalg.norm(est[:3, 3] - true[:3, 3])),
                    "rotation_error_deg": angle_deg(est[:3, :3], true[:3, :3]),
                    "marker_rotation_error_deg": marker_rot,
                })

    mean_offset = np.mean(offsets, axis=0) if offsets else [float("nan")] * 2
    source = "the truth's corners" if args.truth_corners else f"zxing-cpp {version('zxing-cpp')}"
    print(f"# pick anchor: {source} + OpenCV {cv2.__version__} solvePnP IPPE_SQUARE on {args.dir}")
    print(f"corner order: {order_shifts} of {len(offsets)} reads needed a shift or reversal to "
          f"match the truth; mean corner offset after {ZXING_SHIFT_PX:+.1f} px: "
          f"({mean_offset[0]:+.3f}, {mean_offset[1]:+.3f}) px")
    print()
    print("| photos | codes in view | read | grasps | position error median / p90 mm "
          "| rotation error median / p90 ° | grasps off > 20° |")
    print("|---|---|---|---|---|---|---|")
    for group in ("pick", "approach"):
        g = [r for r in rows if r["group"] == group]
        pos = [r["position_error_mm"] for r in g]
        rot = [r["rotation_error_deg"] for r in g]
        mirrored = sum(1 for r in rot if r > MIRROR_DEG)
        print(f"| {group} | {photos[group]} | {read[group]} | {len(g)} | "
              f"{pct(pos, .5):.2f} / {pct(pos, .9):.2f} | {pct(rot, .5):.2f} / {pct(rot, .9):.2f} | "
              f"{mirrored} ({100 * mirrored / max(len(g), 1):.1f} %) |")
    print()
    print("Picks by product (prefix):")
    print("| product | grasps | position median / p90 mm | rotation median / p90 ° | off > 20° |")
    print("|---|---|---|---|---|")
    for prefix in sorted({r["payload"][:6] for r in rows if r["group"] == "pick"}):
        g = [r for r in rows if r["group"] == "pick" and r["payload"].startswith(prefix)]
        pos = [r["position_error_mm"] for r in g]
        rot = [r["rotation_error_deg"] for r in g]
        print(f"| {prefix} | {len(g)} | {pct(pos, .5):.2f} / {pct(pos, .9):.2f} | "
              f"{pct(rot, .5):.2f} / {pct(rot, .9):.2f} | {sum(1 for r in rot if r > MIRROR_DEG)} |")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
