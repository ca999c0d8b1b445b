#!/usr/bin/env python3
"""Hand-eye calibration against ground truth: qrpose against OpenCV's cv2.calibrateHandEye
on the very same rendered photos and reported flange poses (docs/measurements/hand-eye.md).

    scripts/handeye_study.sh                 # builds, renders, runs everything (20 seeds)
    python3 scripts/handeye_study.py DIR     # the OpenCV side and the tables, on DIR

DIR holds the sessions of crates/qrpose-sim/examples/handeye_study.rs (DIR/<setup>-<seed>/
session.json with the truth, the reported flange poses of each noise level and qrpose's
answers; photo-NNN.jpg the code, board-NNN.jpg a 10 x 10-square checkerboard of the same
120 mm at the same pose). For each session and noise level, OpenCV's calibrateHandEye with
each of its five methods (TSAI, PARK, HORAUD, ANDREFF, DANIILIDIS) is fed the target's pose
in each photo from two anchors:

* zxing: zxing-cpp's four corners of the code (moved by -0.5 px into the pixel-centre
  convention, see scripts/accuracy_images.py), solvePnP SOLVEPNP_IPPE_SQUARE with the true
  intrinsics and lens;
* checkerboard: findChessboardCornersSB (9 x 9 inner corners, NORMALIZE_IMAGE | ACCURACY),
  solvePnP SOLVEPNP_ITERATIVE with the true intrinsics and lens. A 10 x 10 board looks the
  same turned by 180 deg; the detected corners are labelled by the truth's nearest
  labelling (as an asymmetric board would label them), which moves no corner.

Photos where an anchor finds nothing are left out of that anchor's calibration (as qrpose
leaves out photos whose code it does not read). Eye-to-hand: the inverted robot poses are
passed, as OpenCV's documentation says. Errors: the mount's rotation (deg) and translation
(mm) against the truth. OpenCV's best-of-five: per anchor, setup and noise level, the method
with the lowest median translation error over the sessions (named in the table).
"""
import json, math, sys
from pathlib import Path

import cv2
import numpy as np

from rigid import angle_deg, rigid

METHODS = {
    "TSAI": cv2.CALIB_HAND_EYE_TSAI,
    "PARK": cv2.CALIB_HAND_EYE_PARK,
    "HORAUD": cv2.CALIB_HAND_EYE_HORAUD,
    "ANDREFF": cv2.CALIB_HAND_EYE_ANDREFF,
    "DANIILIDIS": cv2.CALIB_HAND_EYE_DANIILIDIS,
}
ZXING_SHIFT_PX = -0.5


def errors(est, true):
    angle = angle_deg(est[:3, :3], true[:3, :3])
    return angle, float(np.linalg.norm(est[:3, 3] - true[:3, 3]))


def camera(doc):
    c = doc["camera"]
    k = np.array([[c["fx_px"], 0, c["cx_px"]], [0, c["fy_px"], c["cy_px"]], [0, 0, 1]], float)
    return k, np.array(c["distortion"], float)


def read_gray(path):
    return cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)


def zxing_pose(gray, k, d, size_mm):
    import zxingcpp
    found = zxingcpp.read_barcodes(gray, formats=zxingcpp.BarcodeFormat.QRCode)
    if not found:
        return None
    p = found[0].position
    img = np.array([[p.top_left.x, p.top_left.y], [p.top_right.x, p.top_right.y],
                    [p.bottom_right.x, p.bottom_right.y], [p.bottom_left.x, p.bottom_left.y]],
                   float) + ZXING_SHIFT_PX
    h = size_mm / 2
    obj = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], float)
    ok, rvec, tvec = cv2.solvePnP(obj, img, k, d, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    return (rvec, tvec) if ok else None


def board_pose(gray, k, d, corners_mm, truth_px):
    ok, corners = cv2.findChessboardCornersSB(
        gray, (9, 9), flags=cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_ACCURACY)
    if not ok:
        return None
    c = corners.reshape(-1, 2).astype(float)
    grid = c.reshape(9, 9, 2)
    labellings = [grid, grid[::-1, ::-1], grid.transpose(1, 0, 2), grid[::-1, ::-1].transpose(1, 0, 2),
                  grid[::-1, :], grid[:, ::-1], grid.transpose(1, 0, 2)[::-1, :], grid.transpose(1, 0, 2)[:, ::-1]]
    best = min(labellings, key=lambda g: float(np.sum((g.reshape(-1, 2) - truth_px) ** 2)))
    obj = np.array([[x, y, 0.0] for x, y in corners_mm], float)
    ok, rvec, tvec = cv2.solvePnP(obj, best.reshape(-1, 2), k, d, flags=cv2.SOLVEPNP_ITERATIVE)
    return (rvec, tvec) if ok else None


def project_truth(doc, view, k, d):
    """The board's inner corners in px from the truth (only to label the detected ones)."""
    code = rigid(view["code_in_camera"])  # centre frame
    half = doc["marker"]["size_mm"] / 2
    # Board frame as the marker's paper frame: top-left at (-l, 0), x right, y down; its
    # origin P2 sits at (+l/2, -l/2) from the centre in the centre frame.
    pts = np.array([[x - 2 * half + half, y - half, 0.0] for x, y in view["board_inner_corners_mm"]])
    r, t = code[:3, :3], code[:3, 3]
    rvec, _ = cv2.Rodrigues(r)
    px, _ = cv2.projectPoints(pts, rvec, t, k, d)
    return px.reshape(-1, 2)


def anchor_poses(doc, folder):
    """Per view: the zxing pose and the board pose (or None). Cached in the session folder
    (anchors.json): the photos of a session never change."""
    cache = folder / "anchors.json"
    if cache.exists():
        raw = json.loads(cache.read_text())
    else:
        k, d = camera(doc)
        raw = []
        for view in doc["views"]:
            z = zxing_pose(read_gray(folder / view["photo"]), k, d, doc["marker"]["size_mm"])
            b = board_pose(read_gray(folder / view["board"]), k, d, view["board_inner_corners_mm"],
                           project_truth(doc, view, k, d))
            raw.append({name: None if p is None else [p[0].ravel().tolist(), p[1].ravel().tolist()]
                        for name, p in (("zxing", z), ("checkerboard", b))})
        cache.write_text(json.dumps(raw))
    return [{name: None if p is None else (np.array(p[0]), np.array(p[1])) for name, p in v.items()}
            for v in raw]


def opencv_mounts(doc, poses, level, anchor):
    """{method: 4x4 mount} from the views where `anchor` found the target."""
    r_g, t_g, r_t, t_t = [], [], [], []
    for view, p in zip(doc["views"], poses):
        if p[anchor] is None:
            continue
        f = rigid(view["reported"][level])
        if doc["setup"] == "eye_to_hand":
            f = np.linalg.inv(f)
        r_g.append(f[:3, :3]); t_g.append(f[:3, 3].reshape(3, 1))
        rvec, tvec = p[anchor]
        r_t.append(cv2.Rodrigues(rvec)[0]); t_t.append(tvec.reshape(3, 1))
    out = {}
    if len(r_g) < 3:
        return out
    for name, method in METHODS.items():
        r, t = cv2.calibrateHandEye(r_g, t_g, r_t, t_t, method=method)
        m = np.eye(4); m[:3, :3] = r; m[:3, 3] = t.ravel()
        out[name] = m
    return out


def pct(values, q):
    return float(np.percentile(values, q)) if values else float("nan")


def main():
    root = Path(sys.argv[1])
    cv2.setNumThreads(1)
    sessions = sorted(root.glob("*/session.json"))
    rows = {}  # (setup, level) -> {"qrpose": [(rot, trans)], "zxing": {m: [...]}, ...}
    normalised = {}
    for path in sessions:
        doc = json.loads(path.read_text())
        poses = anchor_poses(doc, path.parent)
        true = rigid(doc["mount"])
        for level in doc["qrpose"]:
            key = (doc["setup"], level)
            row = rows.setdefault(key, {"qrpose": [], "zxing": {}, "checkerboard": {}, "failed": 0,
                                        "read": {"zxing": [], "checkerboard": []}})
            q = doc["qrpose"][level]
            if "error" in q:
                row["failed"] += 1
            else:
                row["qrpose"].append((q["rotation_error_deg"], q["translation_error_mm"]))
                normalised.setdefault(key, []).append(q["normalised_errors"])
            for anchor in ("zxing", "checkerboard"):
                row["read"][anchor].append(sum(p[anchor] is not None for p in poses))
                for name, m in opencv_mounts(doc, poses, level, anchor).items():
                    row[anchor].setdefault(name, []).append(errors(m, true))
        print(f"{path.parent.name}: done", file=sys.stderr)

    print("| setup | flange noise | method | sessions | rotation error median / p90 (deg) | translation error median / p90 (mm) |")
    print("|---|---|---|---|---|---|")
    summary = []
    for (setup, level), row in sorted(rows.items()):
        noise = f"{level} mm, {float(level) / 10:.2f} deg"
        rot = [r for r, _ in row["qrpose"]]; tr = [t for _, t in row["qrpose"]]
        print(f"| {setup} | {noise} | qrpose | {len(rot)} | {pct(rot, 50):.4f} / {pct(rot, 90):.4f} | {pct(tr, 50):.3f} / {pct(tr, 90):.3f} |")
        best = {}
        for anchor in ("checkerboard", "zxing"):
            if not row[anchor]:
                continue
            name = min(row[anchor], key=lambda m: pct([t for _, t in row[anchor][m]], 50))
            errs = row[anchor][name]
            r2 = [r for r, _ in errs]; t2 = [t for _, t in errs]
            best[anchor] = (pct(r2, 50), pct(t2, 50))
            print(f"| {setup} | {noise} | OpenCV {name}, {anchor} | {len(errs)} | {pct(r2, 50):.4f} / {pct(r2, 90):.4f} | {pct(t2, 50):.3f} / {pct(t2, 90):.3f} |")
        summary.append((setup, level, (pct(rot, 50), pct(tr, 50)), best, row))
    print()
    print("qrpose's normalised errors (estimate - truth) / std, RMS over the sessions (about 1 when the standard deviations are right):")
    print()
    print("| setup | flange noise | rotation (3 axes pooled) | translation (3 axes pooled) |")
    print("|---|---|---|---|")
    for (setup, level), values in sorted(normalised.items()):
        a = np.array(values)
        rr = math.sqrt(float(np.mean(a[:, :3] ** 2))); rt = math.sqrt(float(np.mean(a[:, 3:] ** 2)))
        print(f"| {setup} | {level} mm | {rr:.2f} | {rt:.2f} |")
    print()
    print("Every OpenCV method, median rotation (deg) / translation (mm):")
    print()
    print("| setup | flange noise | anchor | " + " | ".join(METHODS) + " |")
    print("|---|---|---|" + "---|" * len(METHODS))
    for (setup, level), row in sorted(rows.items()):
        for anchor in ("checkerboard", "zxing"):
            cells = []
            for name in METHODS:
                errs = row[anchor].get(name, [])
                cells.append(f"{pct([r for r, _ in errs], 50):.3f} / {pct([t for _, t in errs], 50):.2f}")
            reads = row["read"][anchor]
            print(f"| {setup} | {level} mm | {anchor} ({min(reads)}-{max(reads)} of 12 read) | " + " | ".join(cells) + " |")
    print()
    print("Targets (qrpose median at or under the checkerboard's, and at or under half the zxing anchor's, "
          "or under the floors 0.05 deg / 0.5 mm):")
    print()
    for setup, level, (qr, qt), best, row in summary:
        verdicts = []
        if "checkerboard" in best:
            br, bt = best["checkerboard"]
            verdicts.append("checkerboard " + ("met" if (qr <= br or qr <= 0.05) and (qt <= bt or qt <= 0.5) else "NOT met"))
        if "zxing" in best:
            zr, zt = best["zxing"]
            verdicts.append("half zxing " + ("met" if (qr <= zr / 2 or qr <= 0.05) and (qt <= zt / 2 or qt <= 0.5) else "NOT met"))
        print(f"- {setup}, {level} mm: qrpose {qr:.4f} deg / {qt:.3f} mm; " + ", ".join(verdicts)
              + (f"; {row['failed']} sessions refused" if row["failed"] else ""))


if __name__ == "__main__":
    main()
