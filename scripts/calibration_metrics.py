"""Measures of a fitted camera against the truth, and the report, for
scripts/calibration_compare.py. Needs numpy and OpenCV (cv2), which that script's
virtual environment provides.

* Cameras are plumb_bob: fx, fy, cx, cy (px, integer = pixel centre) and OpenCV's
  (k1, k2, p1, p2, k3).
* Distortion field (as qrpose_calib::compare): d(p) = p - K D^-1(K^-1 p), each camera with its
  own K; the field error is a quantile of |d_true(p) - d_fit(p)| over a grid of 96 x 54
  pixels spanning the centred inner 90 % of the image (grid point i of n at
  (0.05 + 0.9 i / (n - 1)) size - 0.5), nearest rank round(q (n - 1)). D^-1 is OpenCV's
  undistortPointsIter run to 1e-14.
* Projection difference: |pi_fit(ray_true(p)) - p| over the same grid.
"""
import math
from pathlib import Path

import cv2
import numpy as np

SAMPLES_LONG_SIDE = 96
INNER = 0.9
QUANTILE = 0.95
# The 95 % range of the RMS of 20 standard normal draws: sqrt(chi2(20) quantiles / 20).
Z_RMS_RANGE_20 = (0.69, 1.31)
# The parameters with a reported standard deviation, in OpenCV's order (plumb_bob).
PARAMETERS = ("fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "p1", "p2", "k3")


class Camera:
    def __init__(self, fx, fy, cx, cy, coefficients):
        self.fx, self.fy, self.cx, self.cy = map(float, (fx, fy, cx, cy))
        self.dist = np.array(list(coefficients) + [0.0] * (5 - len(coefficients)), float)[:5]

    def k(self):
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], float)

    def as_dict(self):
        return {"fx_px": self.fx, "fy_px": self.fy, "cx_px": self.cx, "cy_px": self.cy,
                "coefficients": [float(c) for c in self.dist]}

    def rays(self, pixels):
        """Normalised undistorted (x, y) of each pixel."""
        crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-14)
        pts = np.asarray(pixels, np.float64).reshape(-1, 1, 2)
        return cv2.undistortPointsIter(pts, self.k(), self.dist, None, None, crit).reshape(-1, 2)

    def displacement(self, pixels):
        n = self.rays(pixels)
        ideal = np.c_[self.fx * n[:, 0] + self.cx, self.fy * n[:, 1] + self.cy]
        return np.asarray(pixels) - ideal

    def project(self, rays):
        pts = np.c_[rays, np.ones(len(rays))].reshape(-1, 1, 3)
        out, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), self.k(), self.dist)
        return out.reshape(-1, 2)


def grid(size):
    w, h = size
    long = max(w, h)
    steps = [int(min(max(round(SAMPLES_LONG_SIDE * s / long), 2), SAMPLES_LONG_SIDE)) for s in (w, h)]
    margin = 0.5 * (1 - INNER)
    us = [(margin + INNER * i / (steps[0] - 1)) * w - 0.5 for i in range(steps[0])]
    vs = [(margin + INNER * j / (steps[1] - 1)) * h - 0.5 for j in range(steps[1])]
    return np.array([[u, v] for v in vs for u in us], float)


def quantile(values, q=QUANTILE):
    v = np.sort(np.asarray(values, float))
    return float(v[int(math.floor(q * (len(v) - 1) + 0.5))])


def errors(true, fit, size, std):
    """Every measure of `fit` against `true` (Camera), with the normalised errors of fit's
    reported standard deviations `std` (PARAMETERS)."""
    p = grid(size)
    field = np.linalg.norm(true.displacement(p) - fit.displacement(p), axis=1)
    moved = np.linalg.norm(fit.project(true.rays(p)) - p, axis=1)
    fx_pct, fy_pct = 100 * (fit.fx / true.fx - 1), 100 * (fit.fy / true.fy - 1)
    diff = {"fx_px": fit.fx - true.fx, "fy_px": fit.fy - true.fy,
            "cx_px": fit.cx - true.cx, "cy_px": fit.cy - true.cy}
    diff.update(zip(PARAMETERS[4:], fit.dist - true.dist))
    return {
        "fx_error_pct": fx_pct, "fy_error_pct": fy_pct,
        "focal_pct": max(abs(fx_pct), abs(fy_pct)),
        "pp_px": math.hypot(diff["cx_px"], diff["cy_px"]),
        "field_p95_px": quantile(field), "proj_p95_px": quantile(moved),
        "std_fx_pct": 100 * std["fx_px"] / fit.fx,
        "z": {k: (float(diff[k]) / std[k] if std.get(k, 0) > 0 else float("nan")) for k in diff},
    }


# Distance bins, px, of the residual correlation of ours (see residual_correlation).
CORRELATION_BINS_PX = (0.0, 6.0, 15.0, 25.0, 40.0)


def residual_correlation(views):
    """The correlation of the residuals of two points of one view against their distance:
    for each bin of CORRELATION_BINS_PX, sum over pairs (p, q) of the used views of
    e_p . e_q, over the pair count times the mean |e|^2 (views: the `views` of a calibrate
    answer, with `image_points`). 1: the pair's errors are the same; 0: unrelated."""
    bins = np.asarray(CORRELATION_BINS_PX)
    num, count, squares, points = np.zeros(len(bins) - 1), np.zeros(len(bins) - 1), 0.0, 0
    for v in views:
        pts = [p for p in v.get("image_points") or [] if p.get("residual_px") is not None]
        if not v.get("used") or len(pts) < 2:
            continue
        xy = np.array([p["image_px"] for p in pts], float)
        e = np.array([p["residual_px"] for p in pts], float)
        squares, points = squares + float((e ** 2).sum()), points + len(e)
        i, j = np.triu_indices(len(e), 1)
        d = np.linalg.norm(xy[i] - xy[j], axis=1)
        dots = (e[i] * e[j]).sum(axis=1)
        k = np.digitize(d, bins) - 1
        inside = (k >= 0) & (k < len(num))
        np.add.at(num, k[inside], dots[inside])
        np.add.at(count, k[inside], 1)
    mean_square = squares / points if points else float("nan")
    return [float(n / c / mean_square) if c else float("nan") for n, c in zip(num, count)]


def nearest_errors(found, truth):
    """Distance of each found point to the nearest true point, px."""
    f, t = np.asarray(found, float), np.asarray(truth, float)
    return list(np.linalg.norm(f[:, None, :] - t[None, :, :], axis=2).min(axis=1))


def rms(values):
    v = [x for x in values if x == x]
    return math.sqrt(sum(x * x for x in v) / len(v)) if v else float("nan")


def cpu_model():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


# --- the report -----------------------------------------------------------------------------

def _ok(results, m):
    return [s[m] for s in results if s.get(m, {}).get("ok")]


def _median(v):
    v = sorted(v)
    return float("nan") if not v else (v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2]))


def summary(results, m):
    rs = _ok(results, m)
    if not rs:
        return None
    col = lambda k: [r[k] for r in rs]  # noqa: E731
    s = {"sets": len(rs), "failed": sum(1 for x in results if m in x) - len(rs),
         "views_min": min(col("views")), "std_fx_pct_mean": sum(col("std_fx_pct")) / len(rs),
         "cpu_s_median": _median(col("cpu_s")), "cpu_s_max": max(col("cpu_s")),
         "wall_s_median": _median(col("wall_s"))}
    for k in ("focal_pct", "pp_px", "field_p95_px", "proj_p95_px"):
        s[k + "_rms"], s[k + "_max"] = rms(col(k)), max(col(k))
    s["z_rms"] = {k: rms([r["z"][k] for r in rs]) for k in PARAMETERS}
    corr = [r["residual_correlation"] for r in rs if r.get("residual_correlation")]
    s["residual_correlation"] = [float(np.nanmean(c)) for c in zip(*corr)] if corr else None
    return s


def _first_set_table(results, methods):
    first = results[0]
    lines = [f"First set (seed {first['seed']}):", "",
             "| method | views | fx | fy | cx | cy | k1 | k2 | p1 | p2 | k3 | focal error % | "
             "principal point error px | field p95 px | projection p95 px | reprojection RMS px | "
             "corner error RMS px | CPU s | wall s |",
             "|---" * 19 + "|"]
    for m in methods:
        r = first.get(m)
        if not r or not r["ok"]:
            lines.append(f"| {m} | failed: {r['error'] if r else 'not run'} |" + " |" * 17)
            continue
        c = r["camera"]
        k = " | ".join(f"{x:.4f}" for x in c["coefficients"])
        corner = r.get("corner_rms_px")
        rms_px = r.get("rms_px")
        lines.append(
            f"| {m} | {r['views']} | {c['fx_px']:.1f} | {c['fy_px']:.1f} | {c['cx_px']:.1f} | "
            f"{c['cy_px']:.1f} | {k} | {r['focal_pct']:.3f} | {r['pp_px']:.2f} | "
            f"{r['field_p95_px']:.2f} | {r['proj_p95_px']:.2f} | "
            f"{'–' if rms_px is None else f'{rms_px:.3f}'} | "
            f"{'–' if corner is None else f'{corner:.3f}'} | {r['cpu_s']:.2f} | {r['wall_s']:.2f} |")
    return lines


def _sets_table(sums, methods, n):
    lines = [f"Over {n} sets (RMS / max over the sets; normalised error (est - true)/std, RMS):", "",
             "| method | sets (failed) | views (min) | focal error % | principal point error px | "
             "field p95 px | projection p95 px | std fx % (mean) | normalised RMS fx, fy, cx, cy, "
             "k1, k2, p1, p2, k3 | "
             "CPU s (median / max) | wall s (median) |",
             "|---" * 11 + "|"]
    for m in methods:
        s = sums.get(m)
        if not s:
            lines.append(f"| {m} | 0 |" + " |" * 9)
            continue
        z = ", ".join(f"{s['z_rms'][k]:.2f}" for k in PARAMETERS)
        pair = lambda k, f: f"{s[k + '_rms']:{f}} / {s[k + '_max']:{f}}"  # noqa: E731
        lines.append(
            f"| {m} | {s['sets']} ({s['failed']}) | {s['views_min']} | {pair('focal_pct', '.3f')} | "
            f"{pair('pp_px', '.2f')} | {pair('field_p95_px', '.2f')} | {pair('proj_p95_px', '.2f')} | "
            f"{s['std_fx_pct_mean']:.3f} | {z} | {s['cpu_s_median']:.2f} / {s['cpu_s_max']:.2f} | "
            f"{s['wall_s_median']:.2f} |")
    return lines


def _targets(sums, targets, time_target_s):
    ours, board = sums.get("ours"), sums.get("checkerboard")
    if not ours or not board:
        return ["Targets: not judged (needs both `ours` and `checkerboard`)."]
    lines = ["Targets (RMS over the sets; limit = max(1.5 x checkerboard, absolute)):", ""]
    names = {"focal_pct": "focal error %", "pp_px": "principal point error px",
             "field_p95_px": "distortion field p95 px"}
    for k, absolute in targets.items():
        limit = max(1.5 * board[k + "_rms"], absolute)
        v = ours[k + "_rms"]
        lines.append(f"- {names[k]}: ours {v:.3f}, checkerboard {board[k + '_rms']:.3f}, "
                     f"limit {limit:.3f}: {'met' if v <= limit else 'NOT met'}")
    lo, hi = Z_RMS_RANGE_20
    z = ours["z_rms"]
    inside = all(lo <= z[k] <= hi for k in z) if ours["sets"] == 20 else None
    verdict = {True: "consistent", False: "NOT all within", None: "(range is for 20 sets)"}[inside]
    lines.append(f"- stds: normalised error RMS {', '.join(f'{k} {v:.2f}' for k, v in z.items())}; "
                 f"95 % range for 20 sets {lo}-{hi}: {verdict}")
    corr = ours.get("residual_correlation")
    if corr:
        b = CORRELATION_BINS_PX
        lines.append("- ours' residual correlation of two points of a view, by distance (mean over "
                     "the sets): " + ", ".join(f"{b[i]:g}-{b[i + 1]:g} px {c:.2f}"
                                               for i, c in enumerate(corr)))
    t = ours["cpu_s_max"]
    lines.append(f"- time for 15 photos on one core: CPU median {ours['cpu_s_median']:.2f} s, "
                 f"max {t:.2f} s (wall median {ours['wall_s_median']:.2f} s): "
                 f"{'met' if t < time_target_s else 'NOT met'} (target {time_target_s} s)")
    return lines


# Photos tilted at least this much are counted apart in _left_out, deg.
STEEP_TILT_DEG = 30.0


def _left_out(results):
    """What ours left out: the photos, why, how tilted their code, against the tilts of all."""
    rs = [s["ours"] for s in results if s.get("ours", {}).get("ok") and "left_out" in s["ours"]]
    if not rs:
        return []
    out = [x for r in rs for x in r["left_out"]]
    tilts = [t for r in rs for t in r["tilts_deg"]]
    reasons = {}
    for x in out:
        reasons[x["reason"]] = reasons.get(x["reason"], 0) + 1
    steep = sum(1 for t in tilts if t >= STEEP_TILT_DEG)
    steep_out = sum(1 for x in out if x["tilt_deg"] >= STEEP_TILT_DEG)
    span = (f"; their codes tilted {min(x['tilt_deg'] for x in out):.0f}-"
            f"{max(x['tilt_deg'] for x in out):.0f} deg" if out else "")
    return [f"- ours left out {len(out)} of {len(tilts)} photos "
            f"({', '.join(f'{k} {v}' for k, v in sorted(reasons.items()))}){span}; "
            f"of the {steep} photos tilted {STEEP_TILT_DEG:g} deg or more {steep_out} left out, "
            f"of the {len(tilts) - steep} tilted less {len(out) - steep_out}"]


def report(results, methods, env, targets, time_target_s):
    sums = {m: summary(results, m) for m in methods}
    loads = [x for r in results for x in (r["load_before"], r["load_after"])]
    head = [f"Calibration comparison, {env['date']}: {len(results)} sets of 15 photos "
            f"(seeds {results[0]['seed']}-{results[-1]['seed']}), 1280 x 720; OpenCV {env['opencv']}, "
            f"numpy {env['numpy']}; {env['cpu']}, {env['cores']} cores; 1-min load average "
            f"{min(loads):.1f}-{max(loads):.1f} during the runs.",
            "Truth: fx 1000, fy 1005, cx 652, cy 349 px; k1 -0.25, k2 0.08, p1 0.001, p2 -0.0005, k3 0.",
            ""]
    return "\n".join(head + _first_set_table(results, methods) + [""]
                     + _sets_table(sums, methods, len(results)) + [""]
                     + _targets(sums, targets, time_target_s) + _left_out(results))
