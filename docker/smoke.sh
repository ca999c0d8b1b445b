#!/usr/bin/env bash
# The Docker image built and run for real: docker/Dockerfile built on this
# machine, the container checked as it will run, and docker/compose.yaml's balancer with two
# replicas, one killed under load. Run by .ci/run; run it by hand the same way (as root):
#
#   docker/smoke.sh [--src DIR]     DIR: the workspace to build and its tests/curl and
#                                   scripts/ (default: this checkout; docker/ is always
#                                   this checkout's)
#
# On a machine with no container registry, whose containers reach no package registry:
#
# 1. Installs what is missing from Debian (docker.io, debootstrap, docker-compose, curl)
#    and starts dockerd when none answers (stopped again at the end).
# 2. Makes the base images the Dockerfile would pull, from Debian's packages
#    (docker/smoke/bases.sh): a bookworm builder with cmake and g++, this machine's Rust
#    toolchain and cargo-chef, the crates vendored on the host (`cargo vendor`) and a cargo
#    configuration that reads them; a distroless-like runtime; nginx for the balancer. Each
#    is reused while what makes it is unchanged.
# 3. Builds docker/Dockerfile with BuildKit, unchanged: build arguments point its base
#    images (RUST_IMAGE, CHEF_IMAGE, RUNTIME_IMAGE) at the local ones.
# 4. Runs the image read-only, as its own non-root user, with every capability dropped and
#    the Compose service `qrpose`'s memory and CPU limits and environment, published on
#    127.0.0.1 only; waits for Docker's HEALTHCHECK to say `healthy`; runs the curl suite
#    (tests/curl) against it; loads it at its memory limit as scripts/limits_load.py does
#    (no OOM kill: the cgroup's counters and `docker inspect`); then `docker stop` with
#    image requests in flight: all answered, exit code 0.
# 5. Brings up docker/compose.yaml's scale-out profile with Debian's docker-compose: the
#    balancer and two replicas; kills one replica's process (SIGKILL) under load and counts
#    what the balancer did with the requests (docker/smoke/traffic.py); then a WebSocket
#    session on GET /v1/stream through the balancer, kept on one replica.
#
# Prints the image size, the start-up time to healthy and each step's duration; ends with
# "N passed, N failed" and exits 1 when a check failed. Scratch files (vendored crates, root
# file systems while they are made, logs, test images) go to target/docker-smoke/.
# Knobs: LOAD_S=40 (memory-limit load), CLIENTS=32, FAILOVER_S=30, STOP_REQUESTS=4,
# STOP_EFFORT=thorough, IMAGE=qrpose:smoke, DOCKER=/usr/bin/docker.
set -euo pipefail

REPO="$(cd "$(dirname "$0")/.." && pwd)"
SRC="$REPO"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --src) SRC="$(cd "$2" && pwd)"; shift 2 ;;
    *) echo "usage: $0 [--src DIR]" >&2; exit 2 ;;
  esac
done
WORK="$REPO/target/docker-smoke"
IMAGE="${IMAGE:-qrpose:smoke}"
LOAD_S="${LOAD_S:-40}"
CLIENTS="${CLIENTS:-32}"
FAILOVER_S="${FAILOVER_S:-30}"
STOP_REQUESTS="${STOP_REQUESTS:-4}"
STOP_EFFORT="${STOP_EFFORT:-thorough}"
CONTAINER=qrpose-smoke
PROJECT=qrpose-smoke
COMPOSE_FILE="$REPO/docker/compose.yaml"
mkdir -p "$WORK"

PASSED=0 FAILED=0 SKIPPED=0
pass() { echo "PASS: $*"; PASSED=$((PASSED + 1)); }
fail() { echo "FAIL: $*"; FAILED=$((FAILED + 1)); }
skip() { echo "SKIP: $*"; SKIPPED=$((SKIPPED + 1)); }
check() { local what="$1"; shift; if "$@"; then pass "$what"; else fail "$what"; fi; }
die() { echo "FAIL: $*"; FAILED=$((FAILED + 1)); exit 1; }
TIMES=()
STEP_NAME="" STEP_T0=0
step() {
  [[ -n "$STEP_NAME" ]] && TIMES+=("$STEP_NAME: $((SECONDS - STEP_T0)) s")
  STEP_NAME="$1" STEP_T0=$SECONDS
  echo
  echo "== $1"
}

[[ "$(id -u)" == 0 ]] || { echo "run as root (apt-get, dockerd, the containers' cgroups)" >&2; exit 2; }

# ---- 1. tools and the daemon
step "tools and the Docker daemon"
# Debian's client (20.10) drives the daemon's own BuildKit; a newer client elsewhere on the
# PATH would want a buildx plugin.
DOCKER="${DOCKER:-/usr/bin/docker}"
export DOCKER_BUILDKIT=1
COMPOSE=(docker-compose -p "$PROJECT" -f "$COMPOSE_FILE" --profile scale-out)
DOCKERD_PID=""

cleanup() {
  local status=$?
  set +e
  if ((status != 0)) && [[ -z "${FINISHED:-}" ]]; then
    ((FAILED > 0)) || { echo "FAIL: a command failed (exit $status)"; FAILED=1; }
    echo "smoke: $PASSED passed, $FAILED failed, $SKIPPED skipped (stopped in: $STEP_NAME)"
  fi
  "$DOCKER" rm -f "$CONTAINER" >/dev/null 2>&1
  [[ -n "${COMPOSE_UP:-}" ]] && "${COMPOSE[@]}" down --remove-orphans -t 10 >/dev/null 2>&1
  if [[ -n "$DOCKERD_PID" ]]; then
    kill -TERM "$DOCKERD_PID" 2>/dev/null
    for _ in $(seq 100); do kill -0 "$DOCKERD_PID" 2>/dev/null || break; sleep 0.2; done
  fi
  return "$status"
}
trap cleanup EXIT

missing=()
[[ -x /usr/sbin/dockerd && -x /usr/bin/docker ]] || missing+=(docker.io)
command -v debootstrap >/dev/null || missing+=(debootstrap)
command -v docker-compose >/dev/null || missing+=(docker-compose)
command -v curl >/dev/null || missing+=(curl)
if ((${#missing[@]})); then
  echo "installing ${missing[*]} from Debian"
  export DEBIAN_FRONTEND=noninteractive
  if ! { apt-get update -qq && apt-get install -y -qq "${missing[@]}"; } >"$WORK/apt.log" 2>&1; then
    tail -20 "$WORK/apt.log"
    die "apt-get install ${missing[*]} failed"
  fi
fi
if ! "$DOCKER" info >/dev/null 2>&1; then
  echo "starting dockerd (log: $WORK/dockerd.log)"
  /usr/sbin/dockerd >"$WORK/dockerd.log" 2>&1 &
  DOCKERD_PID=$!
  for _ in $(seq 120); do "$DOCKER" info >/dev/null 2>&1 && break; sleep 0.5; done
  "$DOCKER" info >/dev/null 2>&1 || { tail -20 "$WORK/dockerd.log"; die "dockerd did not start"; }
fi
echo "$("$DOCKER" version -f 'client {{.Client.Version}}, daemon {{.Server.Version}}'), $(docker-compose version --short 2>/dev/null | sed 's/^/docker-compose /'),"\
  "storage $("$DOCKER" info -f '{{.Driver}}'), cgroup v$("$DOCKER" info -f '{{.CgroupVersion}}'); $(nproc) CPUs, load $(cut -d' ' -f1-3 /proc/loadavg)"

PY=python3
if ! python3 -c 'import yaml' 2>/dev/null; then
  if ! "$WORK/venv/bin/python" -c 'import yaml' 2>/dev/null; then
    python3 -m venv "$WORK/venv"
    "$WORK/venv/bin/pip" install --quiet --disable-pip-version-check 'PyYAML==6.0.3'
  fi
  PY="$WORK/venv/bin/python"
fi

# ---- 2. local base images
step "local base images"
# shellcheck source=docker/smoke/bases.sh
source "$REPO/docker/smoke/bases.sh"
make_build_base
make_runtime_base
make_chef_base
rm -rf "$WORK/tools-target"  # cargo-chef's build directory, when make_chef_base built it
make_crates_image
make_lb_image

# ---- 3. the image
step "docker build -f docker/Dockerfile"
build_t0=$SECONDS
if ! "$DOCKER" build --progress=plain -f "$REPO/docker/Dockerfile" \
  --build-arg RUST_IMAGE="$CHEF_BASE" --build-arg CHEF_IMAGE="$CRATES_IMAGE" \
  --build-arg RUNTIME_IMAGE="$RUNTIME_BASE" -t "$IMAGE" "$SRC" >"$WORK/build.log" 2>&1; then
  tail -40 "$WORK/build.log"
  die "docker build failed (log: $WORK/build.log)"
fi
BUILD_S=$((SECONDS - build_t0))
# Each RUN step with its time, or CACHED.
awk '/^#[0-9]+ \[[^]]*\] RUN / { id = $1; sub(/^#[0-9]+ /, ""); name[id] = substr($0, 1, 90) }
     /^#[0-9]+ (DONE|CACHED)/ && ($1 in name) { printf "  %-90s %s %s\n", name[$1], $2, $3 }' "$WORK/build.log"
IMAGE_BYTES="$("$DOCKER" image inspect -f '{{.Size}}' "$IMAGE")"
IMAGE_MB="$(awk -v b="$IMAGE_BYTES" 'BEGIN { printf "%.1f", b / 1e6 }')"
GZIP_MB="$("$DOCKER" save "$IMAGE" | gzip -c | wc -c | awk '{ printf "%.1f", $1 / 1e6 }')"
echo "built $IMAGE in $BUILD_S s: $IMAGE_MB MB uncompressed ($IMAGE_BYTES bytes), $GZIP_MB MB gzipped; its layers:"
"$DOCKER" history --format '  {{.Size}}\t{{.CreatedBy}}' "$IMAGE" | grep -v '^  0B' | cut -c1-100

# ---- 4. one container, as the Compose service `qrpose` runs it
step "one container: read-only, non-root, the Compose limits"
"$DOCKER" rm -f "$CONTAINER" >/dev/null 2>&1 || true
eval "$("$PY" "$SRC/scripts/limits_load.py" compose qrpose "$COMPOSE_FILE" "$WORK/qrpose.env")"
t_run="$(date +%s.%N)"
"$DOCKER" run -d --name "$CONTAINER" --read-only --cap-drop ALL \
  --security-opt no-new-privileges:true --memory "$LIMIT_MEMORY_BYTES" \
  --memory-swap "$LIMIT_MEMORY_BYTES" --cpus "$LIMIT_CPUS" --env-file "$WORK/qrpose.env" \
  -p 127.0.0.1::8080 "$IMAGE" >/dev/null
PORT="$("$DOCKER" port "$CONTAINER" 8080/tcp | head -1 | sed 's/.*://')"
BASE_URL="http://127.0.0.1:$PORT"
t_answer="" t_healthy="" health=""
for _ in $(seq 600); do
  if [[ -z "$t_answer" ]] && curl -sf -o /dev/null "$BASE_URL/healthz"; then t_answer="$(date +%s.%N)"; fi
  health="$("$DOCKER" inspect -f '{{.State.Health.Status}}' "$CONTAINER")"
  [[ "$health" == healthy ]] && { t_healthy="$(date +%s.%N)"; break; }
  [[ "$("$DOCKER" inspect -f '{{.State.Running}}' "$CONTAINER")" == true ]] || break
  sleep 0.1
done
if [[ -n "$t_healthy" ]]; then
  HEALTHY_S="$(awk -v a="$t_run" -v b="$t_healthy" 'BEGIN { printf "%.1f", b - a }')"
  ANSWER_S="$(awk -v a="$t_run" -v b="${t_answer:-$t_healthy}" 'BEGIN { printf "%.2f", b - a }')"
  pass "Docker's HEALTHCHECK says healthy $HEALTHY_S s after docker run (the first check runs at its 10 s interval; /healthz answered after $ANSWER_S s)"
else
  "$DOCKER" logs "$CONTAINER" 2>&1 | tail -20
  die "the container is not healthy after 60 s (health: $health)"
fi
PID="$("$DOCKER" inspect -f '{{.State.Pid}}' "$CONTAINER")"
check "runs as the image's non-root user ($("$DOCKER" inspect -f '{{.Config.User}}' "$CONTAINER"); process uid $(awk '/^Uid:/ {print $2}' "/proc/$PID/status"))" \
  test "$(awk '/^Uid:/ {print $2 $3 $4 $5}' "/proc/$PID/status")" = 65532655326553265532
check "read-only root, capabilities dropped, no-new-privileges" \
  test "$("$DOCKER" inspect -f '{{.HostConfig.ReadonlyRootfs}} {{.HostConfig.CapDrop}} {{.HostConfig.SecurityOpt}}' "$CONTAINER")" = "true [ALL] [no-new-privileges:true]"
check "the Compose limits: $LIMIT_MEMORY_TEXT, $LIMIT_CPUS CPUs" \
  test "$("$DOCKER" inspect -f '{{.HostConfig.Memory}} {{.HostConfig.NanoCpus}}' "$CONTAINER")" = "$LIMIT_MEMORY_BYTES $(awk -v c="$LIMIT_CPUS" 'BEGIN { printf "%d", c * 1e9 }')"

step "the curl suite against the container"
IMAGES="$WORK/images"
mkdir -p "$IMAGES"
# The test photos come from the renderer built on the host (`qrpose-sim render`): the image
# holds the service alone.
(cd "$SRC" && cargo build --release --quiet -p qrpose-sim --bin qrpose-sim)
cat >"$WORK/render.sh" <<EOF
#!/bin/sh
exec "$SRC/target/release/qrpose-sim" "\$@"
EOF
chmod +x "$WORK/render.sh"
"$WORK/render.sh" render --out "$IMAGES/curl-photo.jpg" --payload SKU-1 --marker-size-mm 50 \
  --x-mm 20 --z-mm 400 --alpha-deg 20 --beta-deg -10 --blur-px 0.8 --noise 2 --seed 3 >/dev/null
for script in "$SRC"/tests/curl/*.sh; do
  if BASE_URL="$BASE_URL" IMAGE_PATH="$IMAGES/curl-photo.jpg" bash "$script" >"$WORK/curl-$(basename "$script").log" 2>&1; then
    pass "tests/curl/$(basename "$script") ($(grep -c '^ok' "$WORK/curl-$(basename "$script").log") answers)"
  else
    tail -5 "$WORK/curl-$(basename "$script").log"
    fail "tests/curl/$(basename "$script")"
  fi
done

step "photo load at the memory limit ($LOAD_S s, $CLIENTS clients)"
echo "test images:"
"$PY" "$SRC/scripts/limits_load.py" images "$IMAGES" "$WORK/render.sh"
MEMCG="/sys/fs/cgroup/memory$(awk -F: '$2 ~ /(^|,)memory(,|$)/ {print $3}' "/proc/$PID/cgroup")"
CGV=1
if [[ -f /sys/fs/cgroup/cgroup.controllers ]]; then
  CGV=2 MEMCG="/sys/fs/cgroup$(awk -F: '$1 == "0" {print $3}' "/proc/$PID/cgroup")"
fi
echo "container cgroup: $MEMCG (v$CGV)"
if "$PY" "$SRC/scripts/limits_load.py" load "$WORK" "$IMAGES" "$BASE_URL" "$PID" "$MEMCG" "$CGV" \
  "$LOAD_S" "$CLIENTS" "$BOUND_MIB" "$LIMIT_MEMORY_BYTES" >"$WORK/load.txt" 2>&1; then
  pass "photo load at the memory limit: every check of scripts/limits_load.py"
else
  fail "photo load at the memory limit (report: $WORK/load.txt)"
fi
grep -E '^(ran|all outcomes|/healthz|cgroup peak|memory.failcnt|PASS|FAIL|within|ABOVE)' "$WORK/load.txt" | sed 's/^/  /'
check "after the load: not OOM-killed, running, not restarted ($("$DOCKER" inspect -f 'OOMKilled={{.State.OOMKilled}} Running={{.State.Running}} RestartCount={{.RestartCount}}' "$CONTAINER"))" \
  test "$("$DOCKER" inspect -f '{{.State.OOMKilled}} {{.State.Running}} {{.RestartCount}}' "$CONTAINER")" = "false true 0"

step "docker stop with requests in flight"
if "$PY" "$REPO/docker/smoke/traffic.py" stop "$BASE_URL" "$IMAGES" "$STOP_REQUESTS" \
  "$STOP_EFFORT" "$CONTAINER" "$DOCKER" >"$WORK/stop.txt" 2>&1; then
  pass "docker stop with requests in flight"
else
  fail "docker stop with requests in flight"
fi
sed 's/^/  /' "$WORK/stop.txt"
check "exit code 0 after SIGTERM ($("$DOCKER" inspect -f 'ExitCode={{.State.ExitCode}} OOMKilled={{.State.OOMKilled}}' "$CONTAINER"))" \
  test "$("$DOCKER" inspect -f '{{.State.ExitCode}} {{.State.OOMKilled}}' "$CONTAINER")" = "0 false"
"$DOCKER" logs "$CONTAINER" >"$WORK/container.log" 2>&1
"$DOCKER" rm -f "$CONTAINER" >/dev/null

# ---- 5. Compose: the balancer and two replicas
step "docker-compose: the balancer and two replicas"
LB_PORT="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
export QRPOSE_IMAGE="$IMAGE" QRPOSE_LB_IMAGE="$LB_IMAGE" QRPOSE_LB_PUBLISH="127.0.0.1:$LB_PORT"
"${COMPOSE[@]}" down --remove-orphans -t 10 >/dev/null 2>&1 || true
COMPOSE_UP=1
compose_t0=$SECONDS
if ! "${COMPOSE[@]}" up -d --no-build --scale replica=2 lb >"$WORK/compose-up.log" 2>&1; then
  cat "$WORK/compose-up.log"
  die "docker-compose up failed"
fi
LB_URL="http://127.0.0.1:$LB_PORT"
mapfile -t REPLICAS < <("${COMPOSE[@]}" ps -q replica 2>/dev/null)
LB="$("${COMPOSE[@]}" ps -q lb 2>/dev/null)"
for _ in $(seq 300); do
  states="$("$DOCKER" inspect -f '{{.State.Health.Status}}' "${REPLICAS[@]}" "$LB" | sort -u | xargs)"
  [[ "$states" == healthy ]] && break
  sleep 0.2
done
check "${#REPLICAS[@]} replicas and the balancer healthy after $((SECONDS - compose_t0)) s ($states)" \
  test "$states" = healthy -a "${#REPLICAS[@]}" = 2
# What compose.yaml asks of a replica, read as scripts/limits_load.py reads it.
want="$(eval "$("$PY" "$SRC/scripts/limits_load.py" compose replica "$COMPOSE_FILE" "$WORK/replica.env")"
  echo "$LIMIT_MEMORY_BYTES $(awk -v c="$LIMIT_CPUS" 'BEGIN { printf "%d", c * 1e9 }') true")"
check "replicas get compose.yaml's limits and a read-only root ($("$DOCKER" inspect -f '{{.HostConfig.Memory}} B, {{.HostConfig.NanoCpus}} nano-CPUs, read-only {{.HostConfig.ReadonlyRootfs}}' "${REPLICAS[0]}"))" \
  test "$("$DOCKER" inspect -f '{{.HostConfig.Memory}} {{.HostConfig.NanoCpus}} {{.HostConfig.ReadonlyRootfs}}' "${REPLICAS[@]}" | sort -u)" = "$want"
check "the balancer answers /healthz from a replica" curl -sf -o /dev/null "$LB_URL/healthz"

# websocket_session_through_lb URL: a WebSocket session on GET /v1/stream (docs/stream.md) through
# the balancer: frames of the rendered `still` video (rendered by the image), each answered in
# order with `tracks`, a code `tracking` by the end, closed with 1000
# (scripts/stream_load.py session, websockets from PyPI in target/stream-load-venv). nginx's
# access log line of the session (found by its X-Request-Id) must say 101 and name one
# replica; that replica's qrpose_stream_frames_answered_total must have grown by the frames
# sent and the other's not at all.
stream_answered() {
  curl -sf --max-time 5 "http://$1/metrics" \
    | awk '$1 == "qrpose_stream_frames_answered_total" { print $2 + 0; found = 1 } END { if (!found) print "?" }'
}
websocket_session_through_lb() {
  local url="$1" frames=6 dir="$IMAGES/stream-still" out rid line upstream status b after
  local -A addr_of=() before_of=()
  "$WORK/render.sh" render --sequence still --frames "$frames" --out "$dir" >/dev/null
  for r in "${REPLICAS[@]}"; do
    addr_of[$r]="$("$DOCKER" inspect -f '{{range .NetworkSettings.Networks}}{{.IPAddress}}{{end}}' "$r"):8080"
    before_of[$r]="$(stream_answered "${addr_of[$r]}")"
  done
  local t0; t0="$(date +%s)"
  if ! out="$("$PY" "$SRC/scripts/stream_load.py" session --url "$url" --frames-dir "$dir" 2>"$WORK/stream-session.log")"; then
    tail -5 "$WORK/stream-session.log"
    fail "WebSocket session through the balancer: $out"
    return
  fi
  echo "  session: $out"
  rid="$("$PY" -c 'import json, sys; print(json.load(sys.stdin)["request_id"])' <<<"$out")"
  for _ in $(seq 50); do
    line="$("$DOCKER" logs --since "$t0" "$LB" 2>/dev/null | grep -F "rid=$rid " || true)"
    [[ -n "$line" ]] && break
    sleep 0.2
  done
  echo "  nginx: ${line:-no access log line for rid=$rid}"
  status="$(sed -n 's/.* status=\([0-9]*\) .*/\1/p' <<<"$line")"
  upstream="$(sed -n 's/.* upstream="\([^"]*\)".*/\1/p' <<<"$line")"
  local named="" answered=()
  for r in "${REPLICAS[@]}"; do
    after="$(stream_answered "${addr_of[$r]}")"
    answered+=("${addr_of[$r]} ${before_of[$r]} -> $after")
    if [[ "${addr_of[$r]}" == "$upstream" ]]; then
      named="$r" b="${before_of[$r]}"
      if [[ "$after" == "?" || "$b" == "?" ]] || ((after - b != frames)); then
        named="bad:$r"
      fi
    elif [[ "$after" != "${before_of[$r]}" ]]; then
      named="bad:other"
    fi
  done
  echo "  stream frames answered by replica: ${answered[*]}"
  check "WebSocket session through the balancer: $frames frames answered in order with tracks, closed 1000; nginx passed the upgrade (status $status) to one replica ($upstream), which answered every frame" \
    test "$status" = 101 -a -n "$named" -a "${named#bad:}" = "$named"
}
websocket_session_through_lb "$LB_URL"

step "one replica killed under load ($FAILOVER_S s)"
VICTIM="${REPLICAS[0]}"
VICTIM_PID="$("$DOCKER" inspect -f '{{.State.Pid}}' "$VICTIM")"
VICTIM_ADDR="$("$DOCKER" inspect -f '{{range .NetworkSettings.Networks}}{{.IPAddress}}{{end}}' "$VICTIM"):8080"
echo "replicas: $("$DOCKER" inspect -f '{{.Name}} {{range .NetworkSettings.Networks}}{{.IPAddress}}{{end}}' "${REPLICAS[@]}" | tr '\n' ';') victim $VICTIM_ADDR"
t_failover="$(date +%s)"
"$PY" "$REPO/docker/smoke/traffic.py" failover "$LB_URL" "$IMAGES" "$FAILOVER_S" 6 "$VICTIM_PID" \
  "$(awk -v s="$FAILOVER_S" 'BEGIN { print s / 3 }')" "$WORK/failover.json"
"$DOCKER" logs --since "$t_failover" "$LB" >"$WORK/lb.log" 2>/dev/null
if "$PY" "$REPO/docker/smoke/traffic.py" failover-count "$WORK/failover.json" "$WORK/lb.log" \
  "$VICTIM_ADDR" >"$WORK/failover.txt"; then
  pass "the balancer routed around the killed replica"
else
  fail "the balancer routed around the killed replica"
fi
sed 's/^/  /' "$WORK/failover.txt"
for _ in $(seq 150); do
  [[ "$("$DOCKER" inspect -f '{{.State.Health.Status}}' "$VICTIM")" == healthy ]] && break
  sleep 0.2
done
check "Docker restarted the killed replica and it is healthy again ($("$DOCKER" inspect -f 'RestartCount={{.RestartCount}} {{.State.Health.Status}}' "$VICTIM"))" \
  test "$("$DOCKER" inspect -f '{{.RestartCount}} {{.State.Health.Status}}' "$VICTIM")" = "1 healthy"
"${COMPOSE[@]}" logs --no-color >"$WORK/compose.log" 2>&1 || true
"${COMPOSE[@]}" down --remove-orphans -t 10 >/dev/null 2>&1
COMPOSE_UP=""
step "summary"

echo "image $IMAGE: $IMAGE_MB MB uncompressed, $GZIP_MB MB gzipped; built in $BUILD_S s; healthy $HEALTHY_S s after docker run"
printf '  %s\n' "${TIMES[@]}"
# Builds on this machine add layers; keep the daemon's build cache and dangling images
# bounded (the newest layers, the cached dependency build among them, stay).
"$DOCKER" image prune -f >/dev/null
"$DOCKER" builder prune -f --keep-storage 12GB >/dev/null
echo "Docker's disk use: $("$DOCKER" system df --format '{{.Type}} {{.Size}}' | tr '\n' ' ')"
FINISHED=1
echo "smoke: $PASSED passed, $FAILED failed, $SKIPPED skipped"
((FAILED == 0))
