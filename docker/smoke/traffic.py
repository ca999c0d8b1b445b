#!/usr/bin/env python3
"""Traffic of docker/smoke.sh against containers on loopback: image requests in flight
across `docker stop`, and load through the Compose balancer while a replica is killed.

  traffic.py stop URL IMAGE_DIR REQUESTS EFFORT CONTAINER DOCKER
      REQUESTS POSTs of the 4000x3000 frame, `docker stop CONTAINER` once their bodies are
      sent; exit 0 when every request was answered 200, at least one of them after the stop
      began (they were in flight), and the stop took less than Docker's 10 s timeout.
  traffic.py failover URL IMAGE_DIR SECONDS CLIENTS KILL_PID KILL_AFTER_S OUT_JSON
      CLIENTS loops of image requests (1280x720 and 4000x3000 frames, each with its own
      X-Request-Id) for SECONDS; SIGKILL to KILL_PID (a replica's process) after
      KILL_AFTER_S. Writes every request's times and outcome to OUT_JSON.
  traffic.py failover-count OUT_JSON LB_LOG KILLED_ADDR
      Joins OUT_JSON with the balancer's access log (docker/nginx.conf's `upstreams` format)
      and counts: requests sent, answered, lost; those in flight on the killed replica when
      it died, and what became of them. Exit 0 when no request was lost beyond those in
      flight on the killed replica.

Standard library only. Only loopback addresses are contacted (the published ports).
"""

import http.client
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
import urllib.parse

CAM12 = "fx_px=3000&fy_px=3000&cx_px=1999.5&cy_px=1499.5&marker_size_mm=50"
CAM1 = "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50"


def outcome_of(status, body):
    """'200', or the status and the problem document's code ('503 overloaded')."""
    if status == 200:
        return "200"
    code = ""
    try:
        code = json.loads(body).get("code", "")
    except (ValueError, AttributeError):
        pass
    return f"{status} {code}".strip()


def post(base_url, path, body, content_type, *, request_id=None, sent=None, timeout=60):
    """One POST on a fresh connection: (outcome, end time). `sent` is set once the body is
    written."""
    url = urllib.parse.urlsplit(base_url)
    conn = http.client.HTTPConnection(url.hostname, url.port, timeout=timeout)
    try:
        headers = {"Content-Type": content_type, "Content-Length": str(len(body))}
        if request_id:
            headers["X-Request-Id"] = request_id
        conn.request("POST", path, body=body, headers=headers)
        if sent is not None:
            sent.set()
        resp = conn.getresponse()
        text = resp.read().decode("utf-8", "replace")
        return outcome_of(resp.status, text), time.time()
    except (OSError, http.client.HTTPException) as e:
        return f"connection error {type(e).__name__}", time.time()
    finally:
        if sent is not None:
            sent.set()
        conn.close()


def read(path):
    with open(path, "rb") as f:
        return f.read()


def cmd_stop(base_url, image_dir, requests, effort, container, docker):
    frame = read(os.path.join(image_dir, "frame-4000x3000.jpg"))
    path = f"/v1/pose/image?{CAM12}&effort={effort}"
    n = int(requests)
    results = [None] * n
    sent = [threading.Event() for _ in range(n)]

    def one(i):
        results[i] = post(base_url, path, frame, "image/jpeg", sent=sent[i])

    threads = [threading.Thread(target=one, args=(i,)) for i in range(n)]
    for t in threads:
        t.start()
    for e in sent:
        e.wait(timeout=20)
    time.sleep(0.2)
    t_stop = time.time()
    stop = subprocess.run([docker, "stop", "-t", "10", container], capture_output=True, text=True)
    stop_s = time.time() - t_stop
    for t in threads:
        t.join(timeout=30)
    outcomes = [r[0] if r else "no answer" for r in results]
    after = sum(1 for r in results if r and r[1] > t_stop)
    print(f"docker stop with {n} requests in flight (4000x3000 JPEG, effort={effort}): "
          f"stop took {stop_s:.2f} s (exit {stop.returncode}); answers: "
          + ", ".join(f"{o}: {outcomes.count(o)}" for o in sorted(set(outcomes)))
          + f"; {after} of them answered after the stop began")
    checks = [
        (all(o == "200" for o in outcomes), f"every request in flight answered 200 ({n})"),
        (after >= 1, f"requests were in flight when SIGTERM came ({after} answered after it)"),
        (stop.returncode == 0 and stop_s < 10, f"docker stop returned in {stop_s:.2f} s < 10 s (no SIGKILL)"),
    ]
    return report(checks)


def report(checks):
    status = 0
    for ok, text in checks:
        print(("PASS: " if ok else "FAIL: ") + text)
        status |= not ok
    return status


def cmd_failover(base_url, image_dir, seconds, clients, kill_pid, kill_after, out_json):
    seconds, clients, kill_after = float(seconds), int(clients), float(kill_after)
    small = read(os.path.join(image_dir, "frame-1280x720.jpg"))
    large = read(os.path.join(image_dir, "frame-4000x3000.jpg"))
    kinds = [("1280x720", f"/v1/pose/image?{CAM1}", small),
             ("4000x3000", f"/v1/pose/image?{CAM12}", large)]
    records = []
    lock = threading.Lock()
    stop = threading.Event()
    counter = [0]

    def client(k):
        name, path, body = kinds[k % len(kinds)]
        while not stop.is_set():
            with lock:
                counter[0] += 1
                rid = f"smoke-failover-{counter[0]}"
            t0 = time.time()
            outcome, t1 = post(base_url, path, body, "image/jpeg", request_id=rid, timeout=30)
            with lock:
                records.append({"id": rid, "kind": name, "start": t0, "end": t1, "outcome": outcome})

    threads = [threading.Thread(target=client, args=(k,)) for k in range(clients)]
    t_begin = time.time()
    for t in threads:
        t.start()
    time.sleep(kill_after)
    t_kill = time.time()
    os.kill(int(kill_pid), signal.SIGKILL)
    time.sleep(max(0.0, seconds - (time.time() - t_begin)))
    stop.set()
    for t in threads:
        t.join(timeout=60)
    with open(out_json, "w", encoding="utf-8") as f:
        json.dump({"begin": t_begin, "kill": t_kill, "end": time.time(), "records": records}, f)
    print(f"failover load: {len(records)} requests from {clients} clients in {seconds:.0f} s; "
          f"replica process {kill_pid} killed (SIGKILL) at {t_kill - t_begin:.1f} s")
    return 0


LINE = re.compile(r'rid=(\S+) status=(\d+) end=([\d.]+) rt=([\d.]+) upstream="([^"]*)" '
                  r'upstream_status="([^"]*)"')


def cmd_failover_count(out_json, lb_log, killed_addr):
    with open(out_json, encoding="utf-8") as f:
        run = json.load(f)
    lb = {}
    with open(lb_log, encoding="utf-8", errors="replace") as f:
        for line in f:
            m = LINE.search(line)
            if m:
                rid, status, end, rt, ups, ups_status = m.groups()
                lb[rid] = {"status": int(status), "start": float(end) - float(rt),
                           "upstreams": [u.strip() for u in re.split(r"[,:]\s", ups) if u.strip()],
                           "statuses": [s.strip() for s in re.split(r"[,:]\s", ups_status)]}
    t_kill = run["kill"]
    records = run["records"]
    outcomes = {}
    for r in records:
        outcomes[r["outcome"]] = outcomes.get(r["outcome"], 0) + 1
    lost = [r for r in records if r["outcome"] not in ("200", "503 overloaded")]
    # In flight on the killed replica when it died: the balancer had sent the request there
    # (first attempt) before the kill and had no answer from it by then.
    in_flight = [r for r in records if r["id"] in lb and lb[r["id"]]["upstreams"][:1] == [killed_addr]
                 and lb[r["id"]]["start"] < t_kill < r["end"]
                 and lb[r["id"]]["statuses"][:1] != ["200"]]
    in_flight_ids = {r["id"] for r in in_flight}
    rerouted = [r for r in in_flight if r["outcome"] == "200"]
    after = [rid for rid, e in lb.items() if e["start"] >= t_kill and killed_addr in e["upstreams"]]
    after_failed = [rid for rid in after
                    if lb[rid]["statuses"][lb[rid]["upstreams"].index(killed_addr)] != "200"]
    after_served = [rid for rid in after if rid not in after_failed]
    before = [rid for rid, e in lb.items() if e["start"] < t_kill and killed_addr in e["upstreams"]]
    unlogged = [r for r in records if r["id"] not in lb]
    print(f"sent {len(records)} requests through the balancer: "
          + ", ".join(f"{o}: {n}" for o, n in sorted(outcomes.items())))
    print(f"killed replica {killed_addr}: {len(before)} requests sent to it before the kill; "
          f"{len(in_flight)} in flight on it when it died ({len(rerouted)} answered 200 by the "
          f"other replica after nginx retried them, {len(in_flight) - len(rerouted)} not)")
    print(f"after the kill: {len(after_failed)} attempts on the dead replica failed and went to "
          f"the other one; {len(after_served)} requests served by it again after Docker restarted it")
    print(f"lost (no 200 and no 503 overloaded): {len(lost)}, of them in flight on the killed "
          f"replica: {sum(1 for r in lost if r['id'] in in_flight_ids)}; not in the balancer's "
          f"log: {len(unlogged)}")
    for r in lost[:5]:
        print(f"  lost {r['id']} ({r['kind']}): {r['outcome']}")
    checks = [
        (len(before) > 0, f"the killed replica was serving before the kill ({len(before)} requests)"),
        (all(r["id"] in in_flight_ids for r in lost),
         f"no request lost beyond those in flight on the killed replica "
         f"(lost {len(lost)}, in flight on it {len(in_flight)})"),
        (outcomes.get("200", 0) > 0 and not unlogged,
         f"every request went through the balancer ({len(records) - len(unlogged)} of {len(records)} logged)"),
    ]
    return report(checks)


def main():
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    cmd, args = sys.argv[1], sys.argv[2:]
    commands = {"stop": cmd_stop, "failover": cmd_failover, "failover-count": cmd_failover_count}
    if cmd not in commands:
        raise SystemExit(__doc__)
    sys.exit(commands[cmd](*args))


if __name__ == "__main__":
    main()
