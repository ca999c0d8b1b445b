#!/usr/bin/env python3
"""Real camera frames without a code: how long qrpose and zxing-cpp (PyPI) take to
find nothing, on the same JPEG bytes.

    cargo build --release
    python3 scripts/nocode_bench.py                       # boofcv-dev, crops in target/nocode/
    python3 scripts/nocode_bench.py ../shared/data/qr-photos/boofcv-dev --qrpose-flag=--detector=rxing
    python3 scripts/nocode_bench.py --qrpose-flag='--effort fast' --json target/nocode-bench.json
    python3 scripts/nocode_bench.py --qrpose-bin target-zxing/release/qrpose

Step 1, the set (deterministic): for every photo of MANIFEST_DIR/manifest.json (default
../shared/data/qr-photos/boofcv-dev) large enough, a 1280x720 and a 1920x1080 window (always
landscape, in the stored pixel grid: EXIF orientation is not applied, as qrpose does not) whose
position is drawn from random.Random(f"{seed}:{path}:{size}") (--seed, default 12) until it
intersects no labelled quadrilateral's bounding box grown by 10 % of its width / height on
each side (--margin); after --tries (30) misses that size is skipped for that photo. Each
window is cut from the RGB-decoded photo and written twice as JPEG quality 90 (Pillow
defaults otherwise: 4:2:0, no EXIF): in colour, and in grey (`convert('L')`, one component:
what a monochrome robot camera sends) as `..._grey.jpg`, to target/nocode/ (--out), with
target/nocode/crops.json listing them and the parameters; another --seed gives other
windows, crops not tuned on; a later run reuses the crops when crops.json's parameters (source
manifest's hash, seed, sizes, margin, tries, quality, Pillow version) match and every file is
there with its recorded hash, and rebuilds them otherwise. Photos are never copied: only the
crops, under target/ (git-ignored).

Step 2, the timing: for each crop, `POST /v1/pose/image` to one `qrpose serve` kept running
(`--qrpose-via cli`: `qrpose estimate --image CROP ...`, a new process each; time = the
answer's `timing_ms.decode + timing_ms.detect`; intrinsics F = max(w, h), centre (w-1)/2, (h-1)/2;
extra --qrpose-flag values forwarded as given) and right after it zxing-cpp (OpenCV's
`imdecode(..., IMREAD_GRAYSCALE)` + `read_barcodes(formats=QRCode)`, median of --repeat runs;
Pillow's RGB decode + convert('L') timed too, as a second figure), same bytes. Prints count,
median, p95 and max of each, and the qrpose / zxing-cpp ratios of the medians and p95s (with
OpenCV's decode, then with Pillow's), for colour and grey crops at 720p and 1080p, and all; then the crops where either reader decoded a code (should be about none: a
hit is an unlabelled code in the photo or a false positive; listed), qrpose detections
without a payload, and qrpose failures (non-zero exit, --timeout). --json OUT.json: per-crop
details. --limit N: only the first N crops of each size (quick checks); --repeat N and
--qrpose-repeat N: runs per crop of zxing-cpp / qrpose, median time. See
scripts/photo_common.py for the shared conventions; runs in target/photo-venv.
"""
import argparse, hashlib, json, random, sys, time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import photo_common as pc  # noqa: E402

SIZES = [(1280, 720), (1920, 1080)]
NAMES = {(1280, 720): "720p", (1920, 1080): "1080p"}
KINDS = ["colour", "grey"]


def sha256(data):
    return hashlib.sha256(data).hexdigest()


def forbidden_boxes(labels, margin):
    out = []
    for q in labels or []:
        xs = [p[0] for p in q]; ys = [p[1] for p in q]
        w, h = max(xs) - min(xs), max(ys) - min(ys)
        out.append((min(xs) - margin * w, min(ys) - margin * h, max(xs) + margin * w, max(ys) + margin * h))
    return out


def place(rng, img_w, img_h, cw, ch, boxes, tries):
    for _ in range(tries):
        x, y = rng.randint(0, img_w - cw), rng.randint(0, img_h - ch)
        if all(x + cw <= b[0] or b[2] <= x or y + ch <= b[1] or b[3] <= y for b in boxes):
            return [x, y, x + cw, y + ch]
    return None


def build_set(root, manifest_bytes, out_dir, args):
    """The crops, reused from out_dir when its crops.json has the same parameters."""
    import PIL
    from PIL import Image
    # The manifest is identified by its hash, not its path (a relative and an absolute path
    # to the same folder must reuse the same crops).
    params = {"source_manifest_sha256": sha256(manifest_bytes), "seed": args.seed,
              "sizes": SIZES, "margin": args.margin, "tries": args.tries, "jpeg_quality": 90,
              "pillow": PIL.__version__, "exif_orientation": "not applied",
              "kinds": KINDS}
    index = out_dir / "crops.json"
    if index.exists():
        try:
            old = json.loads(index.read_text())
            if old["params"] == json.loads(json.dumps(params)) and all(
                    (out_dir / c["file"]).exists()
                    and sha256((out_dir / c["file"]).read_bytes()) == c["sha256"]
                    for c in old["crops"]):
                print(f"reusing {len(old['crops'])} crops in {out_dir}", file=sys.stderr)
                return old
        except (ValueError, KeyError, TypeError):
            pass
    out_dir.mkdir(parents=True, exist_ok=True)
    for stale in out_dir.glob("*.jpg"):
        stale.unlink()
    manifest = json.loads(manifest_bytes)
    crops, skipped = [], []
    t0 = time.time()
    for n, e in enumerate(manifest["images"], 1):
        path = root / e["path"]
        w, h = pc.image_size(path)
        boxes = forbidden_boxes(e.get("corners"), args.margin)
        windows = {}
        for cw, ch in SIZES:
            if w < cw or h < ch:
                skipped.append({"source": e["path"], "size": [cw, ch], "why": f"photo {w}x{h} too small"})
                continue
            rng = random.Random(f"{args.seed}:{e['path']}:{cw}x{ch}")
            box = place(rng, w, h, cw, ch, boxes, args.tries)
            if box is None:
                skipped.append({"source": e["path"], "size": [cw, ch],
                                "why": f"no free window in {args.tries} tries"})
                continue
            windows[(cw, ch)] = box
        if not windows:
            continue
        with Image.open(path) as im:
            rgb = im.convert("RGB")
        for (cw, ch), box in windows.items():
            for kind in KINDS:
                suffix = "" if kind == "colour" else "_grey"
                name = f"{e['path'].rsplit('.', 1)[0].replace('/', '__')}__{cw}x{ch}{suffix}.jpg"
                crop = rgb.crop(box)
                (crop if kind == "colour" else crop.convert("L")).save(out_dir / name, "JPEG", quality=90)
                crops.append({"file": name, "source": e["path"], "group": e["group"], "size": [cw, ch],
                              "kind": kind, "box": box, "sha256": sha256((out_dir / name).read_bytes())})
        print(f"[{n}/{len(manifest['images'])}] {e['path']}: {len(windows)} crop(s)",
              file=sys.stderr, flush=True)
    out = {"params": params, "source_manifest": str((root / "manifest.json").resolve()), "crops": crops, "skipped": skipped,
           "built_s": round(time.time() - t0, 1)}
    index.write_text(json.dumps(out, indent=1))
    return out


def stats(ms):
    v = [m for m in ms if m is not None]
    return {"n": len(v), "median": pc.median(v), "p95": pc.pct(v, 0.95),
            "max": max(v) if v else float("nan")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("manifest_dir", nargs="?", default=str(pc.ROOT.parent / "shared" / "data" / "qr-photos" / "boofcv-dev"),
                    help="folder with manifest.json (default: ../shared/data/qr-photos/boofcv-dev)")
    ap.add_argument("--out", default=str(pc.ROOT / "target" / "nocode"), help="crop folder")
    ap.add_argument("--seed", type=int, default=12)
    ap.add_argument("--margin", type=float, default=0.10)
    ap.add_argument("--tries", type=int, default=30)
    ap.add_argument("--limit", type=int, help="time only the first N crops of each size")
    pc.add_common_args(ap)
    args = ap.parse_args()
    pc.ensure_venv()
    flags = pc.qrpose_flags(args)
    if not Path(args.qrpose_bin).exists():
        sys.exit(f"no qrpose binary at {args.qrpose_bin}: `cargo build --release` first")
    root = Path(args.manifest_dir)
    crop_set = build_set(root, (root / "manifest.json").read_bytes(), Path(args.out), args)
    crops = crop_set["crops"]
    if args.limit is not None:
        crops = [c for s in SIZES for k in KINDS
                 for c in [c for c in crops if tuple(c["size"]) == s and c["kind"] == k][:args.limit]]
    env = pc.environment(args, args.qrpose_bin)
    if not args.no_zxing:
        pc.warm_up_zxing()
    t_start = time.time()
    records = []
    for n, c in enumerate(crops, 1):
        path = Path(args.out) / c["file"]
        data = path.read_bytes()
        w, h = c["size"]
        q = pc.run_qrpose(args.qrpose_bin, path, w, h, flags, args.timeout, args.qrpose_repeat,
                         via=args.qrpose_via)
        z = None if args.no_zxing else pc.run_zxing(data, args.repeat, args.zxing_decode)
        rec = dict(c, qrpose=q, zxing=z)
        records.append(rec)
        qs = f"{pc.fmt_ms(q['ms'])} ms" if q["ok"] else f"FAILED ({q['error'][:60]})"
        zs = "" if z is None or z["ms"] is None else f" | zxing {pc.fmt_ms(z['ms'])} ms"
        print(f"[{n}/{len(crops)}] {c['file']}: qrpose {qs}{zs}", file=sys.stderr, flush=True)
    env["loadavg_end"] = __import__("os").getloadavg()
    env["elapsed_s"] = round(time.time() - t_start, 1)

    sets = [(f"{NAMES[s]} {k}", [r for r in records if tuple(r["size"]) == s and r["kind"] == k])
            for s in SIZES for k in KINDS]
    sets += [(f"{k}, all", [r for r in records if r["kind"] == k]) for k in KINDS]
    sets.append(("**all**", records))
    summary = {}
    n_skip = len({s["source"] for s in crop_set["skipped"]})
    print(f"qrpose: `{env['qrpose_bin']}` (built {env['qrpose_bin_mtime']}, tree {env['git_head']}), "
          f"flags: `{' '.join(flags) or '(none)'}`; zxing-cpp {env['zxing_cpp']} (PyPI), Pillow "
          f"{env['pillow']}, OpenCV {env['opencv']}, primary decode `{args.zxing_decode}`, runs per image: qrpose {args.qrpose_repeat} (via {args.qrpose_via}), zxing-cpp {args.repeat} (median). "
          f"{len(crop_set['crops'])} crops from {len({c['source'] for c in crop_set['crops']})} photos "
          f"(seed {args.seed}, margin {args.margin:g}; {len(crop_set['skipped'])} photo/size pairs "
          f"skipped: photo too small or no code-free window; {n_skip} photos lack one size or both), JPEG q90, EXIF orientation not applied. Times in ms: "
          f"qrpose timing_ms.decode + detect, zxing-cpp decode + read_barcodes. Load average "
          f"{env['loadavg_start'][0]:.1f} -> {env['loadavg_end'][0]:.1f} on {env['cpus']} CPUs; "
          f"{env['elapsed_s']} s.\n")
    print("| set | crops | qrpose median | qrpose p95 | qrpose max | zxing-cpp median | zxing-cpp p95 | "
          "zxing-cpp max | ratio of medians | ratio of p95s | ratios with Pillow's decode (medians / p95s) | "
          "crops with a code (qrpose / zxing-cpp) | qrpose failures |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, rs in sets:
        qs = stats([r["qrpose"]["ms"] for r in rs])
        zs = stats([r["zxing"]["ms"] for r in rs if r["zxing"]]) if not args.no_zxing else None
        other = "ms_pillow" if args.zxing_decode == "opencv" else "ms_opencv"
        zp = stats([r["zxing"][other] for r in rs if r["zxing"]]) if not args.no_zxing else None
        qhit = sum(1 for r in rs if any(m["payload"] for m in r["qrpose"]["markers"]))
        zhit = sum(1 for r in rs if r["zxing"] and any(m["payload"] for m in r["zxing"]["results"]))
        fails = sum(1 for r in rs if not r["qrpose"]["ok"])
        summary[name.strip("*")] = {"qrpose": qs, "zxing": zs, "zxing_other_decode": zp,
                                    "qrpose_hits": qhit, "zxing_hits": zhit, "qrpose_failures": fails}
        f = pc.fmt_ms
        if zs:
            ratio_m = f"{qs['median'] / zs['median']:.2f}" if zs["median"] else "–"
            ratio_p = f"{qs['p95'] / zs['p95']:.2f}" if zs["p95"] else "–"
            other_r = (f"{qs['median'] / zp['median']:.2f} / {qs['p95'] / zp['p95']:.2f}"
                       if zp["median"] and zp["p95"] else "–")
            zcols = f"{f(zs['median'])} | {f(zs['p95'])} | {f(zs['max'])} | {ratio_m} | {ratio_p} | {other_r}"
        else:
            zcols = "– | – | – | – | – | –"
        print(f"| {name} | {len(rs)} | {f(qs['median'])} | {f(qs['p95'])} | {f(qs['max'])} | {zcols} | "
              f"{qhit} / {'–' if args.no_zxing else zhit} | {fails} |")

    hits = [r for r in records if any(m["payload"] for m in r["qrpose"]["markers"])
            or (r["zxing"] and any(m["payload"] for m in r["zxing"]["results"]))]
    print(f"\nCrops where a reader decoded a code: {len(hits)}" + (":" if hits else "."))
    for r in hits:
        qp = [m["payload"] for m in r["qrpose"]["markers"] if m["payload"]]
        zp = [m["payload"] for m in r["zxing"]["results"] if m["payload"]] if r["zxing"] else []
        print(f"  - {r['file']} (box {r['box']}): qrpose {[p[:40] for p in qp]}, zxing-cpp {[p[:40] for p in zp]}")
    und = [r for r in records if any(not m["payload"] for m in r["qrpose"]["markers"])]
    print(f"Crops where qrpose returned a marker without a payload: {len(und)}"
          + (": " + ", ".join(r["file"] for r in und[:20]) if und else "") + ".")
    for r in records:
        if not r["qrpose"]["ok"]:
            print(f"  qrpose failure {r['file']}: {r['qrpose']['error']}")
        if r["zxing"] and not r["zxing"]["ok"]:
            print(f"  zxing-cpp failure {r['file']}: {r['zxing']['error']}")
    if args.json:
        out = {"environment": env, "crop_set": {k: v for k, v in crop_set.items() if k != "crops"},
               "summary": summary, "crops": records}
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(out, indent=1))
        print(f"\nPer-crop details: {args.json}")


if __name__ == "__main__":
    main()
