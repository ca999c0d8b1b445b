#!/usr/bin/env python3
"""Camera calibration from photos of a printed QR code, against OpenCV (docs/calibration.md,
"Compared with OpenCV's checkerboard").

    python3 scripts/calibration_compare.py                    # 20 sets, every method
    python3 scripts/calibration_compare.py --sets 3 --methods ours,checkerboard
    python3 scripts/calibration_compare.py --json target/calibration-compare/results.json
    python3 scripts/calibration_compare.py --profile dev --sets 3   # unoptimised builds

Builds and files go to $CARGO_TARGET_DIR (default: target/ in the repository).

The photos are rendered by qrpose-sim with known truth (its example `calibration_photos`,
built and run by this script; see crates/qrpose-sim/examples/calibration_photos.rs): a
1280 x 720 camera with fx 1000, fy 1005, cx 652, cy 349 px and barrel distortion (plumb_bob
k1 -0.25, k2 0.08, p1 0.001, p2 -0.0005, k3 0); per set, 15 views of one printed 120 mm QR
code (version 4) at 0.3-0.7 m, tilted 10-40 deg, spread over the image, with lens blur
(sigma 0.8 px), noise (sigma 2 grey levels), uneven lighting, background shapes and JPEG 90;
and a printed checkerboard of the same outer size (10 x 10 squares of 12 mm, 81 inner
corners, a light border as wide as the code's quiet zone) from the same 15 poses, drawn by
the same rasteriser with the same camera, effects and seeds (render_checkerboard). Set s
(seeds --first-seed .. +--sets, default 1-20) is rendered once into
target/calibration-compare/set-SS/ and reused.

Methods, each fitting plumb_bob (k1, k2, p1, p2, k3) to one set's 15 photos:

* ours: `qrpose calibrate --marker-size-mm 120 --model plumb_bob qr_*.jpg` under
  `taskset -c 0` (skipped, with a message, when the binary has no `calibrate` subcommand);
* checkerboard: OpenCV `findChessboardCornersSB` (9 x 9 inner corners, flags
  NORMALIZE_IMAGE | ACCURACY) on the checkerboard photos, then `calibrateCameraExtended`
  (flags 0: five coefficients, free aspect ratio and principal point);
* qr4-qrpose: `calibrateCameraExtended` on the four outer corners of each code only, as
  qrpose's detector returns them (`qrpose estimate --image`, one process per photo, under
  `taskset -c 0`; corners refined with straight sides, no lens model);
* qr4-opencv: the same from OpenCV's own `QRCodeDetector.detectAndDecode` corners.

OpenCV runs single-threaded (cv2.setNumThreads(1)) on CPU 0 (sched_setaffinity). Per method
and set: focal length error (% of the larger of |fx/fx_true - 1| and |fy/fy_true - 1|),
principal point error (px), the distortion field error (95th percentile over a 96 x 54 grid
on the image's inner 90 % of |d_true(p) - d_fit(p)|, d(p) = p - K D^-1(K^-1 p), each camera
with its own K, as qrpose_calib::compare), the projection difference (95th percentile of
where the fitted camera sees the true camera's rays; it includes the intrinsics' errors),
the reported standard deviations and the normalised errors (est - true) / std of every
parameter, fx, fy, cx, cy, k1, k2, p1, p2, k3 (their RMS over the sets is about 1 when the
stds are right: 0.69-1.31 is the 95 % range of the RMS of 20 standard normal draws; with
--first-seed and --sets, seeds not used to choose a method can be judged alone), for ours the correlation of the
residuals of two points of a view by their distance (cm.residual_correlation) and the photos
it left out (why, and how tilted their code), and the time for the 15 photos: CPU (user +
sys, of the children for subprocesses) and wall clock, with the load average beside them.

Output: Markdown tables (the first set's values; over all sets: RMS and max of each error,
mean std, normalised error RMS, median times), the targets (ours at most 1.5x the
checkerboard's RMS error or under 0.15 %, 3 px, 2 px; stds consistent; 15 photos under 2 s
on one core), and with --json every per-set number.

Runs in target/calib-compare-venv (opencv-python-headless and numpy pinned below, from
PyPI; created on first use, the script re-executes itself inside it).
"""
import argparse, json, os, platform, resource, subprocess, sys, time, venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TARGET = Path(os.environ.get("CARGO_TARGET_DIR") or ROOT / "target")
VENV = TARGET / "calib-compare-venv"
PACKAGES = ["opencv-python-headless==4.10.0.84", "numpy==2.2.6"]
SETS_DIR = TARGET / "calibration-compare"
# Cargo's profile and the folder it builds into.
PROFILES = {"release": "release", "dev": "debug"}
METHODS = ["ours", "checkerboard", "qr4-qrpose", "qr4-opencv"]
BOARD_INNER = (9, 9)
# The targets: each error at most 1.5x the checkerboard's, or under these.
TARGETS = {"focal_pct": 0.15, "pp_px": 3.0, "field_p95_px": 2.0}
TIME_TARGET_S = 2.0


def ensure_venv():
    py = VENV / "bin" / "python3"
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    if not py.exists():
        venv.create(VENV, with_pip=True)
    if subprocess.run([str(py), "-c", "import cv2, numpy"], capture_output=True).returncode:
        subprocess.check_call([str(py), "-m", "pip", "install", "-q"] + PACKAGES)
    os.execv(str(py), [str(py)] + sys.argv)


ensure_venv()
import cv2  # noqa: E402
import numpy as np  # noqa: E402
import calibration_metrics as cm  # noqa: E402  (scripts/, beside this file)


# --- the photo sets -------------------------------------------------------------------------

def render_sets(seeds, profile):
    """Renders every set not yet on disk (the example built once, in `profile`)."""
    missing = [s for s in seeds if not (SETS_DIR / f"set-{s:02d}" / "truth.json").exists()]
    if not missing:
        return
    subprocess.check_call(["cargo", "build", "--profile", profile, "-q", "-p", "qrpose-sim",
                           "--example", "calibration_photos"], cwd=ROOT)
    example = TARGET / PROFILES[profile] / "examples" / "calibration_photos"
    for s in missing:
        subprocess.check_call([str(example), str(SETS_DIR / f"set-{s:02d}"), str(s)])


def load_set(seed):
    d = SETS_DIR / f"set-{seed:02d}"
    truth = json.loads((d / "truth.json").read_text())
    c = truth["camera"]
    cam = cm.Camera(c["fx_px"], c["fy_px"], c["cx_px"], c["cy_px"], c["distortion"]["coefficients"])
    return d, truth, cam


# --- timing ---------------------------------------------------------------------------------

class Clock:
    """CPU (this process and its waited-for children, user + sys) and wall time of a block."""

    def __enter__(self):
        self.cpu0 = self._cpu()
        self.wall0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.cpu_s = self._cpu() - self.cpu0
        self.wall_s = time.perf_counter() - self.wall0

    @staticmethod
    def _cpu():
        s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def on_cpu0():
    os.sched_setaffinity(0, {0})
    cv2.setNumThreads(1)


# --- the methods ----------------------------------------------------------------------------

def calibrate_cv(object_points, image_points, size):
    """cv2.calibrateCameraExtended (flags 0): (Camera, std dict, RMS px)."""
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    out = cv2.calibrateCameraExtended(
        [np.asarray(o, np.float32) for o in object_points],
        [np.asarray(i, np.float32).reshape(-1, 1, 2) for i in image_points],
        tuple(size), None, None, flags=0, criteria=crit)
    rms, k, dist, std_int = out[0], out[1], out[2].ravel(), out[5].ravel()
    cam = cm.Camera(k[0, 0], k[1, 1], k[0, 2], k[1, 2], list(dist[:5]))
    # stdDeviationsIntrinsics: fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, ...
    std = dict(zip(cm.PARAMETERS, map(float, std_int[:len(cm.PARAMETERS)])))
    return cam, std, float(rms)


def run_ours(d, truth, args):
    photos = sorted(str(d / v["qr_image"]) for v in truth["views"])
    cmd = ["taskset", "-c", "0", str(args.qrpose_bin), "calibrate", "--marker-size-mm",
           str(truth["code"]["size_mm"]), "--model", "plumb_bob"] + photos
    with Clock() as clock:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        return {"ok": False, "error": (p.stderr or p.stdout).strip()[-500:]}
    r = json.loads(p.stdout)
    c = r["camera"]
    cam = cm.Camera(c["fx_px"], c["fy_px"], c["cx_px"], c["cy_px"],
                    c["distortion"]["coefficients"])
    std = {k: r["std"][k] for k in cm.PARAMETERS[:4]}
    std.update(zip(cm.PARAMETERS[4:], r["std"]["coefficients"]))
    views = r.get("views") or []
    used = sum(1 for v in views if v.get("used", v.get("status") != "dropped"))
    return {"ok": True, "camera": cam, "std": std, "cpu_s": clock.cpu_s, "wall_s": clock.wall_s,
            "views": used, "warnings": [w.get("name", w) if isinstance(w, dict) else w
                                        for w in r.get("warnings", [])],
            "rms_px": r.get("reprojection_rms_px"),
            "residual_correlation": cm.residual_correlation(views),
            "tilts_deg": [v["tilt_deg"] for v in truth["views"]],
            "left_out": [{"index": i, "reason": v.get("dropped"),
                          "tilt_deg": truth["views"][i]["tilt_deg"]}
                         for i, v in enumerate(views)
                         if not v.get("used", v.get("status") != "dropped")]}


def run_checkerboard(d, truth, args):
    sq = truth["board"]["size_mm"] / truth["board"]["squares"]
    grid = [[(k % BOARD_INNER[0]) * sq, (k // BOARD_INNER[0]) * sq, 0.0]
            for k in range(BOARD_INNER[0] * BOARD_INNER[1])]
    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_ACCURACY
    objs, imgs, corner_err = [], [], []
    with Clock() as clock:
        for v in truth["views"]:
            image = cv2.imread(str(d / v["board_image"]), cv2.IMREAD_GRAYSCALE)
            found, corners = cv2.findChessboardCornersSB(image, BOARD_INNER, flags=flags)
            if not found:
                continue
            corners = corners.reshape(-1, 2)
            objs.append(grid)
            imgs.append(corners)
            corner_err += cm.nearest_errors(corners, v["board"]["inner_corners_px"])
        if len(objs) < 3:
            return {"ok": False, "error": f"board found in {len(objs)} photos"}
        cam, std, rms = calibrate_cv(objs, imgs, truth["image_size_px"])
    return {"ok": True, "camera": cam, "std": std, "cpu_s": clock.cpu_s, "wall_s": clock.wall_s,
            "views": len(objs), "rms_px": rms, "corner_rms_px": cm.rms(corner_err)}


def qrpose_corners(path, args):
    cmd = ["taskset", "-c", "0", str(args.qrpose_bin), "estimate", "--image", str(path),
           "--fx-px", "1280", "--fy-px", "1280", "--cx-px", "639.5", "--cy-px", "359.5",
           "--marker-size-mm", "120"]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if p.returncode != 0:
        return None
    markers = [m for m in json.loads(p.stdout).get("markers", []) if m.get("corners_px")]
    return np.array(markers[0]["corners_px"], float) if markers else None


def opencv_corners(path, detector):
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    _, points, _ = detector.detectAndDecode(image)
    return None if points is None else points.reshape(-1, 2).astype(float)


def run_qr4(d, truth, args, source):
    side = truth["code"]["size_mm"]
    square = [[0.0, 0.0, 0.0], [side, 0.0, 0.0], [side, side, 0.0], [0.0, side, 0.0]]
    detector = cv2.QRCodeDetector()
    objs, imgs, corner_err = [], [], []
    with Clock() as clock:
        for v in truth["views"]:
            path = d / v["qr_image"]
            q = qrpose_corners(path, args) if source == "qrpose" else opencv_corners(path, detector)
            if q is None or len(q) != 4:
                continue
            objs.append(square)
            imgs.append(q)
            corner_err += list(np.linalg.norm(q - np.array(v["qr"]["corners_px"]), axis=1))
        if len(objs) < 3:
            return {"ok": False, "error": f"code found in {len(objs)} photos"}
        try:
            cam, std, rms = calibrate_cv(objs, imgs, truth["image_size_px"])
        except cv2.error as e:
            return {"ok": False, "error": str(e).strip()[-300:]}
    return {"ok": True, "camera": cam, "std": std, "cpu_s": clock.cpu_s, "wall_s": clock.wall_s,
            "views": len(objs), "rms_px": rms, "corner_rms_px": cm.rms(corner_err)}


def has_calibrate(binary):
    p = subprocess.run([str(binary), "calibrate", "--help"], capture_output=True, text=True)
    return p.returncode == 0


def run_set(seed, methods, args):
    d, truth, true_cam = load_set(seed)
    out = {"seed": seed, "load_before": os.getloadavg()[0]}
    for m in methods:
        if m == "ours":
            r = run_ours(d, truth, args)
        elif m == "checkerboard":
            r = run_checkerboard(d, truth, args)
        else:
            r = run_qr4(d, truth, args, m.split("-")[1])
        if r["ok"]:
            r.update(cm.errors(true_cam, r["camera"], truth["image_size_px"], r["std"]))
            r["camera"] = r["camera"].as_dict()
        out[m] = r
        status = (f"focal {r['focal_pct']:.3f} %, pp {r['pp_px']:.2f} px, "
                  f"field {r['field_p95_px']:.2f} px, {r['cpu_s']:.2f} s CPU"
                  if r["ok"] else f"FAILED: {r['error']}")
        print(f"  set {seed:2d} {m:13s} {status}", file=sys.stderr, flush=True)
    out["load_after"] = os.getloadavg()[0]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sets", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--profile", choices=sorted(PROFILES), default="release",
                    help="cargo profile of the example and of the default --qrpose-bin")
    ap.add_argument("--qrpose-bin", type=Path,
                    help="default: the qrpose binary of --profile in $CARGO_TARGET_DIR")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    methods = [m for m in args.methods.split(",") if m]
    unknown = set(methods) - set(METHODS)
    if unknown:
        ap.error(f"unknown methods {sorted(unknown)}; known: {METHODS}")
    seeds = list(range(args.first_seed, args.first_seed + args.sets))
    if args.qrpose_bin is None:
        args.qrpose_bin = TARGET / PROFILES[args.profile] / "qrpose"
    render_sets(seeds, args.profile)
    if "ours" in methods and not has_calibrate(args.qrpose_bin):
        print(f"SKIPPED ours: {args.qrpose_bin} has no `calibrate` subcommand (the points "
              "extraction is not in this build); build this tree with "
              "`cargo build --release`.", file=sys.stderr)
        methods.remove("ours")
    on_cpu0()
    env = {"machine": platform.node(), "cpu": cm.cpu_model(), "cores": os.cpu_count(),
           "opencv": cv2.__version__, "numpy": np.__version__, "qrpose_bin": str(args.qrpose_bin),
           "load_start": os.getloadavg(), "date": time.strftime("%Y-%m-%d %H:%M:%S %z")}
    results = [run_set(s, methods, args) for s in seeds]
    env["load_end"] = os.getloadavg()
    print(cm.report(results, methods, env, TARGETS, TIME_TARGET_S))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"environment": env, "sets": results}, indent=1))


if __name__ == "__main__":
    main()
