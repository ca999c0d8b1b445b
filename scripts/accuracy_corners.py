#!/usr/bin/env python3
"""Pose accuracy on noisy corners: qrpose's three methods beside OpenCV, same inputs.

    python3 scripts/accuracy_corners.py [--sigma-px 0.5] [--cases 2000] [--seed 2022]

Creates its own virtual environment in target/pyenv (numpy, opencv-python-headless from
PyPI), runs `cargo run --release --example corner_accuracy` to write the dataset and our
results into target/accuracy/, solves every case with OpenCV (solvePnP IPPE, IPPE_SQUARE and
ITERATIVE, each followed by solvePnPRefineLM), and prints one markdown table.
"""
import argparse
import csv
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / "target" / "pyenv"
PACKAGES = ["numpy", "opencv-python-headless"]


def ensure_venv():
    """Re-runs this script inside target/pyenv with the packages installed."""
    python = VENV / "bin" / "python"
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    if not python.exists():
        venv.EnvBuilder(with_pip=True).create(VENV)
    subprocess.run([str(python), "-m", "pip", "install", "-q", *PACKAGES], check=True)
    os.execv(str(python), [str(python), __file__, *sys.argv[1:]])


def quantile(values, q):
    """Nearest-rank quantile, as qrpose::sim::report::quantile."""
    v = sorted(values)
    n = len(v)
    rank = next(k for k in range(1, n + 1) if k >= q * n)
    return v[rank - 1]


def rotation_angle_deg(r_a, r_b):
    import numpy as np

    rel = r_a.T @ r_b
    s = np.linalg.norm([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]]) / 2.0
    c = (np.trace(rel) - 1.0) / 2.0
    return float(np.degrees(np.arctan2(s, c)))


def read_dataset(path):
    header = {}
    rows = []
    with open(path) as f:
        first = f.readline().lstrip("# ").split()
        header = {k: float(v) for k, v in (kv.split("=") for kv in first)}
        for row in csv.DictReader(f):
            rows.append({k: float(v) for k, v in row.items()})
    return header, rows


def opencv_results(header, rows):
    import cv2
    import numpy as np

    l = header["marker_mm"]
    h = l / 2.0
    k = np.array([[header["f_px"], 0, header["cx_px"]], [0, header["f_px"], header["cy_px"]], [0, 0, 1.0]])
    # Our marker frame (docs/conventions.md), corners in "qr" order: TL = P3, TR = P2, BR = P1, BL = P4.
    ours = np.array([[-l, 0, 0], [0, 0, 0], [0, l, 0], [-l, l, 0]], dtype=np.float64)
    # IPPE_SQUARE's own frame: centred, y up; our centred frame with y and z flipped.
    square = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], dtype=np.float64)
    flip = np.diag([1.0, -1.0, -1.0])
    centre_ours = np.array([-h, h, 0.0])
    solvers = {
        "OpenCV IPPE + RefineLM": (cv2.SOLVEPNP_IPPE, ours),
        "OpenCV IPPE_SQUARE + RefineLM": (cv2.SOLVEPNP_IPPE_SQUARE, square),
        "OpenCV ITERATIVE + RefineLM": (cv2.SOLVEPNP_ITERATIVE, ours),
    }
    results = {}
    for name, (flag, obj) in solvers.items():
        rot, pos = [], []
        for r in rows:
            img = np.array([[r["u_tl"], r["v_tl"]], [r["u_tr"], r["v_tr"]], [r["u_br"], r["v_br"]], [r["u_bl"], r["v_bl"]]])
            ok, rvec, tvec = cv2.solvePnP(obj, img, k, None, flags=flag)
            if not ok:
                rot.append(float("inf"))
                pos.append(float("inf"))
                continue
            rvec, tvec = cv2.solvePnPRefineLM(obj, img, k, None, rvec, tvec)
            r_cv, _ = cv2.Rodrigues(rvec)
            t = tvec.reshape(3)
            if flag == cv2.SOLVEPNP_IPPE_SQUARE:
                r_ours, centre = r_cv @ flip, t
            else:
                r_ours, centre = r_cv, r_cv @ centre_ours + t
            truth = np.array([[r["r11"], r["r12"], r["r13"]], [r["r21"], r["r22"], r["r23"]], [r["r31"], r["r32"], r["r33"]]])
            rot.append(rotation_angle_deg(r_ours, truth))
            pos.append(float(np.linalg.norm(centre - np.array([r["cx_mm"], r["cy_mm"], r["cz_mm"]]))))
        results[name] = (rot, pos)
    return results, cv2.__version__


def qrpose_results(path):
    """Our errors per method, plus the reprojection poses not flagged ambiguous."""
    results = {}
    unflagged = ([], [])
    total = 0
    with open(path) as f:
        for row in csv.DictReader(f):
            name = f"qrpose {row['method']}"
            rot, pos = results.setdefault(name, ([], []))
            rot.append(float(row["rotation_error_deg"]))
            pos.append(float(row["position_error_mm"]))
            if row["method"] == "reprojection":
                total += 1
                if row["ambiguous"] == "false":
                    unflagged[0].append(rot[-1])
                    unflagged[1].append(pos[-1])
    share = 100.0 * len(unflagged[0]) / max(total, 1)
    results[f"qrpose reprojection, poses not flagged ambiguous ({share:.0f} %)"] = unflagged
    return results


def main():
    ensure_venv()
    parser = argparse.ArgumentParser()
    parser.add_argument("--sigma-px", type=float, default=0.5)
    parser.add_argument("--cases", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=2022)
    args = parser.parse_args()
    out = ROOT / "target" / "accuracy"
    subprocess.run(
        ["cargo", "run", "--release", "-q", "--example", "corner_accuracy", "--",
         str(out), str(args.sigma_px), str(args.cases), str(args.seed)],
        cwd=ROOT, check=True, stdout=subprocess.DEVNULL,
    )
    header, rows = read_dataset(out / "corners.csv")
    ours = qrpose_results(out / "qrpose_results.csv")
    theirs, cv_version = opencv_results(header, rows)
    print(f"{len(rows)} cases: 1280x720, f = {header['f_px']:g} px, {header['marker_mm']:g} mm marker at 200-1500 mm, "
          f"tilt 0-60 deg, sigma = {header['sigma_px']:g} px, seed {int(header['seed'])}; OpenCV {cv_version}\n")
    print_table({**ours, **theirs})


def print_table(results):
    """A markdown table of {method: (rotation errors deg, position errors mm)}."""
    print("| method | rotation error median / mean / p95 (deg) | position error median / mean / p95 (mm) |")
    print("|---|---|---|")
    for name, (rot, pos) in results.items():
        mean_r = sum(rot) / len(rot)
        mean_p = sum(pos) / len(pos)
        print(f"| {name} | {quantile(rot, .5):.3f} / {mean_r:.3f} / {quantile(rot, .95):.3f} "
              f"| {quantile(pos, .5):.3f} / {mean_p:.3f} / {quantile(pos, .95):.3f} |")


if __name__ == "__main__":
    main()
