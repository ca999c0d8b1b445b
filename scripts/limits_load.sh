#!/usr/bin/env bash
# Load run of `qrpose serve` at a Docker Compose service's limits (docs/deploy.md): the CPU and
# memory limits of the service in docker/compose.yaml, emulated with a fresh cgroup (no
# Docker engine needed), and the service's environment (QRPOSE_* and RUST_LOG) exactly.
#
# The load is hostile but valid, for LOAD_S seconds: CLIENTS concurrent image clients
# (more than workers + queue) sending the largest accepted images over and over, retrying
# at once when refused: 50 MP PNGs of zero pixels (grey at effort=thorough, RGB), 24 MB
# noise PNGs just under the body limit (some at full speed, some trickled at about 3.5 MB/s,
# half of those chunked, with no Content-Length), 4000x3000 JPEG frames from `qrpose render`
# (thorough and balanced) and 1280x720 frames; two clients of POST /v1/pose/corners; and
# GET /healthz every 100 ms throughout. The pixel and body budgets and the queue must refuse
# the excess with 503 `overloaded` before the kernel's OOM killer has to act.
#
# Reported: the cgroup's peak memory (memory.max_usage_in_bytes, or memory.peak on cgroup
# v2) against the limit and against docs/deploy.md's bound, memory.failcnt, OOM kills, the
# idle and peak RSS, the answers by client (200 / 503 overloaded / ...) and /healthz's
# latency. Exit 0 when: no OOM kill, the server alive at the end, peak < limit, no 5xx but
# 503 overloaded and 503 timeout, no connection errors, /healthz always answered; 1
# otherwise; 2 when the limits cannot be emulated (no writable cgroup, or not root).
#
# Usage: scripts/limits_load.sh [SERVICE]   (as root)   SERVICE: qrpose (default) or replica
# Knobs: LOAD_S=75 CLIENTS=32 COMPOSE_FILE=docker/compose.yaml
#        CARGO_FEATURES=zxing-cpp (the image's build; built in target/limits-load/build)
#
# The cgroup is made under the caller's own (cgroup v1: memory and cpu controllers; v2:
# memory.max, memory.swap.max = 0, cpu.max) and removed at exit. On v1 the swap limit
# (memory.memsw.limit_in_bytes) is set to the memory limit, so swap cannot hide usage. The
# server's logs go through a pipe to a process outside the cgroup (as Docker's log driver),
# so log files' page cache is not charged to it. The load generator runs outside the cgroup
# but on the same machine: on a machine with few CPUs it competes with the server for them.
# Needs python3 (PyYAML to read the Compose file: the system's, or one installed from PyPI
# into a venv under target/limits-load/). Only loopback traffic.
set -euo pipefail
cd "$(dirname "$0")/.."

SERVICE="${1:-qrpose}"
LOAD_S="${LOAD_S:-75}"
CLIENTS="${CLIENTS:-32}"
COMPOSE_FILE="${COMPOSE_FILE:-docker/compose.yaml}"
CARGO_FEATURES="${CARGO_FEATURES:-}"
OUT="target/limits-load"
RUN="$OUT/$SERVICE"
mkdir -p "$RUN"

cannot() { echo "cannot emulate limits: $*" >&2; exit 2; }
[[ "$(id -u)" == 0 ]] || cannot "run as root (cgroups are written directly)"

# ---- build
if [[ -n "$CARGO_FEATURES" ]]; then
  cargo build --release --quiet --features "$CARGO_FEATURES" --bin qrpose --target-dir "$OUT/build"
  BIN="$OUT/build/release/qrpose"
else
  cargo build --release --quiet
  BIN=target/release/qrpose
fi
# The test photos' renderer (`qrpose-sim render`).
cargo build --release --quiet -p qrpose-sim --bin qrpose-sim
SIM=target/release/qrpose-sim

# ---- the service's limits and environment
PY=python3
if ! python3 -c 'import yaml' 2>/dev/null; then
  if [[ ! -x "$OUT/venv/bin/python" ]]; then
    python3 -m venv "$OUT/venv"
    "$OUT/venv/bin/pip" install --quiet pyyaml
  fi
  PY="$OUT/venv/bin/python"
fi
eval "$("$PY" scripts/limits_load.py compose "$SERVICE" "$COMPOSE_FILE" "$RUN/env")"
mapfile -t SERVICE_ENV <"$RUN/env"

# ---- the cgroup
NAME="qrpose-limits-$$"
MEMCG="" CPUCG="" CGV=""
# shellcheck disable=SC2329  # run by the EXIT trap
cleanup() {
  local cg
  [[ -n "${LOAD_PID:-}" ]] && kill -TERM "$LOAD_PID" 2>/dev/null
  if [[ -n "${SERVER_PID:-}" ]] && kill -0 "$SERVER_PID" 2>/dev/null; then
    kill -TERM "$SERVER_PID" 2>/dev/null || true
    for _ in $(seq 100); do kill -0 "$SERVER_PID" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$SERVER_PID" 2>/dev/null || true
  fi
  for cg in "$MEMCG" "$CPUCG"; do
    [[ -n "$cg" && -d "$cg" ]] || continue
    # Anything still inside goes back to the parent, then the group is removed.
    while read -r p; do echo "$p" >"$(dirname "$cg")/cgroup.procs" 2>/dev/null || true; done <"$cg/cgroup.procs"
    for _ in $(seq 50); do rmdir "$cg" 2>/dev/null && break; sleep 0.1; done
    [[ -d "$cg" ]] && echo "warning: could not remove $cg" >&2
  done
  return 0
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# own_cgroup CONTROLLER: this process's cgroup path for a v1 controller.
own_cgroup() {
  awk -F: -v c="$1" '{ n = split($2, a, ","); for (i = 1; i <= n; i++) if (a[i] == c) print $3 }' /proc/self/cgroup
}
if [[ -f /sys/fs/cgroup/cgroup.controllers ]]; then
  CGV=2
  own="/sys/fs/cgroup$(awk -F: '$1 == "0" {print $3}' /proc/self/cgroup)"
  # The new group's controllers must be enabled in its parent; a parent holding processes
  # cannot delegate them (cgroup v2's no-internal-process rule) unless it is the root.
  made=""
  for parent in "$own" /sys/fs/cgroup; do
    grep -qw memory "$parent/cgroup.controllers" 2>/dev/null || continue
    echo "+memory +cpu" >"$parent/cgroup.subtree_control" 2>/dev/null || continue
    mkdir "$parent/$NAME" 2>/dev/null || continue
    made="$parent/$NAME"; break
  done
  [[ -n "$made" ]] || cannot "cgroup v2 without a writable group that delegates memory and cpu"
  MEMCG="$made" CPUCG=""
  echo "$LIMIT_MEMORY_BYTES" >"$MEMCG/memory.max"
  [[ -f "$MEMCG/memory.swap.max" ]] && echo 0 >"$MEMCG/memory.swap.max"
  echo "$CFS_QUOTA_US 100000" >"$MEMCG/cpu.max"
elif [[ -d /sys/fs/cgroup/memory && -d /sys/fs/cgroup/cpu ]]; then
  CGV=1
  MEMCG="/sys/fs/cgroup/memory$(own_cgroup memory)/$NAME"
  mkdir "$MEMCG" 2>/dev/null || { MEMCG=""; cannot "cannot create a memory cgroup (read-only /sys/fs/cgroup?)"; }
  CPUCG="/sys/fs/cgroup/cpu$(own_cgroup cpu)/$NAME"
  mkdir "$CPUCG" 2>/dev/null || { CPUCG=""; cannot "cannot create a cpu cgroup"; }
  echo "$LIMIT_MEMORY_BYTES" >"$MEMCG/memory.limit_in_bytes"
  [[ -f "$MEMCG/memory.memsw.limit_in_bytes" ]] && echo "$LIMIT_MEMORY_BYTES" >"$MEMCG/memory.memsw.limit_in_bytes"
  echo 100000 >"$CPUCG/cpu.cfs_period_us"
  echo "$CFS_QUOTA_US" >"$CPUCG/cpu.cfs_quota_us"
else
  cannot "neither cgroup v2 (/sys/fs/cgroup/cgroup.controllers) nor v1 memory and cpu hierarchies"
fi
swap_kib="$(awk '/^SwapTotal:/ {print $2}' /proc/meminfo)"
echo "service $SERVICE: ${LIMIT_CPUS} CPUs, ${LIMIT_MEMORY_TEXT} ($LIMIT_MEMORY_BYTES bytes), docs' bound ${BOUND_MIB} MiB;" \
  "cgroup v$CGV $MEMCG; swap ${swap_kib} KiB; $(nproc) CPUs; load average $(cut -d' ' -f1-3 /proc/loadavg)"

# ---- the test images (made once, kept in $OUT)
echo "images:"
python3 scripts/limits_load.py images "$OUT/images" "$SIM"

# ---- the server, inside the cgroup, with the service's environment alone (as in the
# container) but listening on a free loopback port.
: >"$RUN/server.out"
(
  echo "$BASHPID" >"$MEMCG/cgroup.procs"
  [[ -n "$CPUCG" ]] && echo "$BASHPID" >"$CPUCG/cgroup.procs"
  exec env -i PATH=/usr/bin:/bin "${SERVICE_ENV[@]}" QRPOSE_ADDR=127.0.0.1:0 "$BIN" serve
) > >(cat >"$RUN/server.out") 2> >(cat >"$RUN/server.log") &
SERVER_PID=$!
for _ in $(seq 100); do
  grep -q '^listening on ' "$RUN/server.out" 2>/dev/null && break
  sleep 0.1
done
BASE_URL="$(sed -n 's/^listening on //p' "$RUN/server.out" | head -1)"
[[ -n "$BASE_URL" ]] || { echo "the server did not start"; cat "$RUN/server.log"; exit 1; }
grep -qx "$SERVER_PID" "$MEMCG/cgroup.procs" || { echo "the server is not in $MEMCG"; exit 1; }
sleep 1
idle_rss="$(awk '/^VmRSS:/ {print $2}' "/proc/$SERVER_PID/status")"
idle_cg="$(cat "$MEMCG/memory.usage_in_bytes" 2>/dev/null || cat "$MEMCG/memory.current")"
echo "server $SERVER_PID on $BASE_URL; idle: VmRSS $((idle_rss / 1024)) MiB ($idle_rss KiB), cgroup $((idle_cg / 1048576)) MiB"

# ---- the load
# In the background, so that an interrupt runs the EXIT trap at once (it stops the driver).
"$PY" scripts/limits_load.py load "$RUN" "$OUT/images" "$BASE_URL" "$SERVER_PID" "$MEMCG" "$CGV" \
  "$LOAD_S" "$CLIENTS" "$BOUND_MIB" "$LIMIT_MEMORY_BYTES" > >(tee "$RUN/report.txt") &
LOAD_PID=$!
status=0
wait "$LOAD_PID" || status=$?
LOAD_PID=""
echo "idle VmRSS: $((idle_rss / 1024)) MiB; server log: $RUN/server.log; report: $RUN/report.txt; load average now $(cut -d' ' -f1-3 /proc/loadavg)"
exit "$status"
