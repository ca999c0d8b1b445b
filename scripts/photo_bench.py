#!/usr/bin/env python3
"""Real camera frames: qrpose's detector against zxing-cpp (PyPI) on the same photo
bytes, read rate and time per category.

    cargo build --release
    python3 scripts/photo_bench.py ../shared/data/qr-photos/boofcv-dev
    python3 scripts/photo_bench.py ../shared/data/qr-photos/boofcv-dev --only lots nominal --limit 5
    python3 scripts/photo_bench.py ../shared/data/qr-photos/boofcv-dev --qrpose-flag=--detector=rxing
    python3 scripts/photo_bench.py ../shared/data/qr-photos/boofcv-dev --qrpose-flag='--effort fast' \\
        --qrpose-flag=--max-detect-ms=500 --json target/photo-bench.json
    python3 scripts/photo_bench.py ../shared/data/qr-photos/boofcv-dev \\
        --qrpose-bin target-zxing/release/qrpose          # a `--features zxing-cpp` build

MANIFEST_DIR/manifest.json: `images[]` with `path` (relative to MANIFEST_DIR), `group`
(category) and `corners` (hand-labelled quadrilaterals, 4 [x, y] each). A code is READ when a
returned quadrilateral with a decoded payload overlaps its label with IoU >= 0.5 (IoU of the
convex hulls, so corner order does not matter); matching is one-to-one, greedy by IoU. For a
manifest whose `corners` are null but which has `expected_texts` (the zxing-cpp sample set),
codes are matched by payload instead, and the output says so.

Per photo: `POST /v1/pose/image?fx_px=F&fy_px=F&cx_px=(w-1)/2&cy_px=(h-1)/2&marker_size_mm=50`
(and the --qrpose-flag values as query parameters) to one `qrpose serve` started for the
run and warmed by one request, as an integrator runs it (`--qrpose-via cli`: `qrpose estimate
--image PHOTO ...`, a new process per photo, whose cold start lands in its timing), with
F = max(w, h) (intrinsics only matter for the pose); time = the answer's `timing_ms.decode +
timing_ms.detect`. An error status or exit, a timeout (--timeout, 60 s) or an unreadable
answer counts as nothing read and is listed. zxing-cpp:
OpenCV's decode to 8-bit grey (`cv2.imdecode(..., cv2.IMREAD_GRAYSCALE)`, libjpeg-turbo) +
`read_barcodes(formats=QRCode)`, timed together (median of --repeat runs), run right after
qrpose on the same bytes (alternated photo by photo); Pillow's decode (RGB + convert('L')) is
timed too and reported as a second ratio. EXIF orientation is applied on neither side (qrpose ignores it; the labels are
in the stored pixel grid). See scripts/photo_common.py for the shared conventions.

Output: a Markdown table per category (photos, codes, read % of each reader, median and p95
time of each, the photo-by-photo time ratio qrpose / zxing-cpp, median and p90, with OpenCV's
decode and with Pillow's, photos where qrpose took > 150 ms, qrpose failures) with an overall
row (read % over all codes, times over all photos), then codes read by one reader only,
decoded quadrilaterals that match no label, the photos where qrpose took > 150 ms with the
passes that took the time (`timing_ms.detect_passes`: name, ms, symbols decoded), a table of
the passes by kind over all photos (photos, total and largest time, symbols decoded, photos
where the kind decoded one), and failures. --json OUT.json: per-image details.
Options: --only CATEGORY..., --limit N (first N photos of each category, manifest order),
--no-zxing, --zxing-decode convert|draft, --repeat N (zxing-cpp runs per photo, median),
--qrpose-repeat N (qrpose processes per photo, median time), --timeout S.

Runs in target/photo-venv (zxing-cpp, numpy, Pillow, OpenCV; created on first use). The machine's
load shows in the times: run it on an idle machine, or compare runs made side by side.
"""
import argparse, json, re, sys, time
from collections import OrderedDict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import photo_common as pc  # noqa: E402


def select(images, only, limit):
    groups = OrderedDict()
    for e in images:
        if only and e["group"] not in only:
            continue
        groups.setdefault(e["group"], [])
        if limit is None or len(groups[e["group"]]) < limit:
            groups[e["group"]].append(e)
    return groups


def bench_image(root, entry, args, flags):
    path = root / entry["path"]
    data = path.read_bytes()
    w, h = pc.image_size(path)
    rec = {"path": entry["path"], "group": entry["group"], "size": [w, h],
           "exif_orientation": pc.exif_orientation(path)}
    labels = entry.get("corners")
    by_text = labels is None
    rec["codes"] = len(entry.get("expected_texts") or []) if by_text else len(labels)
    q = pc.run_qrpose(args.qrpose_bin, path, w, h, flags, args.timeout, args.qrpose_repeat,
                     via=args.qrpose_via)
    if q["ok"] and q["size"] != [w, h]:
        q["note"] = "; ".join(filter(None, [q.get("note"), f"qrpose saw {q['size']}, Pillow {[w, h]}"]))
    z = None if args.no_zxing else pc.run_zxing(data, args.repeat, args.zxing_decode)
    for name, res in (("qrpose", q), ("zxing", z)):
        if res is None:
            continue
        dets = res["markers"] if name == "qrpose" else res["results"]
        if by_text:
            matched, extras = pc.match_texts(entry.get("expected_texts") or [], dets)
            res["read"] = matched
            res["unmatched_decoded"] = extras
        else:
            matched, extra = pc.match_labels(labels, dets)
            res["read"] = [li for li, _, _ in matched]
            res["matches"] = matched
            res["unmatched_decoded"] = len(extra)
        res["decoded"] = sum(1 for d in dets if d.get("payload"))
        res["undecoded"] = sum(1 for d in dets if not d.get("payload"))
        rec[name] = res
    return rec, by_text


SLOW_MS = 150.0


def summarise(records):
    codes = sum(r["codes"] for r in records)
    out = {"photos": len(records), "codes": codes}
    for name in ("qrpose", "zxing"):
        rs = [r[name] for r in records if r.get(name) is not None]
        if not rs:
            out[name] = None
            continue
        read = sum(len(x["read"]) for x in rs)
        ms = [x["ms"] for x in rs]
        out[name] = {"read": read, "read_pct": 100 * read / codes if codes else float("nan"),
                     "median_ms": pc.median(ms), "p95_ms": pc.pct(ms, 0.95),
                     "max_ms": max((m for m in ms if m is not None), default=float("nan")),
                     "over_150ms": sum(1 for m in ms if m is not None and m > SLOW_MS),
                     "failures": sum(1 for x in rs if not x["ok"]),
                     "unmatched_decoded": sum(x["unmatched_decoded"] for x in rs)}
    for dec in ("opencv", "pillow"):
        out[f"ratio_{dec}"] = pc.ratio_stats(
            [(r["qrpose"]["ms"], r["zxing"].get(f"ms_{dec}")) for r in records
             if r.get("zxing") and r["zxing"]["ok"] and r["qrpose"]["ok"]])
    return out


def ratio_cell(x):
    return "–" if x is None else f"{x['median']:.2f} / {x['p90']:.2f}"


def row(name, s):
    def read(k):
        x = s.get(k)
        return "–" if x is None else f"{x['read_pct']:.1f} ({x['read']})"

    def t(k, f):
        x = s.get(k)
        return "–" if x is None else pc.fmt_ms(x[f])
    q = s["qrpose"]
    return (f"| {name} | {s['photos']} | {s['codes']} | {read('qrpose')} | {read('zxing')} | "
            f"{t('qrpose', 'median_ms')} | {t('qrpose', 'p95_ms')} | {t('zxing', 'median_ms')} | "
            f"{t('zxing', 'p95_ms')} | {ratio_cell(s.get('ratio_opencv'))} | "
            f"{ratio_cell(s.get('ratio_pillow'))} | {q['over_150ms']} | {q['failures']} |")


def pass_kind(name):
    """A pass's name with its region / crop number taken out (`region 3 double` -> `region K
    double`), so that the passes of every photo add up by kind."""
    return re.sub(r"\b(region|tile|pair|lone|triple) \d+", r"\1 K", name or "?")


def print_pass_table(records):
    """Per kind of pass, over every photo where qrpose ran it: photos, total and largest time,
    symbols decoded, and photos where it decoded one."""
    kinds = OrderedDict()
    for r in records:
        for name, ms, dec in r["qrpose"].get("passes") or []:
            k = kinds.setdefault(pass_kind(name), {"photos": set(), "ms": 0.0, "max": 0.0,
                                                   "decoded": 0, "photos_decoding": set()})
            k["photos"].add(r["path"])
            k["ms"] += ms or 0.0
            k["max"] = max(k["max"], ms or 0.0)
            k["decoded"] += dec or 0
            if dec:
                k["photos_decoding"].add(r["path"])
    if not kinds:
        return
    total = sum(k["ms"] for k in kinds.values())
    print(f"\nPasses by kind (`timing_ms.detect_passes`; decoded counts symbols a pass decoded, "
          f"new or read before; detection total {total:.0f} ms):\n")
    print("| pass | photos | total ms | share | largest ms | symbols decoded | photos where it decoded |")
    print("|---|---|---|---|---|---|---|")
    for name, k in sorted(kinds.items(), key=lambda kv: -kv[1]["ms"]):
        print(f"| {name} | {len(k['photos'])} | {k['ms']:.0f} | {100 * k['ms'] / total:.1f} % | "
              f"{k['max']:.0f} | {k['decoded']} | {len(k['photos_decoding'])} |")


def print_cost_floor(records):
    """The photo-by-photo ratio (OpenCV's decode) if parts of qrpose's time were gone: its
    decode as fast as OpenCV's (libjpeg-turbo), no pass after the full-resolution read (what
    `fast` runs; refinement kept), and both. What no choice of later passes can go below."""
    rows = []
    for r in records:
        q, z = r["qrpose"], r.get("zxing")
        if not (q["ok"] and z and z["ok"] and z.get("ms_opencv") and q.get("passes")):
            continue
        later = sum(p[1] or 0.0 for p in q["passes"][1:])
        rows.append((q["decode_ms"], q["detect_ms"], later, z["decode_ms"], z["ms_opencv"]))
    if not rows:
        return
    cases = (("as measured", lambda d, t, l, zd: d + t),
             ("qrpose's decode as fast as OpenCV's", lambda d, t, l, zd: zd + t),
             ("no pass after the first", lambda d, t, l, zd: d + t - l),
             ("both", lambda d, t, l, zd: zd + t - l))
    print("\nThe photo-by-photo ratio (OpenCV's decode) without parts of qrpose's time "
          f"({len(rows)} photos; the first pass is the full-resolution read):\n")
    print("| qrpose's time | median | p90 |")
    print("|---|---|---|")
    for name, f in cases:
        ratios = [f(d, t, l, zd) / z for d, t, l, zd, z in rows]
        print(f"| {name} | {pc.median(ratios):.2f} | {pc.pct(ratios, 0.90):.2f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    pc.add_manifest_args(ap)
    pc.add_common_args(ap)
    args = ap.parse_args()
    pc.ensure_venv()
    flags = pc.qrpose_flags(args)
    if not Path(args.qrpose_bin).exists():
        sys.exit(f"no qrpose binary at {args.qrpose_bin}: `cargo build --release` first")
    root = Path(args.manifest_dir)
    manifest = json.loads((root / "manifest.json").read_text())
    groups = select(manifest["images"], set(args.only or []), args.limit)
    if args.only:
        missing = set(args.only) - set(groups)
        if missing:
            sys.exit(f"no such category: {', '.join(sorted(missing))}")
    env = pc.environment(args, args.qrpose_bin)
    if not args.no_zxing:
        pc.warm_up_zxing()
    total = sum(len(v) for v in groups.values())
    records, by_text_any, done, t_start = [], False, 0, time.time()
    for g, entries in groups.items():
        for e in entries:
            rec, by_text = bench_image(root, e, args, flags)
            by_text_any |= by_text
            records.append(rec)
            done += 1
            q, z = rec["qrpose"], rec.get("zxing")
            zs = "" if z is None else f" | zxing {len(z['read'])} {pc.fmt_ms(z['ms'] if z['ms'] is not None else float('nan'))} ms"
            qs = (f"{len(q['read'])} {pc.fmt_ms(q['ms'])} ms" if q["ok"] else f"FAILED ({q['error'][:60]})")
            print(f"[{done}/{total}] {rec['path']}: {rec['codes']} codes | qrpose {qs}{zs}",
                  file=sys.stderr, flush=True)
    env["loadavg_end"] = __import__("os").getloadavg()
    env["elapsed_s"] = round(time.time() - t_start, 1)

    per_group = OrderedDict((g, summarise([r for r in records if r["group"] == g])) for g in groups)
    overall = summarise(records)

    print(f"qrpose: `{env['qrpose_bin']}` (built {env['qrpose_bin_mtime']}, tree {env['git_head']}), "
          f"flags: `{' '.join(flags) or '(none)'}`; zxing-cpp {env['zxing_cpp']} (PyPI), Pillow "
          f"{env['pillow']}, OpenCV {env['opencv']}, primary decode `{args.zxing_decode}`, runs per image: qrpose {args.qrpose_repeat} (via {args.qrpose_via}), zxing-cpp {args.repeat} (median); "
          f"EXIF orientation {env['exif_orientation']}.")
    print(f"Read = decoded quadrilateral with IoU >= 0.5 to a label" if not by_text_any else
          "Read = expected payload decoded (this manifest has no corner labels)", end="")
    print(f"; times in ms: qrpose timing_ms.decode + detect, zxing-cpp decode + read_barcodes. "
          f"Load average {env['loadavg_start'][0]:.1f} -> {env['loadavg_end'][0]:.1f} on "
          f"{env['cpus']} CPUs; {env['elapsed_s']} s.\n")
    print("| category | photos | codes | qrpose read % (n) | zxing-cpp read % (n) | qrpose median ms | "
          "qrpose p95 ms | zxing-cpp median ms | zxing-cpp p95 ms | ratio, OpenCV decode (median / p90) | "
          "ratio, Pillow decode (median / p90) | qrpose > 150 ms | qrpose failures |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for g, s in per_group.items():
        print(row(g, s))
    print(row("**all**", overall))

    if not args.no_zxing:
        only_q = sum(len(set(r["qrpose"]["read"]) - set(r["zxing"]["read"])) for r in records)
        only_z = sum(len(set(r["zxing"]["read"]) - set(r["qrpose"]["read"])) for r in records)
        both = sum(len(set(r["zxing"]["read"]) & set(r["qrpose"]["read"])) for r in records)
        print(f"\nCodes read by both: {both}; by qrpose only: {only_q}; by zxing-cpp only: {only_z}.")
        for dec, label in (("opencv", "OpenCV"), ("pillow", "Pillow")):
            x = overall.get(f"ratio_{dec}")
            if x:
                print(f"Time, qrpose / zxing-cpp with {label}'s decode: ratio of the medians "
                      f"{x['of_medians']:.2f}; photo by photo median {x['median']:.2f}, p90 "
                      f"{x['p90']:.2f}, p95 {x['p95']:.2f}; ratio of the totals {x['of_totals']:.2f}.")
    print(("Decoded payloads matching no expected text (text-mode or encoding differences, or a "
           "misread): " if by_text_any else
           "Decoded quadrilaterals matching no label (unlabelled codes, or corners off by IoU < 0.5): ")
          + f"qrpose {overall['qrpose']['unmatched_decoded']}"
          + ("" if args.no_zxing else f", zxing-cpp {overall['zxing']['unmatched_decoded']}") + ".")
    print(f"Detections without a payload (not counted): qrpose "
          f"{sum(r['qrpose']['undecoded'] for r in records)}.")
    slow = sorted((r for r in records if r["qrpose"]["ms"] and r["qrpose"]["ms"] > SLOW_MS),
                  key=lambda r: -r["qrpose"]["ms"])
    print(f"qrpose > {SLOW_MS:g} ms: {len(slow)} of {len(records)} photos"
          + (": " + ", ".join(f"{r['path']} ({r['qrpose']['ms']:.0f} ms)" for r in slow[:15])
             + (" …" if len(slow) > 15 else "") if slow else "") + ".")
    if slow:
        print("Where their time went (`timing_ms.detect_passes`, the passes of over 5 % of the "
              "photo's time: ms, symbols decoded):")
        for r in slow:
            q = r["qrpose"]
            big = [p for p in q.get("passes") or [] if p[1] and p[1] > 0.05 * q["ms"]]
            print(f"  - {r['path']} ({r['size'][0]}x{r['size'][1]}; decode {q['decode_ms']:.0f} ms, "
                  f"detect {q['detect_ms']:.0f} ms; read {len(q['read'])} of {r['codes']}): "
                  + ", ".join(f"{p[0]} {p[1]:.0f} ({p[2]})" for p in big) + ".")
    print_pass_table(records)
    print_cost_floor(records)
    fails = [r for r in records if not r["qrpose"]["ok"]]
    if fails:
        print(f"qrpose failures ({len(fails)}, counted as nothing read):")
        for r in fails:
            print(f"  - {r['path']}: {r['qrpose']['error']}")
    zfails = [r for r in records if r.get("zxing") and not r["zxing"]["ok"]]
    if zfails:
        print(f"zxing-cpp failures ({len(zfails)}, counted as nothing read):")
        for r in zfails:
            print(f"  - {r['path']}: {r['zxing']['error']}")
    notes = [r for r in records if r["qrpose"].get("note")]
    for r in notes:
        print(f"  note {r['path']}: {r['qrpose']['note']}")

    if args.json:
        out = {"environment": env, "manifest_dir": str(root), "matching":
               "payload" if by_text_any else "iou>=0.5", "per_category": per_group,
               "overall": overall, "images": records}
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(out, indent=1))
        print(f"\nPer-image details: {args.json}")


if __name__ == "__main__":
    main()
