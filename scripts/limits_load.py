#!/usr/bin/env python3
"""Helper of scripts/limits_load.sh (see its header): the Compose service's limits and
environment, the test images, and the load run against a server confined to a cgroup.

  limits_load.py compose SERVICE COMPOSE_FILE ENV_OUT   shell assignments on stdout
  limits_load.py images OUT_DIR SIM_BIN                 the test images (cached; SIM_BIN: qrpose-sim)
  limits_load.py load OUT_DIR IMAGE_DIR BASE_URL PID MEMCG CGV SECONDS CLIENTS BOUND_MIB LIMIT_BYTES

Standard library only, except `compose`, which needs PyYAML (YAML merge keys as Compose
reads them). The load exits 0 when every check holds, 1 otherwise.
"""

import http.client
import json
import os
import random
import re
import shlex
import struct
import subprocess
import sys
import threading
import time
import urllib.parse
import zlib

MIB = 1 << 20


# ---------------------------------------------------------------------------------------
# compose: limits and environment of one service


def compose_bytes(value):
    """Docker's memory units (binary: 512M is 512 MiB)."""
    if isinstance(value, int):
        return value
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([bkmgt]?)i?b?\s*", str(value).lower())
    if not m:
        raise SystemExit(f"cannot read the memory limit {value!r}")
    power = {"": 0, "b": 0, "k": 1, "m": 2, "g": 3, "t": 4}[m.group(2)]
    return int(float(m.group(1)) * (1024**power))


def cmd_compose(service, path, env_out):
    import yaml  # PyYAML: merge keys (<<) resolved as Compose resolves them

    with open(path, encoding="utf-8") as f:
        doc = yaml.safe_load(f)
    services = doc.get("services", {})
    if service not in services:
        raise SystemExit(f"no service {service!r} in {path}; services: {', '.join(services)}")
    svc = services[service]
    limits = ((svc.get("deploy") or {}).get("resources") or {}).get("limits") or {}
    if "memory" not in limits or "cpus" not in limits:
        raise SystemExit(f"service {service!r} has no deploy.resources.limits cpus and memory")
    env = svc.get("environment") or {}
    if isinstance(env, list):
        env = dict(item.split("=", 1) for item in env)
    env = {str(k): "" if v is None else str(v) for k, v in env.items()}
    with open(env_out, "w", encoding="utf-8") as f:
        for k, v in env.items():
            f.write(f"{k}={v}\n")
    mem = compose_bytes(limits["memory"])
    cpus = float(limits["cpus"])
    # docs/deploy.md, Memory: idle (10 MiB) + 3 B x max inflight pixels + max inflight body
    # bytes + 32 MiB + 32 MiB under sustained load. The defaults when unset: workers x 50 MP, (workers + 2) x body limit.
    workers = int(env.get("QRPOSE_MAX_CONCURRENT_ESTIMATIONS", os.cpu_count()))
    body_limit = int(env.get("QRPOSE_BODY_LIMIT_BYTES", 25165824))
    max_image = int(env.get("QRPOSE_MAX_IMAGE_PIXELS", 50_000_000))
    pixels = int(env.get("QRPOSE_MAX_INFLIGHT_PIXELS", workers * max_image))
    bodies = int(env.get("QRPOSE_MAX_INFLIGHT_BODY_BYTES", (workers + 2) * body_limit))
    # As the docs write it: megapixels times 3 taken as MiB (10 + 3 x 100 + 96 + 32 + 32 = 470),
    # 4.6 % above the exact 3 B x pixels.
    bound_mib = 10 + 3 * pixels / 1e6 + bodies / MIB + 32 + 32
    out = {
        "LIMIT_MEMORY_BYTES": mem,
        "LIMIT_MEMORY_TEXT": limits["memory"],
        "LIMIT_CPUS": limits["cpus"],
        "CFS_QUOTA_US": int(round(cpus * 100000)),
        "BOUND_MIB": f"{bound_mib:.0f}",
        "WORKERS": workers,
        "BODY_LIMIT": body_limit,
        "MAX_IMAGE_PIXELS": max_image,
    }
    for k, v in out.items():
        print(f"{k}={shlex.quote(str(v))}")


# ---------------------------------------------------------------------------------------
# images


def png(width, height, colour_type, rows):
    """A PNG from an iterable of raw rows (bytes without the filter byte), 8-bit."""

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    comp = zlib.compressobj(6)
    parts = []
    for row in rows:
        parts.append(comp.compress(b"\x00" + row))
    parts.append(comp.flush())
    ihdr = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", b"".join(parts))
        + chunk(b"IEND", b"")
    )


def cmd_images(out, binary):
    os.makedirs(out, exist_ok=True)
    made = {}

    def once(name, make):
        path = os.path.join(out, name)
        if not os.path.exists(path):
            data = make()
            if isinstance(data, bytes):
                with open(path + ".tmp", "wb") as f:
                    f.write(data)
                os.replace(path + ".tmp", path)
        made[name] = os.path.getsize(path)

    side = 7071  # 49,999,041 px: the largest square under QRPOSE_MAX_IMAGE_PIXELS = 50 MP
    zero = bytes(side)
    once("zero-grey-7071.png", lambda: png(side, side, 0, (zero for _ in range(side))))
    zero3 = bytes(3 * side)
    once("zero-rgb-7071.png", lambda: png(side, side, 2, (zero3 for _ in range(side))))
    # Near the 24 MiB body limit and still a valid image: 4900 x 4900 grey noise (24 MP)
    # does not compress, so the PNG is about 24.0 MB.
    rng = random.Random(16)
    noise_side = 4900
    once(
        "noise-grey-4900.png",
        lambda: png(noise_side, noise_side, 0, (rng.randbytes(noise_side) for _ in range(noise_side))),
    )

    def render(name, *args):
        def make():
            subprocess.run(
                [binary, "render", "--out", os.path.join(out, name), *args],
                check=True,
                stdout=subprocess.DEVNULL,
            )

        once(name, make)

    # A full-size 12 MP phone frame: a 50 mm code 600 mm away, clutter and noise (a large
    # JPEG at quality 95).
    render(
        "frame-4000x3000.jpg", "--width-px", "4000", "--height-px", "3000", "--fx-px", "3000",
        "--fy-px", "3000", "--payload", "SKU-12MP", "--z-mm", "600", "--alpha-deg", "15",
        "--noise", "4", "--clutter", "40", "--lighting", "0.2", "--jpeg-quality", "95",
        "--seed", "7",
    )
    render(
        "frame-1280x720.jpg", "--payload", "SKU-1", "--marker-size-mm", "50", "--x-mm", "20",
        "--z-mm", "400", "--alpha-deg", "20", "--beta-deg", "-10", "--blur-px", "0.8",
        "--noise", "2", "--lighting", "0.2", "--clutter", "10", "--seed", "3",
    )
    for name, size in made.items():
        print(f"  {name}: {size:,} bytes")


# ---------------------------------------------------------------------------------------
# load


class Stats:
    def __init__(self):
        self.lock = threading.Lock()
        self.counts = {}  # (kind, outcome) -> n
        self.latency = {}  # kind -> [s]
        self.examples = {}  # outcome -> first body seen

    def add(self, kind, outcome, seconds, body=""):
        with self.lock:
            self.counts[(kind, outcome)] = self.counts.get((kind, outcome), 0) + 1
            self.latency.setdefault(kind, []).append(seconds)
            if outcome not in self.examples:
                self.examples[outcome] = body[:300]


def outcome_of(status, body):
    if status == 200:
        return "200"
    code = ""
    try:
        code = json.loads(body).get("code", "")
    except (ValueError, AttributeError):
        pass
    return f"{status} {code}".strip()


def request(host, port, method, path, headers, body, *, slow=None, chunked=False, timeout=60):
    """One request on a fresh connection: (outcome, body text). `slow` = (chunk, pause s)
    trickles the body. A server that answers before the whole body is sent (a refusal)
    may close the connection under the upload; its answer is still read when it arrived."""
    conn = http.client.HTTPConnection(host, port, timeout=timeout)
    try:
        conn.putrequest(method, path, skip_accept_encoding=True)
        for k, v in headers.items():
            conn.putheader(k, v)
        if body is not None:
            if chunked:
                conn.putheader("Transfer-Encoding", "chunked")
            else:
                conn.putheader("Content-Length", str(len(body)))
        conn.endheaders()
        cut = False
        if body is not None:
            try:
                step = slow[0] if slow else 1 << 20
                view = memoryview(body)
                for i in range(0, len(body), step):
                    piece = view[i : i + step]
                    if chunked:
                        conn.send(f"{len(piece):x}\r\n".encode() + bytes(piece) + b"\r\n")
                    else:
                        conn.send(piece)
                    if slow:
                        time.sleep(slow[1])
                if chunked:
                    conn.send(b"0\r\n\r\n")
            except OSError:
                cut = True
        try:
            resp = conn.getresponse()
            text = resp.read().decode("utf-8", "replace")
            return outcome_of(resp.status, text), text
        except (OSError, http.client.HTTPException) as e:
            if cut:
                return "upload cut, no answer", repr(e)
            return f"connection error {type(e).__name__}", repr(e)
    except (OSError, http.client.HTTPException) as e:
        return f"connection error {type(e).__name__}", repr(e)
    finally:
        conn.close()


def read_int(path):
    try:
        with open(path, encoding="ascii") as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def read_kv(path):
    out = {}
    try:
        with open(path, encoding="ascii") as f:
            for line in f:
                parts = line.split()
                if len(parts) == 2:
                    out[parts[0]] = int(parts[1])
    except (OSError, ValueError):
        pass
    return out


def proc_kib(pid, field):
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as f:
            for line in f:
                if line.startswith(field):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def cmd_load(out, images, base_url, pid, memcg, cgv, seconds, clients, bound_mib, limit_bytes):
    pid, seconds, clients = int(pid), float(seconds), int(clients)
    bound_mib, limit_bytes = float(bound_mib), int(limit_bytes)
    url = urllib.parse.urlsplit(base_url)
    host, port = url.hostname, url.port
    img = lambda name: open(os.path.join(images, name), "rb").read()  # noqa: E731
    zero_grey, zero_rgb = img("zero-grey-7071.png"), img("zero-rgb-7071.png")
    noise, frame12, frame1 = img("noise-grey-4900.png"), img("frame-4000x3000.jpg"), img("frame-1280x720.jpg")
    cam12 = "fx_px=3000&fy_px=3000&cx_px=1999.5&cy_px=1499.5&marker_size_mm=50"
    cam1 = "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50"
    cam50 = "fx_px=5000&fy_px=5000&cx_px=3535&cy_px=3535&marker_size_mm=50"
    thorough = "&effort=thorough&max_detect_ms=60000"  # capped by the server (--max-detect-ms)
    png_h = {"Content-Type": "image/png"}
    jpg_h = {"Content-Type": "image/jpeg"}
    # kind -> (share of the clients, request maker). Each client loops until the end.
    kinds = [
        ("50MP zero grey PNG, thorough", 0.25, lambda: ("/v1/pose/image?" + cam50 + thorough, png_h, zero_grey, {})),
        ("50MP zero RGB PNG, balanced", 0.125, lambda: ("/v1/pose/image?" + cam50, png_h, zero_rgb, {})),
        ("24MB noise PNG, full speed", 0.0625, lambda: ("/v1/pose/image?" + cam50, png_h, noise, {})),
        ("24MB noise PNG, slow / chunked", 0.125, None),  # below
        ("12MP JPEG frame, thorough|balanced", 0.1875, None),
        ("1280x720 JPEG frame", 0.25, lambda: ("/v1/pose/image?" + cam1, jpg_h, frame1, {})),
    ]
    slow_turn = [0]

    def slow_noise():
        slow_turn[0] += 1
        chunked = slow_turn[0] % 2 == 0
        # About 3-4 MB/s: the upload takes 6-8 s of the 10 s request timeout.
        return ("/v1/pose/image?" + cam50, png_h, noise, {"slow": (256 << 10, 0.07), "chunked": chunked})

    frame_turn = [0]

    def frame_12mp():
        frame_turn[0] += 1
        q = cam12 + (thorough if frame_turn[0] % 2 else "")
        return ("/v1/pose/image?" + q, jpg_h, frame12, {})

    makers = {
        "24MB noise PNG, slow / chunked": slow_noise,
        "12MP JPEG frame, thorough|balanced": frame_12mp,
    }
    plan = []
    for name, share, make in kinds:
        n = max(1, round(share * clients))
        plan += [(name, make or makers[name])] * n
    plan = plan[:clients] if len(plan) > clients else plan

    stats = Stats()
    stop = threading.Event()
    samples = {"cg_peak_sampled": 0, "rss_max_kib": 0, "anon_at_peak": 0, "file_at_peak": 0}

    def client(name, make):
        while not stop.is_set():
            path, headers, body, opts = make()
            t0 = time.monotonic()
            outcome, text = request(host, port, "POST", path, headers, body,
                                    slow=opts.get("slow"), chunked=opts.get("chunked", False))
            stats.add(name, outcome, time.monotonic() - t0, text)
            if outcome != "200":
                time.sleep(0.05)  # a hostile client: retries at once, Retry-After ignored

    corners_body = json.dumps({
        "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
        "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5},
        "marker": {"size_mm": 50},
    }).encode()

    def corners():
        while not stop.is_set():
            t0 = time.monotonic()
            outcome, text = request(host, port, "POST", "/v1/pose/corners",
                                    {"Content-Type": "application/json"}, corners_body, timeout=30)
            stats.add("corners (JSON)", outcome, time.monotonic() - t0, text)
            time.sleep(0.02)

    health = {"max": 0.0, "n": 0, "failed": 0, "over_1s": 0, "fail_examples": []}

    def healthz():
        while not stop.is_set():
            t0 = time.monotonic()
            outcome, text = request(host, port, "GET", "/healthz", {}, None, timeout=10)
            dt = time.monotonic() - t0
            health["n"] += 1
            health["max"] = max(health["max"], dt)
            if dt > 1:
                health["over_1s"] += 1
            if outcome != "200":
                health["failed"] += 1
                health["fail_examples"].append(f"{outcome}: {text[:120]}")
            time.sleep(0.1)

    usage_file = f"{memcg}/memory.usage_in_bytes" if cgv == "1" else f"{memcg}/memory.current"

    def sampler():
        while not stop.is_set():
            u = read_int(usage_file) or 0
            if u > samples["cg_peak_sampled"]:
                samples["cg_peak_sampled"] = u
                st = read_kv(f"{memcg}/memory.stat")
                samples["anon_at_peak"] = st.get("total_rss", st.get("rss", st.get("anon", 0)))
                samples["file_at_peak"] = st.get("total_cache", st.get("cache", st.get("file", 0)))
            r = proc_kib(pid, "VmRSS:")
            if r:
                samples["rss_max_kib"] = max(samples["rss_max_kib"], r)
            time.sleep(0.02)

    threads = [threading.Thread(target=client, args=p, daemon=True) for p in plan]
    threads += [threading.Thread(target=corners, daemon=True) for _ in range(2)]
    aux = [threading.Thread(target=healthz, daemon=True), threading.Thread(target=sampler, daemon=True)]
    print(f"load: {len(plan)} image clients, 2 corners clients, /healthz every 100 ms, {seconds:.0f} s")
    for name in dict.fromkeys(n for n, _ in plan):
        print(f"  {sum(1 for n, _ in plan if n == name):2d} x {name}")
    t_start = time.monotonic()
    for t in aux + threads:
        t.start()
    while time.monotonic() - t_start < seconds:
        time.sleep(1)
        if not os.path.exists(f"/proc/{pid}"):
            print("the server process is gone")
            break
    stop.set()
    for t in threads:
        t.join(timeout=90)
    stop_hz = time.monotonic()
    for t in aux:
        t.join(timeout=15)
    elapsed = stop_hz - t_start

    # ---- report
    def summary(cgfile):
        return read_int(f"{memcg}/{cgfile}")

    if cgv == "1":
        peak = summary("memory.max_usage_in_bytes")
        failcnt = summary("memory.failcnt")
        oom = read_kv(f"{memcg}/memory.oom_control")
        oom_kills = oom.get("oom_kill", 0)
        under_oom = oom.get("under_oom", 0)
        memsw_fail = summary("memory.memsw.failcnt")
    else:
        peak = summary("memory.peak") or samples["cg_peak_sampled"]
        events = read_kv(f"{memcg}/memory.events")
        failcnt = events.get("max", 0)
        oom_kills = events.get("oom_kill", 0)
        under_oom = 0
        memsw_fail = None
    alive = os.path.exists(f"/proc/{pid}") and open(f"/proc/{pid}/stat").read().split()[2] != "Z"
    hwm_kib = proc_kib(pid, "VmHWM:") if alive else None

    outcomes = {}
    for (kind, outcome), n in stats.counts.items():
        outcomes[outcome] = outcomes.get(outcome, 0) + n
    total = sum(outcomes.values())
    print()
    print(f"ran {elapsed:.0f} s, {total} requests (healthz not counted)")
    print()
    print("| client | requests | outcomes | p50 s | max s |")
    print("|---|---:|---|---:|---:|")
    for kind in list(dict.fromkeys([n for n, _ in plan])) + ["corners (JSON)"]:
        lat = sorted(stats.latency.get(kind, []))
        if not lat:
            print(f"| {kind} | 0 | | | |")
            continue
        outs = ", ".join(f"{o}: {n}" for (k, o), n in sorted(stats.counts.items()) if k == kind)
        print(f"| {kind} | {len(lat)} | {outs} | {lat[len(lat) // 2]:.2f} | {lat[-1]:.2f} |")
    print()
    print("all outcomes: " + ", ".join(f"{o}: {n}" for o, n in sorted(outcomes.items())))
    for o, ex in stats.examples.items():
        if o != "200":
            print(f"  first '{o}': {ex[:200]}")
    print(f"/healthz: {health['n']} polls, {health['failed']} failed, max latency "
          f"{health['max'] * 1000:.0f} ms, {health['over_1s']} over 1 s")
    for ex in health["fail_examples"][:5]:
        print(f"  {ex}")
    mib = lambda b: f"{b / MIB:.1f} MiB" if b is not None else "n/a"  # noqa: E731
    print(f"cgroup peak: {mib(peak)} (limit {mib(limit_bytes)}, docs' bound {bound_mib:.0f} MiB); "
          f"sampled every 20 ms: {mib(samples['cg_peak_sampled'])}, of it anon "
          f"{mib(samples['anon_at_peak'])}, page cache {mib(samples['file_at_peak'])}")
    print(f"process VmHWM: {mib(hwm_kib * 1024) if hwm_kib else 'n/a'}; "
          f"max VmRSS sampled: {mib(samples['rss_max_kib'] * 1024)}")
    print(f"memory.failcnt: {failcnt}" + (f", memsw.failcnt: {memsw_fail}" if memsw_fail is not None else "")
          + f"; OOM kills: {oom_kills}, under_oom: {under_oom}; server alive: {alive}")

    bad_5xx = {o: n for o, n in outcomes.items()
               if o.startswith("5") and o not in ("503 overloaded", "503 timeout")}
    conn_err = {o: n for o, n in outcomes.items() if o.startswith("connection error") or o.startswith("upload cut")}
    checks = [
        (oom_kills == 0 and under_oom == 0, f"no OOM kill (oom_kill {oom_kills}, under_oom {under_oom})"),
        (alive, "server alive at the end"),
        (peak is not None and peak < limit_bytes, f"peak {mib(peak)} < limit {mib(limit_bytes)}"),
        (not bad_5xx, f"no 5xx but 503 overloaded/timeout ({bad_5xx or 'none'})"),
        (health["failed"] == 0 and health["n"] > 0, f"/healthz always answered ({health['failed']} of {health['n']} failed)"),
        (not conn_err, f"no connection errors ({conn_err or 'none'})"),
    ]
    print()
    status = 0
    for ok, text in checks:
        print(("PASS: " if ok else "FAIL: ") + text)
        status |= not ok
    info_ok = peak is not None and peak <= bound_mib * MIB
    print(("within" if info_ok else "ABOVE") + f" the docs' bound: peak {mib(peak)} vs {bound_mib:.0f} MiB")
    with open(os.path.join(out, "result.json"), "w", encoding="utf-8") as f:
        json.dump({
            "elapsed_s": elapsed, "outcomes": outcomes,
            "by_client": {f"{k} | {o}": n for (k, o), n in stats.counts.items()},
            "healthz": {k: v for k, v in health.items() if k != "fail_examples"},
            "cgroup_peak_bytes": peak, "limit_bytes": limit_bytes, "bound_mib": bound_mib,
            "sampled": samples, "vmhwm_kib": hwm_kib, "failcnt": failcnt,
            "oom_kills": oom_kills, "under_oom": under_oom, "alive": alive, "status": status,
        }, f, indent=1)
    return status


def main():
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    cmd, args = sys.argv[1], sys.argv[2:]
    if cmd == "compose":
        cmd_compose(*args)
    elif cmd == "images":
        cmd_images(*args)
    elif cmd == "load":
        sys.exit(cmd_load(*args))
    else:
        raise SystemExit(__doc__)


if __name__ == "__main__":
    main()
