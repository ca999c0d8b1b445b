#!/usr/bin/env python3
"""Writes the OpenCV fixtures of the lens models and the calibration readers
(docs/calibration.md, How the fixtures were made).

    python3 scripts/make_calibration_fixtures.py

Creates its own virtual environment in target/calib-venv (opencv-python-headless pinned to
OPENCV_PACKAGE, numpy, from PyPI) on first use and re-executes itself inside it. Writes:

* crates/qrpose-core/tests/fixtures/opencv_projections.json: for three realistic cameras
  (plumb_bob, rational_polynomial, equidistant), 3D points in the camera frame and the pixels
  OpenCV projects them to: cv2.projectPoints for the two radial-tangential models (rvec =
  tvec = 0, 5 or 8 coefficients), cv2.fisheye.projectPoints for the fisheye model. The points
  cover the image: ideal normalised points on a grid (fisheye: angles from the axis up to
  88 degrees and every direction around it), each at a depth drawn from a seeded generator,
  kept when OpenCV puts them inside the image, on the model's first rising branch (the
  script asserts it), so undistortion has one answer there.
  crates/qrpose-core/tests/distortion_models.rs reads it.
* crates/qrpose-site/tests/fixtures/opencv_*.yaml: calibration files written by
  cv2.FileStorage, with the keys of OpenCV's calibration sample (camera_matrix,
  distortion_coefficients, image_width, image_height, ...) or the K / D of fisheye tools; one
  with 14 coefficients and one with a NaN (how OpenCV writes them), which the reader refuses.
* crates/qrpose-site/tests/fixtures/opencv_expected.json: what each readable file holds and
  where OpenCV projects a few points with it; crates/qrpose-site/tests/calibration.rs reads it.

crates/qrpose-site/tests/fixtures/ros_camera_info*.yaml are written by hand (see their comments),
not by this script. Running the script again gives the same files byte for byte.
"""
import json
import os
import re
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / "target" / "calib-venv"
# FileStorage of OpenCV 4 writes the `%YAML:1.0` header that most calibration files in use
# carry (OpenCV 5 writes `%YAML 1.2`; the reader takes both).
OPENCV_PACKAGE = "opencv-python-headless==4.10.0.84"
PACKAGES = [OPENCV_PACKAGE, "numpy"]
CORE_FIXTURES = ROOT / "crates" / "qrpose-core" / "tests" / "fixtures"
SITE_FIXTURES = ROOT / "crates" / "qrpose-site" / "tests" / "fixtures"
SEED = 14

# Realistic cameras: a 720p webcam, a 1080p wide-angle camera calibrated with OpenCV's
# rational model, and a fisheye tracking camera of about 170 degrees (848 x 800).
CAMERAS = {
    "webcam_plumb_bob": {
        "model": "plumb_bob",
        "image_size_px": [1280, 720],
        "fx_px": 912.34, "fy_px": 910.87, "cx_px": 641.23, "cy_px": 358.71,
        "coefficients": [-0.3121, 0.1083, 6.1e-4, -4.2e-4, -0.01874],
    },
    "wide_rational_polynomial": {
        "model": "rational_polynomial",
        "image_size_px": [1920, 1080],
        "fx_px": 1398.62, "fy_px": 1397.15, "cx_px": 961.87, "cy_px": 538.42,
        "coefficients": [0.3521, -0.0472, 3.7e-4, -2.9e-4, 0.0013, 0.6893, 0.0104, -0.0031],
    },
    "tracking_equidistant": {
        "model": "equidistant",
        "image_size_px": [848, 800],
        "fx_px": 285.72, "fy_px": 285.93, "cx_px": 423.08, "cy_px": 401.44,
        "coefficients": [-0.00566, 0.04186, -0.03869, 0.00673],
    },
}


def ensure_venv():
    """Re-runs this script inside target/calib-venv with the packages installed."""
    python = VENV / "bin" / "python"
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    if not python.exists():
        venv.EnvBuilder(with_pip=True).create(VENV)
    probe = subprocess.run([str(python), "-c", "import cv2, numpy"], capture_output=True)
    if probe.returncode != 0:
        subprocess.run([str(python), "-m", "pip", "install", "-q", *PACKAGES], check=True)
    os.execv(str(python), [str(python), __file__, *sys.argv[1:]])


def camera_matrix(cam):
    import numpy as np

    return np.array([[cam["fx_px"], 0.0, cam["cx_px"]],
                     [0.0, cam["fy_px"], cam["cy_px"]],
                     [0.0, 0.0, 1.0]])


def project(cam, points_mm):
    """OpenCV's pixels of camera-frame points (rvec = tvec = 0), shape (N, 2)."""
    import cv2
    import numpy as np

    k = camera_matrix(cam)
    d = np.array(cam["coefficients"], dtype=np.float64)
    obj = np.asarray(points_mm, dtype=np.float64).reshape(-1, 1, 3)
    zero = np.zeros(3)
    if cam["model"] == "equidistant":
        px, _ = cv2.fisheye.projectPoints(obj, zero, zero, k, d.reshape(4, 1))
    else:
        px, _ = cv2.projectPoints(obj, zero, zero, k, d)
    return px.reshape(-1, 2)


def radial_distance(cam, r):
    """The distorted radius of ideal radius r (normalised) along the x axis, no tangential."""
    import numpy as np

    c = cam["coefficients"]
    if cam["model"] == "equidistant":
        t = np.arctan(r)
        return t * (1 + c[0] * t**2 + c[1] * t**4 + c[2] * t**6 + c[3] * t**8)
    k4, k5, k6 = (c[5], c[6], c[7]) if len(c) == 8 else (0.0, 0.0, 0.0)
    s = r * r
    return r * (1 + c[0] * s + c[1] * s**2 + c[4] * s**3) / (1 + k4 * s + k5 * s**2 + k6 * s**3)


def ideal_grid(cam):
    """Ideal normalised points (x, y) over and beyond the image."""
    import numpy as np

    if cam["model"] == "equidistant":
        theta = np.radians(np.linspace(0.0, 88.0, 12))
        phi = np.radians(np.arange(0.0, 360.0, 30.0) + 7.0)
        return [(np.tan(t) * np.cos(p), np.tan(t) * np.sin(p)) for t in theta for p in phi
                if t > 0] + [(0.0, 0.0)]
    w, h = cam["image_size_px"]
    half_x = 1.6 * max(cam["cx_px"], w - cam["cx_px"]) / cam["fx_px"]
    half_y = 1.6 * max(cam["cy_px"], h - cam["cy_px"]) / cam["fy_px"]
    return [(x, y) for x in np.linspace(-half_x, half_x, 17) for y in np.linspace(-half_y, half_y, 11)]


def reference_case(name, cam, rng):
    """One camera's points (mm), OpenCV's pixels, and the check that all lie on the model's
    first rising branch and inside the image."""
    import numpy as np

    ideal = ideal_grid(cam)
    depths = rng.uniform(200.0, 5000.0, size=len(ideal))
    points = np.array([[x * z, y * z, z] for (x, y), z in zip(ideal, depths)])
    pixels = project(cam, points)
    w, h = cam["image_size_px"]
    inside = ((pixels[:, 0] >= -0.5) & (pixels[:, 0] <= w - 0.5)
              & (pixels[:, 1] >= -0.5) & (pixels[:, 1] <= h - 0.5))
    points, pixels = points[inside], pixels[inside]
    r_max = max(np.hypot(p[0] / p[2], p[1] / p[2]) for p in points)
    radii = np.linspace(0.0, 1.05 * r_max, 2000)
    assert np.all(np.diff(radial_distance(cam, radii)) > 0), f"{name}: folds over in the image"
    return {
        "name": name,
        **cam,
        "points_mm": points.tolist(),
        "pixels_px": pixels.tolist(),
    }


def write_json(path, document):
    """Indented JSON with every list of numbers on one line."""
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(document, indent=1)
    text = re.sub(r"\[\s+([-+0-9.eE,\s]+?)\s+\]", lambda m: "[" + " ".join(m.group(1).split()) + "]", text)
    path.write_text(text + "\n")
    print(f"wrote {path.relative_to(ROOT)}")


def header(cv2, what):
    return [
        f"Written by scripts/make_calibration_fixtures.py with OpenCV {cv2.__version__} "
        f"({OPENCV_PACKAGE}); do not edit by hand, run the script again.",
        what,
    ]


def write_storage(path, entries):
    """A calibration file through cv2.FileStorage, entries in order."""
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in entries:
        fs.write(key, value)
    fs.release()
    print(f"wrote {path.relative_to(ROOT)}")


def calibration_files(cv2, rng):
    """The cv2.FileStorage fixtures, and what each readable one holds."""
    import numpy as np

    SITE_FIXTURES.mkdir(parents=True, exist_ok=True)
    webcam = CAMERAS["webcam_plumb_bob"]
    wide = CAMERAS["wide_rational_polynomial"]
    fisheye = CAMERAS["tracking_equidistant"]
    four = {**webcam, "coefficients": webcam["coefficients"][:4], "image_size_px": None}
    sample_keys = [("calibration_time", "Tue 14 Jan 2025 10:12:31 CET"), ("nframes", 25)]
    files = {
        "opencv_plumb_bob.yaml": (webcam, sample_keys + [
            ("image_width", 1280), ("image_height", 720),
            ("board_width", 9), ("board_height", 6), ("square_size", 25.0), ("flags", 0),
            ("camera_matrix", camera_matrix(webcam)),
            ("distortion_coefficients", np.array([webcam["coefficients"]])),
            ("avg_reprojection_error", 0.2135),
        ]),
        "opencv_rational_polynomial.yaml": (wide, sample_keys + [
            ("image_width", 1920), ("image_height", 1080),
            ("flags", cv2.CALIB_RATIONAL_MODEL),
            ("camera_matrix", camera_matrix(wide)),
            ("distortion_coefficients", np.array(wide["coefficients"]).reshape(8, 1)),
            ("avg_reprojection_error", 0.1874),
        ]),
        "opencv_fisheye.yaml": (fisheye, [
            ("image_width", 848), ("image_height", 800),
            ("distortion_model", "fisheye"),
            ("K", camera_matrix(fisheye)),
            ("D", np.array(fisheye["coefficients"]).reshape(4, 1)),
        ]),
        "opencv_four_coefficients.yaml": (four, [
            ("camera_matrix", camera_matrix(webcam)),
            ("distortion_coefficients", np.array([four["coefficients"]])),
        ]),
    }
    expected = {}
    for name, (cam, entries) in files.items():
        write_storage(SITE_FIXTURES / name, entries)
        model = "plumb_bob" if name == "opencv_four_coefficients.yaml" else cam["model"]
        coefficients = cam["coefficients"] + ([0.0] if len(cam["coefficients"]) == 4
                                              and model == "plumb_bob" else [])
        as_read = {**cam, "model": model, "coefficients": coefficients}
        case = reference_case(name, {**as_read, "image_size_px": cam["image_size_px"] or [1280, 720]}, rng)
        expected[name] = {
            **as_read,
            "points_mm": case["points_mm"][::7],
            "pixels_px": case["pixels_px"][::7],
        }
    # Refused: OpenCV's 14-coefficient model (thin prism and tilted sensor), and a NaN
    # (FileStorage writes it as `.Nan`).
    fourteen = np.array(webcam["coefficients"] + [0.0, 0.0, 0.0, 1e-3, 0.0, 0.0, 0.0, 0.0, 0.0])
    write_storage(SITE_FIXTURES / "opencv_fourteen_coefficients.yaml", [
        ("camera_matrix", camera_matrix(webcam)),
        ("distortion_coefficients", fourteen.reshape(1, 14)),
    ])
    nan = np.array(webcam["coefficients"])
    nan[1] = np.nan
    write_storage(SITE_FIXTURES / "opencv_nan.yaml", [
        ("camera_matrix", camera_matrix(webcam)),
        ("distortion_coefficients", nan.reshape(1, 5)),
    ])
    return expected


def main():
    ensure_venv()
    import cv2
    import numpy as np

    rng = np.random.default_rng(SEED)
    cases = [reference_case(name, cam, rng) for name, cam in CAMERAS.items()]
    write_json(CORE_FIXTURES / "opencv_projections.json", {
        "_comment": header(cv2, "cv2.projectPoints (plumb_bob, rational_polynomial) and "
                                "cv2.fisheye.projectPoints (equidistant) of points_mm in the "
                                "camera frame, rvec = tvec = 0; see the script's docstring."),
        "opencv_version": cv2.__version__,
        "cases": cases,
    })
    expected = calibration_files(cv2, rng)
    write_json(SITE_FIXTURES / "opencv_expected.json", {
        "_comment": header(cv2, "What each cv2.FileStorage fixture beside this file holds "
                                "(coefficients as the reader must return them) and where "
                                "OpenCV projects a few points with it."),
        "opencv_version": cv2.__version__,
        "files": expected,
    })


if __name__ == "__main__":
    main()
