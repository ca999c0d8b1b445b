"""The server under test and the machine it shares, for scripts/stream_load.py (see its
header): the server started (its "listening on" line read, its log kept) or attached to; its
CPU time and RSS from /proc; the whole machine's busy CPU and load; /metrics read; and the
statistics of a run (percentiles, an RSS slope). Standard library only.
"""

import asyncio
import os
import re
import signal
import subprocess
import threading
import time
import urllib.request
from pathlib import Path

CLK_TCK = os.sysconf("SC_CLK_TCK")
PAGE = os.sysconf("SC_PAGE_SIZE")


class Server:
    """The server under test: started here (`start`) or external (`attach`)."""

    def __init__(self, url, pid=None, log=None, proc=None):
        self.url, self.pid, self.log, self.proc = url, pid, log, proc

    @classmethod
    def start(cls, qrpose_bin, args, work):
        """`qrpose serve` on a free loopback port, its log in `work`."""
        work.mkdir(parents=True, exist_ok=True)
        log = work / f"server-{time.strftime('%Y%m%dT%H%M%S')}.log"
        cmd = [qrpose_bin, "serve", "--addr", "127.0.0.1:0", *args]
        f = open(log, "wb")
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=f)
        line = proc.stdout.readline().decode()
        m = re.search(r"listening on (http://\S+)", line)
        if not m:
            proc.kill()
            raise SystemExit(f"the server did not say where it listens: {line!r} (log {log})")
        # Keep draining stdout so the server never blocks on it.
        threading_drain(proc.stdout, f)
        return cls(m.group(1), proc.pid, log, proc)

    def alive(self):
        """The process still runs (an external one without a PID: assumed)."""
        if self.proc is not None:
            return self.proc.poll() is None
        return self.pid is None or Path(f"/proc/{self.pid}").exists()

    def cpu_s(self):
        """User + system CPU seconds so far, or None."""
        if self.pid is None or not self.alive():
            return None
        fields = Path(f"/proc/{self.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / CLK_TCK

    def rss_mib(self):
        """Resident memory, MiB, or None."""
        if self.pid is None or not self.alive():
            return None
        fields = Path(f"/proc/{self.pid}/statm").read_text().split()
        return int(fields[1]) * PAGE / (1 << 20)

    def panics(self):
        """The log's lines that mention a panic (None without a log)."""
        if self.log is None or not Path(self.log).exists():
            return None
        text = Path(self.log).read_text(errors="replace")
        return [ln for ln in text.splitlines() if "panic" in ln.lower()][:5]

    def stop(self, timeout_s=20):
        """SIGTERM, then the exit code (None if it had to be killed)."""
        if self.proc is None:
            return None
        self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            return None


def threading_drain(pipe, sink):
    """Copies `pipe` to `sink` on a thread, so that the server never blocks writing to it."""

    def run():
        for chunk in iter(lambda: pipe.read(4096), b""):
            sink.write(chunk)
            sink.flush()

    threading.Thread(target=run, daemon=True).start()


def machine_ticks():
    """(busy, total) CPU ticks of the whole machine, from /proc/stat."""
    v = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    idle = v[3] + (v[4] if len(v) > 4 else 0)
    return sum(v) - idle, sum(v)


class Usage:
    """CPU used over an interval by the machine, the server and this client (in cores)."""

    def __init__(self, server):
        self.server = server
        self.t0 = time.monotonic()
        self.load0 = Path("/proc/loadavg").read_text().split()[:3]
        self.m0 = machine_ticks()
        self.s0 = server.cpu_s()
        self.c0 = sum(os.times()[:2])

    def end(self):
        dt = time.monotonic() - self.t0
        m1, s1, c1 = machine_ticks(), self.server.cpu_s(), sum(os.times()[:2])
        ncpu = os.cpu_count()
        busy = (m1[0] - self.m0[0]) / max(1, m1[1] - self.m0[1]) * ncpu
        server = None if s1 is None or self.s0 is None else (s1 - self.s0) / dt
        return {"seconds": round(dt, 1), "cpus": ncpu,
                "loadavg_start": self.load0,
                "loadavg_end": Path("/proc/loadavg").read_text().split()[:3],
                "machine_busy_cores": round(busy, 2),
                "server_cores": None if server is None else round(server, 2),
                "client_cores": round((c1 - self.c0) / dt, 2),
                "others_cores": None if server is None
                else round(busy - server - (c1 - self.c0) / dt, 2)}


def metrics(url):
    """The server's /metrics as {name{labels}: value}."""
    with urllib.request.urlopen(f"{url}/metrics", timeout=10) as r:
        text = r.read().decode()
    out = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            name, _, value = line.rpartition(" ")
            try:
                out[name] = float(value)
            except ValueError:
                pass
    return out


def metric(m, name):
    """A metric by name, the `qrpose_` prefix optional; 0 when absent."""
    return m.get(f"qrpose_{name}", m.get(name, 0.0))


def percentile(values, p):
    """The p-th percentile (linear between closest ranks); None for no values."""
    if not values:
        return None
    s = sorted(values)
    k = (len(s) - 1) * p / 100
    lo = int(k)
    hi = min(lo + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (k - lo)


def slope_per_min(samples):
    """Least-squares slope of (t_s, value) samples, per minute."""
    if len(samples) < 3:
        return None
    n = len(samples)
    mt = sum(t for t, _ in samples) / n
    mv = sum(v for _, v in samples) / n
    var = sum((t - mt) ** 2 for t, _ in samples)
    return 60 * sum((t - mt) * (v - mv) for t, v in samples) / var if var else None


async def sample_rss(server, every_s, stop, out, sessions=None):
    """Appends (t_s, RSS MiB) to `out` every `every_s` until `stop` is set; with `sessions`
    a list, also (t_s, the server's stream_sessions_open) read from /metrics off the loop."""
    t0 = time.monotonic()
    while not stop.is_set():
        rss = server.rss_mib()
        t = round(time.monotonic() - t0, 1)
        if rss is not None:
            out.append((t, round(rss, 1)))
        if sessions is not None:
            m = await asyncio.to_thread(metrics, server.url)
            sessions.append((t, metric(m, "stream_sessions_open")))
        try:
            await asyncio.wait_for(stop.wait(), every_s)
        except asyncio.TimeoutError:
            pass
