#!/usr/bin/env python3
"""Load and soak of the stream, GET /v1/stream (docs/stream.md, "Measured").

  stream_load.py latency [options]   N sessions at F fps for a duration: per-frame latency
                                     p50/p95/p99, frames answered and dropped, server CPU/RSS
  stream_load.py soak [options]      20 sessions for 5 minutes of mixed clients (normal,
                                     cut mid-frame, garbage, stalled) reconnecting after each
                                     end; checks that the server stays up, RSS stays flat,
                                     every session was answered or closed with a documented
                                     code, and /metrics comes back to 0 sessions open; with
                                     its own server, then opens --max-stream-sessions
                                     sessions (one more must get 1013) and sends SIGTERM
                                     (each must get 1001; exit code 0)
  stream_load.py session --url URL   one session of rendered frames, answers checked
                                     (docker/smoke.sh runs it through the balancer)

  scripts/stream_load.py latency --qrpose-bin target/release/qrpose
  scripts/stream_load.py soak --qrpose-bin target/release/qrpose --duration-s 300

The server: `--qrpose-bin BIN`; the qrpose-sim beside it renders the frames (`qrpose-sim render --sequence NAME --out DIR
--frames N`, cached under target/stream-load/; `--frames-dir` takes frames rendered before)
and, without `--url`, is started as
`BIN serve --addr 127.0.0.1:0 [--server-arg ARG]...` (its "listening on" line read, its log
kept, SIGTERM at the end). With `--url`, an external server is used; `--server-pid` and
`--server-log` let its CPU, RSS and log be checked. The machine's load (/proc/loadavg, and
the busy CPU of the whole machine, the server and this client) is reported with each run:
the client shares the machine with the server.

Writes a JSON summary (`--json`, default target/stream-load/MODE-TIME.json) and prints a
short table. `soak` exits 1 when a check fails; `latency` when nothing was answered.
Runs in its own venv, target/stream-load-venv (websockets from PyPI, pinned), made on
first use. The clients are in scripts/stream_clients.py; the server's and the machine's
measures in scripts/stream_server.py.
"""

import argparse
import asyncio
import json
import os
import subprocess
import sys
import time
import urllib.request
import venv
from pathlib import Path

sys.dont_write_bytecode = True  # no __pycache__ beside the scripts
from stream_server import (  # noqa: E402
    Server, Usage, metric, metrics, percentile, sample_rss, slope_per_min)

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / "target" / "stream-load-venv"
PACKAGES = ["websockets==17.4"]
WORK = ROOT / "target" / "stream-load"


def ensure_venv():
    """Re-runs this script inside VENV with PACKAGES installed."""
    python = VENV / "bin" / "python"
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    if not python.exists():
        venv.EnvBuilder(with_pip=True).create(VENV)
    probe = subprocess.run([str(python), "-c", "import websockets"], capture_output=True)
    if probe.returncode != 0:
        subprocess.run([str(python), "-m", "pip", "install", "-q",
                        "--disable-pip-version-check", *PACKAGES], check=True)
    os.execv(str(python), [str(python), __file__, *sys.argv[1:]])


# ---------------------------------------------------------------------------------------
# frames


def render_frames(qrpose_bin, sequence, count):
    """JPEG frames of `qrpose-sim render --sequence`, rendered once and cached (keyed by the
    binary's size and time). Returns (frames as bytes, sequence.json, seconds spent)."""
    out = WORK / "frames" / f"{sequence}-{count}"
    stamp = out / "stamp.json"
    st = os.stat(qrpose_bin)
    key = {"bin": str(Path(qrpose_bin).resolve()), "size": st.st_size, "mtime": st.st_mtime}
    t0 = time.monotonic()
    if not (stamp.exists() and json.loads(stamp.read_text()) == key):
        out.mkdir(parents=True, exist_ok=True)
        for old in out.glob("frame_*.jpg"):
            old.unlink()
        sim_bin = Path(qrpose_bin).with_name("qrpose-sim")
        subprocess.run([str(sim_bin), "render", "--sequence", sequence, "--out", str(out),
                        "--frames", str(count)], check=True, stdout=subprocess.DEVNULL)
        stamp.write_text(json.dumps(key))
    files = sorted(out.glob("frame_*.jpg"))
    if not files:
        raise SystemExit(f"no frames in {out}")
    spec = json.loads((out / "sequence.json").read_text())
    return [f.read_bytes() for f in files], spec, time.monotonic() - t0


def stream_query(spec):
    """The session's query string for a rendered sequence: its camera, and the size of most of
    its codes (a load measurement does not need every code's size right)."""
    cam = spec["camera"]
    q = {"fx_px": cam["fx_px"], "fy_px": cam["fy_px"],  # the principal point's default:
         "cx_px": cam.get("cx_px", (spec["width_px"] - 1) / 2),  # the image centre
         "cy_px": cam.get("cy_px", (spec["height_px"] - 1) / 2)}
    dist = cam.get("distortion") or {}
    if dist.get("model") == "plumb_bob":
        q.update(zip(("k1", "k2", "p1", "p2", "k3"), dist["coefficients"]))
    sizes = [c.get("size_mm", 50) for c in spec.get("codes", [])] or [50]
    q["marker_size_mm"] = max(set(sizes), key=sizes.count)
    return "&".join(f"{k}={v}" for k, v in q.items())


# ---------------------------------------------------------------------------------------
# modes


async def run_latency(a, server, frames, query):
    """`a.sessions` paced sessions at once, staggered within a frame period; the summary and
    whether anything was answered without an error."""
    import stream_clients as sc

    url = f"{server.url.replace('http', 'ws', 1)}/v1/stream?{query}"
    m0 = metrics(server.url)
    usage = Usage(server)
    rss, stop = [], asyncio.Event()
    sampler = asyncio.create_task(sample_rss(server, 1.0, stop, rss))
    start = time.monotonic() + 0.5
    results = await asyncio.gather(*[
        sc.paced_session(url, frames, a.fps, a.duration_s, start + i / (a.fps * a.sessions),
                         offset=i * len(frames) // a.sessions)
        for i in range(a.sessions)])
    use = usage.end()
    stop.set()
    await sampler
    m1 = metrics(server.url)
    lat = [x for r in results for x in r["latencies_ms"]]
    count = metric(m1, "stream_frame_duration_seconds_count") - metric(
        m0, "stream_frame_duration_seconds_count")
    total = metric(m1, "stream_frame_duration_seconds_sum") - metric(
        m0, "stream_frame_duration_seconds_sum")
    summary = {
        "mode": "latency", "sessions": a.sessions, "fps": a.fps, "duration_s": a.duration_s,
        "frames_sent": sum(r["sent"] for r in results),
        "frames_answered": len(lat),
        "frames_dropped": sum(r["dropped"] for r in results),
        "frames_skipped_by_client": sum(r["late"] for r in results),
        "problems": sum(r["problems"] for r in results),
        "answered_fps": round(len(lat) / a.duration_s, 1),
        "latency_ms": {f"p{p}": round(percentile(lat, p), 1) if lat else None
                       for p in (50, 95, 99)} | {"max": round(max(lat), 1) if lat else None},
        "server_frame_ms_mean": round(1e3 * total / count, 1) if count else None,
        "markers_per_answer": round(sum(r["markers"] for r in results) / max(1, len(lat)), 2),
        "rss_mib": {"first": rss[0][1] if rss else None, "max": max(v for _, v in rss)
                    if rss else None, "last": rss[-1][1] if rss else None},
        "machine": use,
        "errors": [e for r in results for e in r["errors"]][:10],
    }
    ok = bool(lat) and not summary["errors"]
    return summary, ok


async def run_soak(a, server, frames, query):
    """The soak's slots until the deadline, then its checks (and, with the server started
    here, the last phase); the summary and whether every check held."""
    import stream_clients as sc

    url = f"{server.url.replace('http', 'ws', 1)}/v1/stream?{query}"
    mix = dict(part.split("=") for part in a.mix.split(","))
    kinds = [k for k, n in mix.items() for _ in range(int(n))]
    if len(kinds) != a.sessions:
        raise SystemExit(f"--mix names {len(kinds)} sessions, --sessions is {a.sessions}")
    m0 = metrics(server.url)
    usage = Usage(server)
    rss, opened, stop = [], [], asyncio.Event()
    sampler = asyncio.create_task(sample_rss(server, a.sample_s, stop, rss, opened))
    deadline = time.monotonic() + a.duration_s
    ctx = sc.Soak(url, frames, a.fps, a.idle_timeout_s, deadline, seed=a.seed)
    await asyncio.gather(*[ctx.slot(i, kind) for i, kind in enumerate(kinds)])
    use = usage.end()
    # The server's own count of sessions comes back to 0 once every session has ended.
    open_now = None
    for _ in range(50):
        m1 = metrics(server.url)
        open_now = metric(m1, "stream_sessions_open")
        if open_now == 0:
            break
        await asyncio.sleep(0.2)
    tracks_live = sum(v for k, v in m1.items() if "stream_tracks{" in k)
    stop.set()
    await sampler
    settled = [(t, v) for t, v in rss if t >= a.warmup_s]
    slope = slope_per_min(settled)
    with urllib.request.urlopen(f"{server.url}/healthz", timeout=10) as r:
        healthy = r.status == 200 and server.alive()
    final = None
    if server.proc is not None:
        a.frames_bytes = frames
        final = await sc.final_phase(
            server, url, a, lambda: metric(metrics(server.url), "stream_sessions_open"))
    outcomes = ctx.outcomes
    bad = [o for o in outcomes if not o["ok"]]
    panics = server.panics()
    checks = {
        "server up, /healthz 200": healthy,
        "no panic in the server log": panics == [] if panics is not None else None,
        f"RSS flat: slope after {a.warmup_s} s <= {a.max_slope_mib_per_min} MiB/min":
            slope is not None and slope <= a.max_slope_mib_per_min,
        "every session answered or closed with 1000/1001/1008/1013": not bad,
        "every stalled session closed with 1008": all(
            o["close"] == 1008 for o in outcomes if o["kind"] == "stall" and o["answers"]),
        "stream_sessions_open back to 0": open_now == 0,
        "stream_tracks back to 0": tracks_live == 0,
        "sessions refused (server) >= 1013 seen + resets before an answer": metric(
            m1, "stream_sessions_refused_total") - metric(m0, "stream_sessions_refused_total")
        >= sum(o["close"] in (1013, "reset before an answer") for o in outcomes),
        "frames answered (server) >= answers received": metric(
            m1, "stream_frames_answered_total") - metric(m0, "stream_frames_answered_total")
        >= sum(o["answers"] for o in outcomes),
    }
    if final is not None:
        checks.update(final["checks"])
    by_kind = {}
    for o in outcomes:
        k = by_kind.setdefault(o["kind"], {"sessions": 0, "answers": 0, "closes": {},
                                           "problems": {}, "variants": {}})
        k["sessions"] += 1
        k["answers"] += o["answers"]
        close = "none (the client cut)" if o["close"] is None else str(o["close"])
        for field, key, n in [("closes", close, 1),
                              ("variants", o.get("variant"), 1),
                              *[("problems", c, n) for c, n in o["problem_codes"].items()]]:
            if key is not None:
                k[field][key] = k[field].get(key, 0) + n
        if o["kind"] == "stall":
            k.setdefault("closed_after_s", []).append(o.get("closed_after_s"))
    for k in by_kind.values():
        waits = [x for x in k.pop("closed_after_s", []) if x is not None]
        if waits:
            k["idle_close_after_s_min_max"] = [min(waits), max(waits)]
    summary = {
        "mode": "soak", "sessions": a.sessions, "mix": mix, "duration_s": a.duration_s,
        "fps": a.fps, "sessions_run": len(outcomes), "by_kind": by_kind,
        "answers": sum(o["answers"] for o in outcomes),
        "dropped": sum(o["dropped"] for o in outcomes),
        "server_metrics_delta": {n: metric(m1, n) - metric(m0, n) for n in (
            "stream_frames_answered_total", "stream_frames_dropped_total",
            "stream_sessions_refused_total", "stream_tracks_lost_total")},
        "rss_mib": {"first": rss[0][1] if rss else None,
                    "at_warmup": settled[0][1] if settled else None,
                    "last": rss[-1][1] if rss else None,
                    "max": max(v for _, v in rss) if rss else None,
                    "slope_mib_per_min_after_warmup": None if slope is None
                    else round(slope, 2), "samples": rss},
        "stream_sessions_open_max": max((v for _, v in opened), default=None),
        "stream_sessions_open_samples": opened,
        "machine": use, "final_phase": final,
        "panics": panics, "failures_total": len(bad), "failures": bad[:10],
        "checks": checks,
    }
    return summary, all(v is not False for v in checks.values())


def table(s):
    """A short human summary."""
    r, m = s["rss_mib"], s["machine"]
    if s["mode"] == "latency":
        lat = s["latency_ms"]
        rows = [("sessions x fps", f"{s['sessions']} x {s['fps']} for {s['duration_s']} s"),
                ("frames sent / answered / dropped",
                 f"{s['frames_sent']} / {s['frames_answered']} / {s['frames_dropped']}"
                 f" (client skipped {s['frames_skipped_by_client']})"),
                ("latency p50 / p95 / p99 / max ms",
                 f"{lat['p50']} / {lat['p95']} / {lat['p99']} / {lat['max']}"),
                ("server mean, arrival to answer ms", s["server_frame_ms_mean"]),
                ("server RSS MiB first / max / last", f"{r['first']} / {r['max']} / {r['last']}")]
    else:
        rows = [("sessions", f"{s['sessions']} ({s['mix']}) for {s['duration_s']} s: "
                 f"{s['sessions_run']} sessions, {s['answers']} answers")]
        rows += [(f"  {k}", f"{v['sessions']} sessions, {v['answers']} answers, closes "
                  f"{v['closes']}") for k, v in s["by_kind"].items()]
        rows += [("server's stream_sessions_open max", s["stream_sessions_open_max"]),
                 ("RSS MiB first / at warmup / last / max",
                  f"{r['first']} / {r['at_warmup']} / {r['last']} / {r['max']}"),
                 ("RSS slope after warmup", f"{r['slope_mib_per_min_after_warmup']} MiB/min")]
    rows.append(("CPU cores: server / client / others",
                 f"{m['server_cores']} / {m['client_cores']} / {m['others_cores']}"
                 f" of {m['cpus']}; load {' '.join(m['loadavg_start'])}"))
    for name, ok in s.get("checks", {}).items():
        rows.append((name, "PASS" if ok else "SKIP" if ok is None else "FAIL"))
    return "\n".join(f"{k:<44} {v}" for k, v in rows)


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mode", choices=["latency", "soak", "session"])
    p.add_argument("--qrpose-bin", default=str(ROOT / "target" / "release" / "qrpose"))
    p.add_argument("--url", help="an external server (http://HOST:PORT); default: start one")
    p.add_argument("--server-pid", type=int)
    p.add_argument("--server-log")
    p.add_argument("--server-arg", action="append", default=[],
                   help="an argument of `qrpose serve` (repeat)")
    p.add_argument("--sequence", default="approach")
    p.add_argument("--frames-dir", help="frames already rendered (the --out of `qrpose-sim render "
                   "--sequence`); nothing is rendered")
    p.add_argument("--frames", type=int, default=120, help="frames to render (played back "
                   "and forth)")
    p.add_argument("--sessions", type=int)
    p.add_argument("--fps", type=float, default=30)
    p.add_argument("--duration-s", type=float)
    p.add_argument("--mix", default="normal=10,disconnect=4,garbage=3,stall=3")
    p.add_argument("--idle-timeout-s", type=float, default=30,
                   help="the server's --stream-idle-timeout-ms, in s (stalled clients wait)")
    p.add_argument("--sample-s", type=float, default=5)
    p.add_argument("--warmup-s", type=float, default=60)
    p.add_argument("--max-slope-mib-per-min", type=float, default=2.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", help="where the JSON summary goes")
    a = p.parse_args(argv)
    defaults = {"latency": (4, 30), "soak": (20, 300), "session": (1, 0)}[a.mode]
    a.sessions = a.sessions or defaults[0]
    a.duration_s = a.duration_s if a.duration_s is not None else defaults[1]
    return a


def server_flag(args, name):
    """The value of `name` among `qrpose serve`'s arguments (`--x V` or `--x=V`), or None."""
    for i, arg in enumerate(args):
        if arg == name and i + 1 < len(args):
            return args[i + 1]
        if arg.startswith(name + "="):
            return arg.split("=", 1)[1]
    return None


def main(argv):
    a = parse_args(argv)
    ensure_venv()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import stream_clients as sc

    if a.frames_dir:
        d = Path(a.frames_dir)
        frames = [f.read_bytes() for f in sorted(d.glob("frame_*.jpg"))]
        spec, render_s = json.loads((d / "sequence.json").read_text()), 0.0
        a.sequence = spec.get("name", d.name)
    else:
        frames, spec, render_s = render_frames(a.qrpose_bin, a.sequence, a.frames)
    query = stream_query(spec)
    if a.mode == "session":
        if not a.url:
            raise SystemExit("session needs --url")
        result = asyncio.run(sc.checked_session(a.url, frames, query))
        print(json.dumps(result))
        return 0 if result["ok"] else 1
    # The session limit the soak's last phase fills: the flag, its variable or its default.
    limit = server_flag(a.server_arg, "--max-stream-sessions")
    a.session_limit = int(limit or os.environ.get("QRPOSE_MAX_STREAM_SESSIONS", 64))
    idle_ms = server_flag(a.server_arg, "--stream-idle-timeout-ms")
    if idle_ms is not None:
        a.idle_timeout_s = float(idle_ms) / 1e3
    server = (Server(a.url, a.server_pid, a.server_log) if a.url
              else Server.start(a.qrpose_bin, a.server_arg, WORK))
    print(f"server {server.url} (pid {server.pid}, log {server.log}); {len(frames)} frames of "
          f"{a.sequence} ({sum(map(len, frames)) // len(frames) // 1024} KiB each, rendered "
          f"or cached in {render_s:.1f} s); query {query}", flush=True)
    try:
        run = run_latency if a.mode == "latency" else run_soak
        summary, ok = asyncio.run(run(a, server, frames, query))
    finally:
        code = server.stop()
    summary.update({"date": time.strftime("%Y-%m-%d %H:%M:%S %z"), "sequence": a.sequence,
                    "frames": len(frames), "query": query, "server": server.url,
                    "server_args": a.server_arg, "server_exit_code": code,
                    "server_log": str(server.log) if server.log else None})
    if server.proc is not None and a.mode == "soak":
        summary["checks"]["server exits 0 on SIGTERM"] = code == 0
        ok = ok and code == 0
    out = Path(a.json) if a.json else WORK / f"{a.mode}-{time.strftime('%Y%m%dT%H%M%S')}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=1))
    print(table(summary))
    print(f"summary: {out}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
