#!/usr/bin/env python3
"""Busy synthetic frames (2-6 codes each): qrpose against zxing-cpp
(PyPI) on the same rendered JPEG bytes, share of codes read and time per frame.

    cargo build --release
    python3 scripts/multicode_bench.py                                 # seeds 1..40
    python3 scripts/multicode_bench.py --qrpose-flag=--detector=rxing --json target/multicode.json
    python3 scripts/multicode_bench.py --frames 10 --first-seed 100 --qrpose-bin /tmp/qrpose
    python3 scripts/multicode_bench.py --qrpose-bin target-zxing/release/qrpose \\
        --render-bin target/release/qrpose-sim   # a `--features zxing-cpp` build, same frames

Step 1, the frames (deterministic): for SEED in --first-seed .. --first-seed + --frames - 1,
`RENDER_BIN render --random-scene SEED --seed SEED --width-px W --height-px H --blur-px B
--noise N --jpeg-quality Q --out OUT/scene-SEED.jpg` (W x H default 1280 x 720; OUT default
target/multicode/). The renderer draws 2-6 codes of 30-120 mm, 0.3-2 m away, tilted up to 35°,
never overlapping, all inside the frame, fx = fy in 950-1050 px. The effects come from
random.Random(f"multicode:{SEED}"): JPEG quality an integer in 75-95, Gaussian blur σ uniform in
0.5-1.2 px, sensor noise σ uniform in 1-4 grey levels. The JSON the renderer prints is the
ground truth: `codes[].payload` and `codes[].truth.corners_px`; the camera is
`camera.fx_px ...`. RENDER_BIN (--render-bin) defaults to the qrpose-sim beside --qrpose-bin; pass the same
--render-bin to runs that should see identical frames (the output prints a hash of all frames).

Step 2, the reading: `POST /v1/pose/image` of OUT/scene-SEED.jpg to one `qrpose serve` kept
running (`--qrpose-via cli`: `qrpose estimate --image ... [--qrpose-flag ...]`, a new process
each) with the renderer's camera and marker_size_mm=50 (time = its
`timing_ms.decode + timing_ms.detect`), and zxing-cpp (OpenCV's greyscale decode +
`read_barcodes(formats=QRCode)`, timed together; Pillow's decode timed too, as a second ratio)
on the same bytes, as scripts/photo_bench.py
(scripts/photo_common.py has the shared runners). A code is READ when a returned quadrilateral
whose payload equals the code's payload overlaps its truth corners with IoU >= 0.5 (IoU of the
convex hulls), matched one-to-one, greedily by IoU. A quadrilateral with IoU >= 0.5 and another
payload is a misread (listed). A code whose truth corners leave the frame would not count (the
renderer places none there; the output says how many were skipped).

Code size in the image = the SHORTEST side of its truth quadrilateral, px (a tilted code is as
small as its foreshortened side); the output gives the read % over all codes and over codes
with that side >= --min-px (40), and the per-frame misses with each missed code's size,
px per module, distance and tilt.

Output: a Markdown table (frames, codes, read % of each reader, median / p95 time of each per
frame), read % by code size, the misses per frame, misreads, qrpose failures, and the frames
where qrpose warned `detection_budget_exhausted` (its detection deadline is wall-clock time, so
on a loaded machine it reads less: compare runs at similar load, or pass
--qrpose-flag=--max-detect-ms=N). --json OUT.json: per-frame details.
Runs in target/photo-venv (zxing-cpp, numpy, Pillow, OpenCV; created on first use).
"""
import argparse, hashlib, json, math, random, subprocess, sys, time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import photo_common as pc  # noqa: E402


def effects(seed):
    rng = random.Random(f"multicode:{seed}")
    return {"jpeg_quality": rng.randint(75, 95), "blur_px": round(rng.uniform(0.5, 1.2), 3),
            "noise": round(rng.uniform(1.0, 4.0), 3)}


def render(binary, seed, out_dir, w, h):
    fx = effects(seed)
    path = out_dir / f"scene-{seed}.jpg"
    cmd = [str(binary), "render", "--random-scene", str(seed), "--seed", str(seed),
           "--width-px", str(w), "--height-px", str(h),
           "--blur-px", repr(fx["blur_px"]), "--noise", repr(fx["noise"]),
           "--jpeg-quality", str(fx["jpeg_quality"]), "--out", str(path)]
    proc = subprocess.run(cmd, capture_output=True, check=True)
    return path, fx, json.loads(proc.stdout), cmd


def side_px(q):
    return min(math.dist(q[i], q[(i + 1) % 4]) for i in range(4))


def tilt_deg(code):
    """Angle between the code's normal and the line of sight to its centre."""
    r = code["truth"].get("rotation_matrix")
    p = code["truth"].get("position_mm") or code["position_mm"]
    if not r:
        return None
    n = [r[0][2], r[1][2], r[2][2]]
    d = math.sqrt(sum(x * x for x in p))
    c = abs(sum(n[i] * p[i] for i in range(3))) / d
    return math.degrees(math.acos(min(1.0, c)))


def match(truth, dets, threshold=0.5):
    """Greedy one-to-one matching by IoU of truth codes [{payload, corners}] to decoded
    detections; a pair counts only with the same payload. Returns (read truth indices,
    misreads [(truth index, decoded payload, iou)], decoded detections matching nothing)."""
    decoded = [i for i, d in enumerate(dets) if d.get("payload")]
    pairs, wrong = [], []
    for ti, t in enumerate(truth):
        for di in decoded:
            v = pc.quad_iou(t["corners"], dets[di]["corners"])
            if v >= threshold:
                if dets[di]["payload"] == t["payload"]:
                    pairs.append((v, ti, di))
                else:
                    wrong.append((ti, dets[di]["payload"], round(v, 3), di))
    pairs.sort(reverse=True)
    used_t, used_d = set(), set()
    for v, ti, di in pairs:
        if ti in used_t or di in used_d:
            continue
        used_t.add(ti); used_d.add(di)
    misreads = [(ti, p, v) for ti, p, v, di in wrong if di not in used_d]
    wrong_d = {di for _, _, _, di in wrong}
    extra = [di for di in decoded if di not in used_d and di not in wrong_d]
    return sorted(used_t), misreads, extra


def summarise(records, min_px):
    out = {}
    for key, keep in (("all", lambda c: True), (f"side >= {min_px:g} px", lambda c: c["side_px"] >= min_px)):
        codes = [(r, i) for r in records for i, c in enumerate(r["codes"]) if keep(c)]
        row = {"frames": len(records), "codes": len(codes)}
        for name in ("qrpose", "zxing"):
            rs = [r[name] for r in records if r.get(name) is not None]
            if not rs:
                row[name] = None
                continue
            read = sum(1 for r, i in codes if i in r[name]["read"])
            ms = [x["ms"] for x in rs]
            row[name] = {"read": read, "read_pct": 100 * read / len(codes) if codes else float("nan"),
                         "median_ms": pc.median(ms), "p95_ms": pc.pct(ms, 0.95),
                         "max_ms": max((m for m in ms if m is not None), default=float("nan")),
                         "failures": sum(1 for x in rs if not x["ok"])}
        out[key] = row
    return out


def table_row(name, s):
    def read(k):
        x = s.get(k)
        return "–" if x is None else f"{x['read_pct']:.1f} ({x['read']})"

    def t(k, f):
        x = s.get(k)
        return "–" if x is None else pc.fmt_ms(x[f])
    return (f"| {name} | {s['frames']} | {s['codes']} | {read('qrpose')} | {read('zxing')} | "
            f"{t('qrpose', 'median_ms')} | {t('qrpose', 'p95_ms')} | {t('zxing', 'median_ms')} | "
            f"{t('zxing', 'p95_ms')} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=40, help="number of frames (default 40)")
    ap.add_argument("--first-seed", type=int, default=1, help="seed of the first frame (default 1)")
    ap.add_argument("--width-px", type=int, default=1280)
    ap.add_argument("--height-px", type=int, default=720)
    ap.add_argument("--out", default=str(pc.ROOT / "target" / "multicode"),
                    help="folder for the rendered frames (default target/multicode)")
    ap.add_argument("--render-bin", help="qrpose-sim binary that renders the frames (default: "
                    "qrpose-sim beside --qrpose-bin)")
    ap.add_argument("--min-px", type=float, default=40.0,
                    help="second read %% over codes whose shortest side is >= this, px (default 40)")
    pc.add_common_args(ap)
    args = ap.parse_args()
    pc.ensure_venv()
    flags = pc.qrpose_flags(args)
    render_bin = args.render_bin or str(Path(args.qrpose_bin).with_name("qrpose-sim"))
    for b in (args.qrpose_bin, render_bin):
        if not Path(b).exists():
            sys.exit(f"no qrpose binary at {b}: `cargo build --release` first")
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    env = pc.environment(args, args.qrpose_bin)
    env["render_bin"] = str(render_bin)
    if not args.no_zxing:
        pc.warm_up_zxing()
    seeds = range(args.first_seed, args.first_seed + args.frames)
    records, skipped, all_hash, t_start = [], 0, hashlib.sha256(), time.time()
    for n, seed in enumerate(seeds, 1):
        path, fx, gt, cmd = render(render_bin, seed, out_dir, args.width_px, args.height_px)
        data = path.read_bytes()
        all_hash.update(data)
        w, h = gt["image"]["width_px"], gt["image"]["height_px"]
        cam = gt["camera"]
        truth = []
        for c in gt["codes"]:
            q = c["truth"]["corners_px"]
            if not all(0 <= u <= w - 1 and 0 <= v <= h - 1 for u, v in q):
                skipped += 1
                continue
            s = side_px(q)
            mc = c["truth"].get("module_count")
            truth.append({"payload": c["payload"], "corners": q, "side_px": round(s, 1),
                          "module_count": mc, "px_per_module": round(s / mc, 2) if mc else None,
                          "size_mm": round(c["size_mm"], 1),
                          "distance_m": round(math.sqrt(sum(x * x for x in c["position_mm"])) / 1e3, 2),
                          "tilt_deg": None if tilt_deg(c) is None else round(tilt_deg(c), 1)})
        rec = {"seed": seed, "path": str(path), "sha256": hashlib.sha256(data).hexdigest(),
               "size": [w, h], "effects": fx, "camera": cam, "render_cmd": cmd, "codes": truth}
        q = pc.run_qrpose(args.qrpose_bin, path, w, h, flags, args.timeout, args.qrpose_repeat,
                          intrinsics=(cam["fx_px"], cam["fy_px"], cam["cx_px"], cam["cy_px"]),
                          via=args.qrpose_via)
        z = None if args.no_zxing else pc.run_zxing(data, args.repeat, args.zxing_decode)
        for name, res in (("qrpose", q), ("zxing", z)):
            if res is None:
                continue
            dets = res["markers"] if name == "qrpose" else res["results"]
            read, misreads, extra = match(truth, dets)
            res["read"] = read
            res["misreads"] = misreads
            res["unmatched_decoded"] = [dets[i]["payload"] for i in extra]
            res["undecoded"] = sum(1 for d in dets if not d.get("payload"))
            rec[name] = res
        records.append(rec)
        zs = "" if z is None else f" | zxing {len(z['read'])} {pc.fmt_ms(z['ms'] if z['ms'] is not None else float('nan'))} ms"
        qs = f"{len(q['read'])} {pc.fmt_ms(q['ms'])} ms" if q["ok"] else f"FAILED ({q['error'][:60]})"
        print(f"[{n}/{args.frames}] scene-{seed}: {len(truth)} codes | qrpose {qs}{zs}",
              file=sys.stderr, flush=True)
    env["loadavg_end"] = __import__("os").getloadavg()
    env["elapsed_s"] = round(time.time() - t_start, 1)
    env["frames_sha256"] = all_hash.hexdigest()

    summary = summarise(records, args.min_px)
    print(f"qrpose: `{env['qrpose_bin']}` (built {env['qrpose_bin_mtime']}, tree {env['git_head']}), "
          f"flags: `{' '.join(flags) or '(none)'}`; frames rendered by `{render_bin}`, seeds "
          f"{seeds.start}..{seeds.stop - 1}, {args.width_px}x{args.height_px}, JPEG 75-95, blur "
          f"0.5-1.2 px, noise 1-4 (frames sha256 {env['frames_sha256'][:12]}); zxing-cpp "
          f"{env['zxing_cpp']} (PyPI), Pillow {env['pillow']}, OpenCV {env['opencv']}, primary decode `{args.zxing_decode}`.")
    print(f"Read = quadrilateral with the code's payload and IoU >= 0.5 to its truth corners; "
          f"times in ms per frame: qrpose timing_ms.decode + detect, zxing-cpp decode + "
          f"read_barcodes. Size = shortest side of the truth quadrilateral. Load average "
          f"{env['loadavg_start'][0]:.1f} -> {env['loadavg_end'][0]:.1f} on {env['cpus']} CPUs; "
          f"{env['elapsed_s']} s.\n")
    print("| subset | frames | codes | qrpose read % (n) | zxing-cpp read % (n) | qrpose median ms | "
          "qrpose p95 ms | zxing-cpp median ms | zxing-cpp p95 ms |")
    print("|---|---|---|---|---|---|---|---|---|")
    for k, s in summary.items():
        print(table_row(k, s))
    print("\n| shortest side px | codes | qrpose read % (n) | zxing-cpp read % (n) |")
    print("|---|---|---|---|")
    edges = [0, 30, 40, 50, 60, 80, 1e9]
    for lo, hi in zip(edges, edges[1:]):
        sel = [(r, i) for r in records for i, c in enumerate(r["codes"]) if lo <= c["side_px"] < hi]
        cells = []
        for name in ("qrpose", "zxing"):
            if args.no_zxing and name == "zxing":
                cells.append("–")
                continue
            n = sum(1 for r, i in sel if i in r[name]["read"])
            cells.append(f"{100 * n / len(sel):.1f} ({n})" if sel else "–")
        label = f"{lo:g}-{hi:g}" if hi < 1e9 else f">= {lo:g}"
        print(f"| {label} | {len(sel)} | {cells[0]} | {cells[1]} |")
    if skipped:
        print(f"\nCodes skipped (truth corners outside the frame): {skipped}.")
    sides = sorted(c["side_px"] for r in records for c in r["codes"])
    small = sum(1 for s in sides if s < args.min_px)
    print(f"\nCode sizes (shortest side, px): min {sides[0]:.0f}, median {pc.median(sides):.0f}, "
          f"max {sides[-1]:.0f}; {small} of {len(sides)} codes below {args.min_px:g} px.")
    if not args.no_zxing:
        both = sum(len(set(r["qrpose"]["read"]) & set(r["zxing"]["read"])) for r in records)
        only_q = sum(len(set(r["qrpose"]["read"]) - set(r["zxing"]["read"])) for r in records)
        only_z = sum(len(set(r["zxing"]["read"]) - set(r["qrpose"]["read"])) for r in records)
        print(f"Codes read by both: {both}; by qrpose only: {only_q}; by zxing-cpp only: {only_z}.")
        for dec, label in (("opencv", "OpenCV"), ("pillow", "Pillow")):
            x = pc.ratio_stats([(r["qrpose"]["ms"], r["zxing"].get(f"ms_{dec}")) for r in records
                                if r["qrpose"]["ok"] and r["zxing"]["ok"]])
            summary[f"ratio_{dec}"] = x
            if x:
                print(f"Time, qrpose / zxing-cpp with {label}'s decode: ratio of the medians "
                      f"{x['of_medians']:.2f}; frame by frame median {x['median']:.2f}, p90 "
                      f"{x['p90']:.2f}.")

    print("\nMisses per frame (size px, px/module, distance, tilt; who missed):")
    any_miss = False
    for r in records:
        items = []
        for i, c in enumerate(r["codes"]):
            who = [name for name in ("qrpose", "zxing") if r.get(name) is not None and i not in r[name]["read"]]
            if who:
                items.append(f"{c['payload']} {c['side_px']:.0f} px ({c['px_per_module']} px/mod, "
                             f"{c['distance_m']} m, {c['tilt_deg']}°): "
                             + " + ".join("zxing-cpp" if w == "zxing" else w for w in who))
        if items:
            any_miss = True
            fx = r["effects"]
            print(f"- scene-{r['seed']} (q{fx['jpeg_quality']}, blur {fx['blur_px']}, noise {fx['noise']}; "
                  f"{len(r['codes'])} codes): " + "; ".join(items))
    if not any_miss:
        print("- none")
    for name, label in (("qrpose", "qrpose"), ("zxing", "zxing-cpp")):
        mis = [(r["seed"], r["codes"][ti]["payload"], p, v) for r in records if r.get(name)
               for ti, p, v in r[name]["misreads"]]
        if mis:
            print(f"{label} misreads (IoU >= 0.5, other payload): "
                  + "; ".join(f"scene-{s} {t} read as {p!r} (IoU {v})" for s, t, p, v in mis))
        extra = [(r["seed"], p) for r in records if r.get(name) for p in r[name]["unmatched_decoded"]]
        if extra:
            print(f"{label} decoded quadrilaterals matching no code: "
                  + "; ".join(f"scene-{s} {p!r}" for s, p in extra))
    print(f"qrpose detections without a payload (not counted): "
          f"{sum(r['qrpose']['undecoded'] for r in records)}.")
    budget = [r["seed"] for r in records if "detection_budget_exhausted" in (r["qrpose"].get("warnings") or [])]
    print(f"qrpose frames with warning detection_budget_exhausted (deadline hit; wall-clock, so "
          f"load-dependent): {len(budget)} of {len(records)}"
          + (f" (seeds {', '.join(map(str, budget))})" if budget else "") + ".")
    fails = [r for r in records if not r["qrpose"]["ok"]]
    if fails:
        print(f"qrpose failures ({len(fails)}, counted as nothing read):")
        for r in fails:
            print(f"  - scene-{r['seed']}: {r['qrpose']['error']}")
    zfails = [r for r in records if r.get("zxing") and not r["zxing"]["ok"]]
    if zfails:
        print(f"zxing-cpp failures ({len(zfails)}):")
        for r in zfails:
            print(f"  - scene-{r['seed']}: {r['zxing']['error']}")

    if args.json:
        out = {"environment": env, "matching": "payload and iou>=0.5", "min_px": args.min_px,
               "summary": summary, "frames": records}
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(out, indent=1))
        print(f"\nPer-frame details: {args.json}")


if __name__ == "__main__":
    main()
