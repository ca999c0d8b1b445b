#!/usr/bin/env python3
"""Pose accuracy on noisy corners: qrpose and OpenCV (as scripts/accuracy_corners.py) beside
AprilTag's pose code, same dataset, one markdown table.

    python3 scripts/accuracy_apriltag.py APRILTAG_POSES.csv

Expects target/accuracy/corners.csv and qrpose_results.csv (cargo run --release --example
corner_accuracy) and the poses written by benches/apriltag/pose_bench.c, whose rows are
"id,method,r11..r33,cx_mm,cy_mm,cz_mm", already in our marker frame (rotation of docs/conventions.md, marker centre in the camera frame). Uses the virtual environment of
scripts/accuracy_corners.py (target/pyenv) for OpenCV; scripts/bench_apriltag_pose.sh runs it.
"""
import csv
import math
import os
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_corners as ac  # noqa: E402


def ensure_venv():
    python = ac.VENV / "bin" / "python"
    if Path(sys.prefix).resolve() == ac.VENV.resolve():
        return
    if not python.exists():
        import venv

        venv.EnvBuilder(with_pip=True).create(ac.VENV)
    subprocess.run([str(python), "-m", "pip", "install", "-q", *ac.PACKAGES], check=True)
    os.execv(str(python), [str(python), __file__, *sys.argv[1:]])


def apriltag_results(path, rows):
    import numpy as np

    names = {
        "apriltag_estimate_tag_pose": "AprilTag estimate_tag_pose (homography + orthogonal iteration + 2nd minimum)",
        "apriltag_homography": "AprilTag homography only (a copy of estimate_pose_for_tag_homography, not exported by libapriltag 3.3.0)",
    }
    results = {}
    with open(path) as f:
        for p in csv.DictReader(f):
            rot, pos = results.setdefault(names[p["method"]], ([], []))
            truth_row = rows[int(p["id"])]
            est = np.array([float(p[k]) for k in ("r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33")]).reshape(3, 3)
            truth = np.array([truth_row[k] for k in ("r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33")]).reshape(3, 3)
            centre = np.array([float(p["cx_mm"]), float(p["cy_mm"]), float(p["cz_mm"])])
            if not np.all(np.isfinite(est)) or not np.all(np.isfinite(centre)):
                rot.append(math.inf)
                pos.append(math.inf)
                continue
            rot.append(ac.rotation_angle_deg(est, truth))
            pos.append(float(np.linalg.norm(centre - np.array([truth_row["cx_mm"], truth_row["cy_mm"], truth_row["cz_mm"]]))))
    return results


def main():
    ensure_venv()
    poses = Path(sys.argv[1]) if len(sys.argv) > 1 else ac.ROOT / "target" / "apriltag-bench" / "poses.csv"
    out = ac.ROOT / "target" / "accuracy"
    header, rows = ac.read_dataset(out / "corners.csv")
    ours = ac.qrpose_results(out / "qrpose_results.csv")
    theirs, cv_version = ac.opencv_results(header, rows)
    april = apriltag_results(poses, rows)
    print(f"{len(rows)} cases: 1280x720, f = {header['f_px']:g} px, {header['marker_mm']:g} mm marker at 200-1500 mm, "
          f"tilt 0-60 deg, sigma = {header['sigma_px']:g} px, seed {int(header['seed'])}; OpenCV {cv_version}, "
          f"libapriltag 3.3.0 (Debian)\n")
    ac.print_table({**ours, **theirs, **april})


if __name__ == "__main__":
    main()
