#!/usr/bin/env python3
"""The JPEG decode to grey, photo by photo: qrpose's decoder and
zune-jpeg's options (examples/jpeg_decode_speed.rs) against OpenCV's greyscale decode
(libjpeg-turbo), on the same bytes.

    cargo build --release --example jpeg_decode_speed
    python3 scripts/jpeg_decode_bench.py ../shared/data/qr-photos/boofcv-dev --repeat 5 \\
        --json target/jpeg-decode.json

For every JPEG photo of MANIFEST_DIR/manifest.json (--only CATEGORY..., --limit N per category;
other formats are skipped and counted):
`jpeg_decode_speed --repeat N PHOTO` (its variants `qrpose`, `strict`, `lenient`,
`lenient_no_unsafe`, alternated in every round, median of N rounds each), then right after it
`cv2.imdecode(..., IMREAD_GRAYSCALE | IMREAD_IGNORE_ORIENTATION)` N times (median), as
scripts/photo_common.py times zxing-cpp's decode. Prints per pixel-count class and overall: the
median of each decoder's time, and the photo-by-photo ratio to OpenCV's (median / p90) of
every variant; how many JPEGs strict mode rejects (qrpose then decodes them twice) and what
that costs. --json OUT.json: per-photo times. Runs in target/photo-venv (scripts/photo_common.py).
"""
import argparse, json, statistics, subprocess, sys, time
from collections import OrderedDict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import photo_common as pc  # noqa: E402

DEFAULT_BIN = pc.ROOT / "target" / "release" / "examples" / "jpeg_decode_speed"
VARIANTS = ["qrpose", "strict", "lenient", "lenient_no_unsafe"]


def opencv_ms(data, repeat):
    times = []
    pc._decode_opencv(data)  # untimed, as the example's first round
    for _ in range(repeat):
        t0 = time.perf_counter()
        pc._decode_opencv(data)
        times.append(1e3 * (time.perf_counter() - t0))
    return statistics.median(times)


def size_class(w, h):
    mp = w * h / 1e6
    return "< 1 MP" if mp < 1 else "1-4 MP" if mp < 4 else "4-8 MP" if mp < 8 else ">= 8 MP"


def summary_row(name, recs):
    cells = [name, str(len(recs)), pc.fmt_ms(pc.median([r["opencv_ms"] for r in recs]))]
    for v in VARIANTS:
        cells.append(pc.fmt_ms(pc.median([r["ms"][v] for r in recs])))
    for v in VARIANTS:
        x = pc.ratio_stats([(r["ms"][v], r["opencv_ms"]) for r in recs])
        cells.append("–" if x is None else f"{x['median']:.2f} / {x['p90']:.2f}")
    cells.append(str(sum(1 for r in recs if not r["strict_ok"])))
    return "| " + " | ".join(cells) + " |"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    pc.add_manifest_args(ap)
    ap.add_argument("--repeat", type=int, default=5, help="rounds per photo on each side (default 5)")
    ap.add_argument("--bin", default=str(DEFAULT_BIN),
                    help="the jpeg_decode_speed example (default: target/release/examples/jpeg_decode_speed)")
    ap.add_argument("--json", metavar="OUT.json", help="write per-photo times here")
    args = ap.parse_args()
    pc.ensure_venv()
    import cv2
    if not Path(args.bin).exists():
        sys.exit(f"no example binary at {args.bin}: `cargo build --release --example jpeg_decode_speed`")
    root = Path(args.manifest_dir)
    images = json.loads((root / "manifest.json").read_text())["images"]
    per_group = OrderedDict()
    for e in images:
        if args.only and e["group"] not in args.only:
            continue
        g = per_group.setdefault(e["group"], [])
        if args.limit is None or len(g) < args.limit:
            g.append(e)
    load0, t_start, records = __import__("os").getloadavg(), time.time(), []
    todo = [e for g in per_group.values() for e in g]
    # JPEG only (by the SOI marker): the other photos go through other decoders.
    not_jpeg = {e["path"] for e in todo if (root / e["path"]).read_bytes()[:2] != b"\xff\xd8"}
    todo = [e for e in todo if e["path"] not in not_jpeg]
    for n, e in enumerate(todo, 1):
        path = root / e["path"]
        data = path.read_bytes()
        out = subprocess.run([args.bin, "--repeat", str(args.repeat), str(path)],
                             capture_output=True, text=True, check=True).stdout
        rec = json.loads(out.strip().splitlines()[-1])
        rec.update(path=e["path"], group=e["group"], opencv_ms=opencv_ms(data, args.repeat))
        records.append(rec)
        print(f"[{n}/{len(todo)}] {e['path']} {rec['width_px']}x{rec['height_px']}: opencv "
              f"{rec['opencv_ms']:.1f} ms, qrpose {rec['ms']['qrpose']:.1f} ms, lenient "
              f"{rec['ms']['lenient']:.1f} ms", file=sys.stderr, flush=True)
    load1 = __import__("os").getloadavg()
    print(f"jpeg_decode_speed `{args.bin}` against OpenCV {cv2.__version__} IMREAD_GRAYSCALE, "
          f"{args.repeat} rounds per photo on each side (median); load average {load0[0]:.1f} -> "
          f"{load1[0]:.1f} on {__import__('os').cpu_count()} CPUs; {time.time() - t_start:.0f} s; "
          f"{len(not_jpeg)} photos skipped, not JPEG.\n")
    head = (["photos", "n", "OpenCV ms"] + [f"{v} ms" for v in VARIANTS]
            + [f"{v} / OpenCV (median / p90)" for v in VARIANTS] + ["strict rejects"])
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    classes = OrderedDict((c, []) for c in ["< 1 MP", "1-4 MP", "4-8 MP", ">= 8 MP"])
    for r in records:
        classes[size_class(r["width_px"], r["height_px"])].append(r)
    for c, recs in classes.items():
        if recs:
            print(summary_row(c, recs))
    print(summary_row("**all**", records))
    rejected = [r for r in records if not r["strict_ok"]]
    if rejected:
        extra = [r["ms"]["qrpose"] - r["ms"]["lenient"] for r in rejected]
        print(f"\nStrict mode rejects {len(rejected)} photos; on them qrpose's decode takes "
              f"{pc.median(extra):.1f} ms more than one lenient decode (median; max "
              f"{max(extra):.1f} ms): " + ", ".join(r["path"] for r in rejected[:12])
              + (" …" if len(rejected) > 12 else ""))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"repeat": args.repeat, "loadavg": [load0, load1],
                                               "photos": records}, indent=1))
        print(f"\nPer-photo times: {args.json}")


if __name__ == "__main__":
    main()
