#!/usr/bin/env python3
"""Shared pieces of scripts/photo_bench.py and scripts/nocode_bench.py (real camera
frames): the venv, running qrpose (`POST /v1/pose/image` to a `qrpose serve` kept running, or
`qrpose estimate --image`) and zxing-cpp (PyPI) on the same bytes,
quadrilateral IoU and label matching, percentiles. Not meant to be run by itself.

Conventions (the same on both sides, so that both readers see the same pixels):

* EXIF orientation is NOT applied. qrpose's decoder (crates/qrpose-detect/src/decode: zune-jpeg
  luma, or the `image` crate for PNG/WebP) ignores the EXIF Orientation tag, and so does
  `PIL.Image.open(...).convert('L')` (Pillow only rotates on `ImageOps.exif_transpose`). The
  boofcv-dev labels are in the stored (un-rotated) pixel grid too: the four `lots/` photos
  tagged Orientation=6 have labels that only fit the raw 4032x3024 grid.
* qrpose time = the answer's own `timing_ms.decode + timing_ms.detect` (HTTP, process
  start-up, file reading, pose and JSON are not counted); its passes
  (`timing_ms.detect_passes`) are kept in the JSON details. By default (`--qrpose-via
  server`) the answers come from one `qrpose serve` started for the run and warmed by one
  request: a long-lived process, as the service runs and as zxing-cpp runs in this one.
  `--qrpose-via cli` runs `qrpose estimate` per image instead; a fresh process pays its
  first page faults and cold caches inside timing_ms (on 2026-11-28: no-code crops 1.25×
  zxing-cpp's median that way, 1.03× served; docs/measurements/detection.md). zxing-cpp time = `time.perf_counter()` around a decode to 8-bit
  grey + `zxingcpp.read_barcodes(..., formats=QRCode)` with the library's default options
  (try harder, rotate, invert, downscale), as scripts/speed_zxing_pypi.py; the file's bytes
  are read into memory before the clock starts, on both sides. The decode is OpenCV's
  `cv2.imdecode(..., cv2.IMREAD_GRAYSCALE | cv2.IMREAD_IGNORE_ORIENTATION)` (libjpeg-turbo,
  luma straight from the JPEG: what an integrator would run; without the second flag OpenCV
  would turn EXIF-tagged photos, which qrpose does not). Pillow's decode (RGB, then convert('L'), or with
  `--zxing-decode draft` JPEG luma directly) is timed too, on the same bytes, and its time
  plus the same `read_barcodes` time is reported as the Pillow figure (`ms_pillow`);
  `--zxing-decode convert|draft` makes Pillow's the primary figure instead.
* Percentiles are nearest-rank, `sorted(v)[round((n - 1) * q)]`, as scripts/accuracy_images.py.

The venv is target/photo-venv (zxing-cpp, numpy, Pillow, opencv-python-headless from PyPI),
created on first use; the scripts re-execute themselves inside it.
"""
import io, json, os, shlex, statistics, subprocess, sys, time, venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / "target" / "photo-venv"
DEFAULT_BIN = ROOT / "target" / "release" / "qrpose"
PACKAGES = ["zxing-cpp", "numpy", "Pillow", "opencv-python-headless"]


def ensure_venv():
    """Creates target/photo-venv if needed and re-executes the calling script inside it."""
    py = VENV / "bin" / "python3"
    if not py.exists():
        venv.create(VENV, with_pip=True)
    if Path(sys.prefix).resolve() == VENV.resolve() or os.environ.get("QRPOSE_PHOTO_VENV") == "1":
        return
    probe = subprocess.run([str(py), "-c", "import zxingcpp, numpy, PIL, cv2"], capture_output=True)
    if probe.returncode != 0:
        subprocess.check_call([str(py), "-m", "pip", "install", "-q"] + PACKAGES)
    os.environ["QRPOSE_PHOTO_VENV"] = "1"
    os.execv(str(py), [str(py)] + sys.argv)


def add_manifest_args(ap):
    """The photo set: a folder with manifest.json, and which of its photos."""
    ap.add_argument("manifest_dir", help="folder with manifest.json")
    ap.add_argument("--only", nargs="+", metavar="CATEGORY", help="these categories only")
    ap.add_argument("--limit", type=int, help="at most N photos per category (manifest order)")


def add_common_args(ap):
    ap.add_argument("--qrpose-bin", default=str(DEFAULT_BIN),
                    help="the qrpose binary (default: target/release/qrpose)")
    ap.add_argument("--qrpose-flag", action="append", default=[], metavar="FLAG",
                    help="extra argument(s) for `qrpose estimate`, forwarded as given (served: "
                         "as query parameters, --name value -> name=value); repeatable; "
                         "a value with spaces is split like a shell would "
                         "(--qrpose-flag=--detector=rxing, --qrpose-flag='--effort fast')")
    ap.add_argument("--timeout", type=float, default=60.0,
                    help="seconds before a qrpose run counts as failed (default 60)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="zxing-cpp runs per image; its time is their median (default 1)")
    ap.add_argument("--qrpose-repeat", type=int, default=1,
                    help="qrpose runs per image; its time is their median, its "
                         "markers those of the first run (default 1)")
    ap.add_argument("--qrpose-via", choices=["server", "cli"], default="server",
                    help="server (default): POST /v1/pose/image to one `qrpose serve` kept "
                         "running, warmed by one request, as an integrator runs it and as "
                         "zxing-cpp runs here; cli: `qrpose estimate --image`, a new process "
                         "per image (cold: its first page faults count)")
    ap.add_argument("--zxing-decode", choices=["opencv", "convert", "draft"], default="opencv",
                    help="decode timed for zxing-cpp's primary figure: OpenCV's IMREAD_GRAYSCALE "
                         "(default), Pillow's RGB then convert('L'), or Pillow's JPEG luma via "
                         "Image.draft('L'); the other of OpenCV / Pillow is reported beside it")
    ap.add_argument("--no-zxing", action="store_true", help="run qrpose only")
    ap.add_argument("--json", metavar="OUT.json", help="write per-image details here")


def qrpose_flags(args):
    out = []
    for f in args.qrpose_flag:
        out += shlex.split(f)
    return out


def image_size(path_or_bytes):
    """(width, height) from the header only (Pillow opens lazily)."""
    from PIL import Image
    src = io.BytesIO(path_or_bytes) if isinstance(path_or_bytes, (bytes, bytearray)) else path_or_bytes
    with Image.open(src) as im:
        return im.size


def exif_orientation(path):
    from PIL import Image
    with Image.open(path) as im:
        return im.getexif().get(0x0112)


def run_qrpose(binary, image_path, width, height, flags, timeout, repeat=1, intrinsics=None,
               via="server"):
    """qrpose on one image, `repeat` times: the first run's result, with ms, decode_ms
    and detect_ms the medians over the runs (runs_ms lists them; a failure in any run makes
    the whole a failure; `note` says when the decoded payloads differed between runs).
    intrinsics: optional (fx, fy, cx, cy) in px instead of F = max(w, h) and the centre
    (scripts/multicode_bench.py passes the renderer's camera). via "server": `POST
    /v1/pose/image` to one `qrpose serve` kept running (what an integrator runs: a warm
    process, as zxing-cpp is timed in this one); "cli": `qrpose estimate --image`, a new
    process per run (its first page faults and cold caches are inside timing_ms)."""
    once = _run_qrpose_served if via == "server" else _run_qrpose_once
    first = once(binary, image_path, width, height, flags, timeout, intrinsics)
    if repeat <= 1 or not first["ok"]:
        first["runs_ms"] = [first["ms"]]
        return first
    runs = [first]
    for _ in range(repeat - 1):
        r = once(binary, image_path, width, height, flags, timeout, intrinsics)
        if not r["ok"]:
            r["runs_ms"] = [x["ms"] for x in runs] + [None]
            return r
        runs.append(r)
    for k in ("ms", "decode_ms", "detect_ms", "wall_ms"):
        first[k] = statistics.median(x[k] for x in runs)
    first["runs_ms"] = [x["ms"] for x in runs]
    payloads = {tuple(sorted(m["payload"] or "" for m in x["markers"])) for x in runs}
    if len(payloads) > 1:
        first["note"] = f"decoded payloads differ between the {repeat} runs"
    return first


def _intrinsics(width, height, intrinsics):
    """(fx, fy, cx, cy) px: `intrinsics` when given, else F = max(w, h) and the centre."""
    f = float(max(width, height))
    return intrinsics or (f, f, (width - 1) / 2, (height - 1) / 2)


def _no_result():
    """A run's result before anything is known: not ok, nothing read."""
    return {"ok": False, "error": None, "ms": None, "decode_ms": None, "detect_ms": None,
            "wall_ms": None, "markers": [], "size": None}


_SERVERS = {}


def _server_for(binary):
    """The `qrpose serve` of `binary` (started on first use on a free loopback port, its log
    under target/photo-server/, stopped at exit), warmed by one untimed request."""
    if binary in _SERVERS:
        return _SERVERS[binary]
    import atexit
    from stream_server import Server
    server = Server.start(str(binary), [], ROOT / "target" / "photo-server")
    atexit.register(server.stop)
    _SERVERS[binary] = server
    buf = io.BytesIO()
    from PIL import Image
    Image.new("L", (640, 480), 255).save(buf, "JPEG")
    _post_image(server.url, buf.getvalue(), {"fx_px": 640, "fy_px": 640, "cx_px": 319.5,
                                              "cy_px": 239.5, "marker_size_mm": 50}, 60)
    return server


def flags_as_query(flags):
    """`qrpose estimate` flags as the query parameters of POST /v1/pose/image: `--name value`
    and `--name=value` give name=value (dashes to underscores), a lone `--name` name=true."""
    query, i = {}, 0
    while i < len(flags):
        f = flags[i]
        if not f.startswith("--"):
            raise SystemExit(f"cannot turn {f!r} into a query parameter")
        name, eq, value = f[2:].partition("=")
        if not eq:
            if i + 1 < len(flags) and not flags[i + 1].startswith("--"):
                value, i = flags[i + 1], i + 1
            else:
                value = "true"
        query[name.replace("-", "_")] = value
        i += 1
    return query


def _post_image(url, data, query, timeout):
    """POST the bytes as the raw body; (status, parsed JSON)."""
    import urllib.error, urllib.parse, urllib.request
    ctype = "image/png" if data[:8] == b"\x89PNG\r\n\x1a\n" else "image/jpeg"
    req = urllib.request.Request(f"{url}/v1/pose/image?{urllib.parse.urlencode(query)}",
                                 data=data, method="POST", headers={"Content-Type": ctype})
    try:
        with urllib.request.urlopen(req, timeout=timeout) as resp:
            return resp.status, json.loads(resp.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"{}")


def _run_qrpose_served(binary, image_path, width, height, flags, timeout, intrinsics=None):
    """One POST /v1/pose/image to the kept server; the same dict as `_run_qrpose_once`."""
    fx, fy, cx, cy = _intrinsics(width, height, intrinsics)
    query = {"fx_px": repr(fx), "fy_px": repr(fy), "cx_px": repr(cx), "cy_px": repr(cy),
             "marker_size_mm": "50", **flags_as_query(flags)}
    out = _no_result()
    server = _server_for(binary)
    data = Path(image_path).read_bytes()
    t0 = time.perf_counter()
    try:
        status, resp = _post_image(server.url, data, query, timeout)
    except OSError as e:
        out["wall_ms"] = 1e3 * (time.perf_counter() - t0)
        out["error"] = f"request failed: {e}"
        return out
    out["wall_ms"] = 1e3 * (time.perf_counter() - t0)
    if status != 200:
        out["error"] = f"status {status}: {json.dumps(resp)[:300]}"
        return out
    return _read_answer(resp, out)


def _run_qrpose_once(binary, image_path, width, height, flags, timeout, intrinsics=None):
    """One `qrpose estimate --image` run. Returns a dict: ok, error, ms (decode + detect),
    decode_ms, detect_ms, wall_ms, markers [{payload, corners}], size."""
    fx, fy, cx, cy = _intrinsics(width, height, intrinsics)
    cmd = [str(binary), "estimate", "--image", str(image_path),
           "--fx-px", repr(fx), "--fy-px", repr(fy),
           "--cx-px", repr(cx), "--cy-px", repr(cy),
           "--marker-size-mm", "50"] + list(flags)
    out = _no_result()
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        out["wall_ms"] = 1e3 * (time.perf_counter() - t0)
        out["error"] = f"timeout after {timeout:g} s"
        return out
    out["wall_ms"] = 1e3 * (time.perf_counter() - t0)
    if proc.returncode != 0:
        err = proc.stderr.decode("utf-8", "replace").strip().replace("\n", " ")
        out["error"] = f"exit {proc.returncode}: {err[:300]}"
        return out
    try:
        resp = json.loads(proc.stdout)
    except ValueError as e:
        out["error"] = f"unreadable output ({type(e).__name__}: {e})"
        return out
    return _read_answer(resp, out)


def _read_answer(resp, out):
    """Fills `out` from an answer of POST /v1/pose/image (or `qrpose estimate`'s)."""
    try:
        timing = resp["timing_ms"]
        out["decode_ms"] = float(timing["decode"])
        out["detect_ms"] = float(timing["detect"])
        out["ms"] = out["decode_ms"] + out["detect_ms"]
        out["size"] = [resp["image"]["width_px"], resp["image"]["height_px"]]
        out["warnings"] = list(resp.get("warnings") or [])
        out["passes"] = [[p.get("pass"), p.get("ms"), p.get("decoded")]
                         for p in timing.get("detect_passes") or []]
        for m in resp.get("markers") or []:
            out["markers"].append({"payload": m.get("payload"),
                                   "corners": [[float(u), float(v)] for u, v in m["corners_px"]]})
    except (ValueError, KeyError, TypeError) as e:
        out["error"] = f"unreadable output ({type(e).__name__}: {e})"
        return out
    out["ok"] = True
    return out


def _decode_opencv(data):
    import cv2, numpy as np
    # IMREAD_IGNORE_ORIENTATION: OpenCV would otherwise turn the photo by its EXIF tag, which
    # qrpose does not (and the labels are in the stored grid); turning costs time too.
    return cv2.imdecode(np.frombuffer(data, dtype=np.uint8),
                        cv2.IMREAD_GRAYSCALE | cv2.IMREAD_IGNORE_ORIENTATION)


def _decode_pillow(data, mode):
    from PIL import Image
    im = Image.open(io.BytesIO(data))
    if mode == "draft":
        im.draft("L", im.size)
    return im.convert("L")


def run_zxing(data, repeat=1, mode="opencv"):
    """zxing-cpp on encoded bytes: a decode to grey + read_barcodes, timed together, with
    OpenCV's decode (mode "opencv") or Pillow's ("convert", "draft") as the primary figure
    `ms`; the other decoder is timed on the same bytes too and `ms_pillow` / `ms_opencv` is
    its decode time plus the same read time. Returns a dict: ok, error, ms (median over
    `repeat`), ms_opencv, ms_pillow, decode_ms, read_ms, runs_ms, results [{payload, corners}]."""
    import zxingcpp
    pillow_mode = "convert" if mode == "opencv" else mode
    runs, reads, cv_dec, pil_dec, results, error = [], [], [], [], [], None
    for _ in range(max(1, repeat)):
        try:
            t0 = time.perf_counter()
            gray = _decode_opencv(data)
            t1 = time.perf_counter()
            if gray is None:
                raise ValueError("OpenCV cannot decode the bytes")
            found = zxingcpp.read_barcodes(gray, formats=zxingcpp.BarcodeFormat.QRCode)
            t2 = time.perf_counter()
            _decode_pillow(data, pillow_mode)
            t3 = time.perf_counter()
        except Exception as e:  # a reader crash on one image counts as nothing read
            return {"ok": False, "error": f"{type(e).__name__}: {e}", "ms": None,
                    "ms_opencv": None, "ms_pillow": None, "runs_ms": runs, "results": []}
        cv_dec.append(1e3 * (t1 - t0))
        reads.append(1e3 * (t2 - t1))
        pil_dec.append(1e3 * (t3 - t2))
        runs.append(1e3 * (t2 - t0) if mode == "opencv" else 1e3 * (t3 - t1))
        results = []
        for b in found:
            p = b.position
            text = b.text if b.valid else None
            raw = bytes(b.bytes) if b.valid else b""
            results.append({"payload": text if (text or raw) else None,
                            "corners": [[p.top_left.x, p.top_left.y], [p.top_right.x, p.top_right.y],
                                        [p.bottom_right.x, p.bottom_right.y],
                                        [p.bottom_left.x, p.bottom_left.y]]})
    read = statistics.median(reads)
    ms_opencv = statistics.median(cv_dec) + read
    ms_pillow = statistics.median(pil_dec) + read
    return {"ok": True, "error": error, "ms": ms_opencv if mode == "opencv" else ms_pillow,
            "ms_opencv": ms_opencv, "ms_pillow": ms_pillow, "read_ms": read,
            "decode_ms": statistics.median(cv_dec), "pillow_decode_ms": statistics.median(pil_dec),
            "pillow_decode": pillow_mode, "runs_ms": runs, "results": results}


def warm_up_zxing():
    """One untimed read, so that the first timed image does not pay for the library's start."""
    import zxingcpp
    from PIL import Image
    zxingcpp.read_barcodes(Image.new("L", (64, 64), 255), formats=zxingcpp.BarcodeFormat.QRCode)
    buf = io.BytesIO()
    Image.new("L", (64, 64), 255).save(buf, "JPEG")
    _decode_opencv(buf.getvalue())
    _decode_pillow(buf.getvalue(), "convert")


# --- geometry -------------------------------------------------------------------------------

def _cross(o, a, b):
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def convex_hull(points):
    """Counter-clockwise convex hull (monotone chain). Makes the IoU independent of the corner
    order a reader uses, and of a self-intersecting (bow-tie) order."""
    pts = sorted(set((float(x), float(y)) for x, y in points))
    if len(pts) <= 2:
        return pts
    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def area(poly):
    n = len(poly)
    return abs(sum(poly[i][0] * poly[(i + 1) % n][1] - poly[(i + 1) % n][0] * poly[i][1]
                   for i in range(n))) / 2 if n >= 3 else 0.0


def _clip(subject, clip):
    """Sutherland-Hodgman: subject ∩ clip, both convex and counter-clockwise."""
    out = subject
    n = len(clip)
    for i in range(n):
        a, b = clip[i], clip[(i + 1) % n]
        inp, out = out, []
        if not inp:
            break
        for j in range(len(inp)):
            p, q = inp[j], inp[(j + 1) % len(inp)]
            pin, qin = _cross(a, b, p) >= 0, _cross(a, b, q) >= 0
            if pin:
                out.append(p)
            if pin != qin:
                dx, dy = q[0] - p[0], q[1] - p[1]
                ex, ey = b[0] - a[0], b[1] - a[1]
                den = ex * dy - ey * dx
                if den != 0:
                    t = (ey * (p[0] - a[0]) - ex * (p[1] - a[1])) / den
                    out.append((p[0] + t * dx, p[1] + t * dy))
    return out


def quad_iou(q1, q2):
    """Intersection over union of the convex hulls of two quadrilaterals."""
    h1, h2 = convex_hull(q1), convex_hull(q2)
    a1, a2 = area(h1), area(h2)
    if a1 <= 0 or a2 <= 0:
        return 0.0
    x1 = [p[0] for p in h1]; y1 = [p[1] for p in h1]
    x2 = [p[0] for p in h2]; y2 = [p[1] for p in h2]
    if max(x1) < min(x2) or max(x2) < min(x1) or max(y1) < min(y2) or max(y2) < min(y1):
        return 0.0
    inter = area(_clip(h1, h2))
    return inter / (a1 + a2 - inter)


def match_labels(labels, detections, threshold=0.5):
    """Greedy one-to-one matching, highest IoU first, of labelled quadrilaterals to decoded
    detections ({payload, corners}; undecoded ones are ignored). Returns (matched: list of
    (label index, detection index, iou), unmatched decoded detection indices)."""
    decoded = [i for i, d in enumerate(detections) if d.get("payload")]
    pairs = []
    for li, lab in enumerate(labels):
        for di in decoded:
            v = quad_iou(lab, detections[di]["corners"])
            if v >= threshold:
                pairs.append((v, li, di))
    pairs.sort(reverse=True)
    used_l, used_d, matched = set(), set(), []
    for v, li, di in pairs:
        if li in used_l or di in used_d:
            continue
        used_l.add(li); used_d.add(di)
        matched.append((li, di, round(v, 4)))
    return sorted(matched), [di for di in decoded if di not in used_d]


def match_texts(expected, detections):
    """For manifests without corners (e.g. the zxing-cpp sample set): expected payloads
    matched to decoded payloads as multisets. Returns (matched expected indices, extras)."""
    pool = [d["payload"] for d in detections if d.get("payload")]
    matched = []
    for i, t in enumerate(expected):
        if t in pool:
            pool.remove(t)
            matched.append(i)
    return matched, len(pool)


# --- statistics -----------------------------------------------------------------------------

def pct(values, q):
    v = sorted(x for x in values if x is not None)
    if not v:
        return float("nan")
    return v[round((len(v) - 1) * q)]


def median(values):
    v = [x for x in values if x is not None]
    return statistics.median(v) if v else float("nan")


def fmt_ms(x):
    if x != x:  # nan
        return "–"
    return f"{x:.0f}" if x >= 100 else f"{x:.1f}"


def ratio_stats(pairs):
    """Ratios of paired times [(ours, theirs)]: of the medians, the median and p90 / p95 of
    the per-item ratios, of the totals; None without pairs."""
    pairs = [(q, z) for q, z in pairs if q and z]
    if not pairs:
        return None
    ratios = [q / z for q, z in pairs]
    return {"n": len(pairs),
            "of_medians": median([q for q, _ in pairs]) / median([z for _, z in pairs]),
            "median": median(ratios), "p90": pct(ratios, 0.90), "p95": pct(ratios, 0.95),
            "of_totals": sum(q for q, _ in pairs) / sum(z for _, z in pairs)}


def environment(args, binary):
    """What a reader of the numbers needs to rerun them."""
    import PIL, zxingcpp, cv2
    try:
        from importlib.metadata import version
        zx = version("zxing-cpp")
    except Exception:
        zx = getattr(zxingcpp, "__version__", "?")
    b = Path(binary)
    try:
        git = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip() != ""
    except OSError:
        git, dirty = "?", False
    return {
        "command": " ".join(shlex.quote(a) for a in sys.argv),
        "qrpose_bin": str(b),
        "qrpose_bin_mtime": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(b.stat().st_mtime))
        if b.exists() else None,
        "qrpose_flags": qrpose_flags(args),
        "git_head": git + (" (working tree modified)" if dirty else ""),
        "zxing_cpp": zx,
        "pillow": PIL.__version__,
        "opencv": cv2.__version__,
        "zxing_decode": args.zxing_decode,
        "repeat": args.repeat,
        "qrpose_repeat": args.qrpose_repeat,
        "qrpose_via": args.qrpose_via,
        "exif_orientation": "not applied on either side (qrpose ignores it; Pillow does too)",
        "loadavg_start": os.getloadavg(),
        "cpus": os.cpu_count(),
    }
