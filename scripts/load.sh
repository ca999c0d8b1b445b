#!/usr/bin/env bash
# Load test of `qrpose serve` on this machine: requests/s and p50/p99 latency of
# POST /v1/pose/corners, POST /v1/pose/image (a 1280x720 JPEG rendered by `qrpose-sim render`)
# and GET /healthz (the ceiling) on the same server in the same run, then a soak of the
# corners endpoint while resident memory (VmRSS) is sampled.
#
# The endpoints are measured in alternating rounds and each is reported by its median
# round, so that load from other processes on a shared machine hits both alike. The server's
# own CPU time per request (from /proc) is reported too: it does not depend on that load.
#
# Checks: zero errors (non-2xx answers or socket errors), corners rate >= 70 % of the
# /healthz rate, RSS flat over the soak, and the image endpoint reading the photo's code.
# Exit 0 when all hold, 1 otherwise. The image endpoint has no rate target: it is bound by
# decoding and detection (about 6-7 ms of CPU per 1280x720 photo, docs/performance.md).
#
# Usage: scripts/load.sh            (installs wrk from Debian if missing; builds release)
# Knobs: ROUNDS=3 DURATION_S=10 SOAK_S=60 CONNECTIONS=32 WRK_THREADS=2 TARGET_RATIO=0.70
#        RUST_LOG=info (the access log stays on, one line per request, as in production)
# Only loopback traffic; every wrk run is bounded by its duration.
set -euo pipefail
cd "$(dirname "$0")/.."

ROUNDS="${ROUNDS:-3}"
DURATION_S="${DURATION_S:-10}"
SOAK_S="${SOAK_S:-60}"
CONNECTIONS="${CONNECTIONS:-32}"
WRK_THREADS="${WRK_THREADS:-2}"
TARGET_RATIO="${TARGET_RATIO:-0.70}"
SAMPLE_S=5
# RSS may grow by at most this much over the soak (allocator noise), KiB.
RSS_SLACK_KIB=4096
OUT="target/load"
mkdir -p "$OUT"

if ! command -v wrk >/dev/null; then
  echo "installing wrk (Debian package)"
  if [[ "$(id -u)" == 0 ]]; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq wrk
  else
    sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq wrk
  fi
fi

cargo build --release --quiet
BIN=target/release/qrpose
SIM=target/release/qrpose-sim

# The access log stays on (info, one line per request), as in production; it goes to a
# file so that the terminal is not the bottleneck.
RUST_LOG="${RUST_LOG:-info}" "$BIN" serve --addr 127.0.0.1:0 >"$OUT/server.out" 2>"$OUT/server.log" &
SERVER_PID=$!
trap 'kill "$SERVER_PID" 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  grep -q '^listening on ' "$OUT/server.out" 2>/dev/null && break
  sleep 0.1
done
BASE_URL="$(sed -n 's/^listening on //p' "$OUT/server.out")"
[[ -n "$BASE_URL" ]] || { echo "the server did not start"; cat "$OUT/server.log"; exit 1; }
echo "server $SERVER_PID on $BASE_URL ($(nproc) CPUs, load average $(cut -d' ' -f1 /proc/loadavg); wrk -t$WRK_THREADS -c$CONNECTIONS)"

# The image endpoint's photo: a 50 mm code 400 mm in front of a 1280x720 camera (f = 1000 px),
# tilted, blurred, noisy, unevenly lit, with background clutter; JPEG quality 90.
"$SIM" render --out "$OUT/photo.jpg" --payload SKU-1 --marker-size-mm 50 --x-mm 20 --z-mm 400 \
  --alpha-deg 20 --beta-deg -10 --blur-px 0.8 --noise 2 --lighting 0.2 --clutter 10 --seed 3 \
  >"$OUT/photo.json"
IMAGE_QUERY="fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50"
# Measure real work only: the server must read the code in this photo.
if ! curl -sS -X POST "$BASE_URL/v1/pose/image?$IMAGE_QUERY" -H 'Content-Type: image/jpeg' \
  --data-binary "@$OUT/photo.jpg" | grep -q '"payload":"SKU-1"'; then
  echo "FAIL: the image endpoint did not read the photo's code"; exit 1
fi
cat >"$OUT/image.lua" <<LUA
wrk.method = "POST"
wrk.headers["Content-Type"] = "image/jpeg"
local f = assert(io.open("$OUT/photo.jpg", "rb"))
wrk.body = f:read("*a")
f:close()
LUA

cat >"$OUT/corners.lua" <<'LUA'
wrk.method = "POST"
wrk.headers["Content-Type"] = "application/json"
wrk.body = [==[{"corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
  "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5},
  "marker": {"size_mm": 50}}]==]
LUA

# run NAME SECONDS PATH [LUA]: one bounded wrk run, its report in $OUT/NAME.txt and the
# server's CPU time over the run (clock ticks) in $OUT/NAME.cpu.
run() {
  local name="$1" seconds="$2" path="$3" script="${4:-}"
  local args=(-t"$WRK_THREADS" -c"$CONNECTIONS" -d"${seconds}s" --timeout 5s --latency)
  [[ -n "$script" ]] && args+=(-s "$script")
  local before
  before="$(cpu_ticks)"
  wrk "${args[@]}" "$BASE_URL$path" >"$OUT/$name.txt"
  echo $(( $(cpu_ticks) - before )) >"$OUT/$name.cpu"
}

cpu_ticks() { awk '{print $14 + $15}' "/proc/$SERVER_PID/stat"; }
rate() { awk '/^Requests\/sec:/ {print $2}' "$OUT/$1.txt"; }
count() { awk '/ requests in / {print $1}' "$OUT/$1.txt"; }
# Server CPU per request, microseconds.
cpu_us() {
  awk -v t="$(cat "$OUT/$1.cpu")" -v n="$(count "$1")" -v hz="$(getconf CLK_TCK)" \
    'BEGIN {printf "%.0f", t * 1e6 / hz / n}'
}
# Latency percentile in ms from wrk's distribution ("50%    1.23ms").
pct() {
  awk -v p="$2%" '$1 == p {
    v = $2; u = v; gsub(/[0-9.]/, "", u); sub(/[a-z]+$/, "", v);
    if (u == "us") v /= 1000; else if (u == "s") v *= 1000; else if (u == "m") v *= 60000;
    printf "%.2f", v }' "$OUT/$1.txt"
}
errors() {
  local non2xx sock
  non2xx="$(awk '/Non-2xx or 3xx responses:/ {print $5}' "$OUT/$1.txt")"
  sock="$(awk -F'[ ,]+' '/Socket errors:/ {print $4 + $6 + $8 + $10}' "$OUT/$1.txt")"
  echo $(( ${non2xx:-0} + ${sock:-0} ))
}
rss_kib() { awk '/^VmRSS:/ {print $2}' "/proc/$SERVER_PID/status"; }
# The round of NAME with the median rate: "NAME-r2".
median_round() {
  for ((r = 1; r <= ROUNDS; r++)); do echo "$(rate "$1-r$r") $1-r$r"; done |
    sort -n | awk -v m=$(( (ROUNDS + 1) / 2 )) 'NR == m {print $2}'
}

echo "warm-up"
run warmup-healthz 3 /healthz
run warmup-corners 3 /v1/pose/corners "$OUT/corners.lua"
run warmup-image 3 "/v1/pose/image?$IMAGE_QUERY" "$OUT/image.lua"

for ((r = 1; r <= ROUNDS; r++)); do
  echo "round $r/$ROUNDS: GET /healthz, POST /v1/pose/corners, POST /v1/pose/image, ${DURATION_S}s each"
  run "healthz-r$r" "$DURATION_S" /healthz
  run "corners-r$r" "$DURATION_S" /v1/pose/corners "$OUT/corners.lua"
  run "image-r$r" "$DURATION_S" "/v1/pose/image?$IMAGE_QUERY" "$OUT/image.lua"
done
healthz="$(median_round healthz)"
corners="$(median_round corners)"
image="$(median_round image)"

echo "soak: POST /v1/pose/corners for ${SOAK_S}s, RSS every ${SAMPLE_S}s"
run soak "$SOAK_S" /v1/pose/corners "$OUT/corners.lua" &
WRK_PID=$!
rss=()
for ((t = 0; t <= SOAK_S; t += SAMPLE_S)); do
  rss+=("$(rss_kib)")
  sleep "$SAMPLE_S"
done
wait "$WRK_PID"
rss+=("$(rss_kib)")

h="$(rate "$healthz")"
c="$(rate "$corners")"
ratio="$(awk -v c="$c" -v h="$h" 'BEGIN {printf "%.2f", c / h}')"
# Flat: the last samples exceed the one taken after the first interval (warm) by at most
# the slack.
rss_base="${rss[1]}"
rss_max_late="$(printf '%s\n' "${rss[@]: -3}" | sort -n | tail -1)"
rss_growth=$(( rss_max_late - rss_base ))
total_errors=0
for f in "$OUT"/healthz-r*.txt "$OUT"/corners-r*.txt "$OUT"/image-r*.txt "$OUT"/soak.txt; do
  total_errors=$(( total_errors + $(errors "$(basename "$f" .txt)") ))
done

echo
echo "| endpoint | requests/s | p50 ms | p99 ms | server CPU µs/request | errors |"
echo "|---|---:|---:|---:|---:|---:|"
row() { echo "| $1 | $(rate "$2") | $(pct "$2" 50) | $(pct "$2" 99) | $(cpu_us "$2") | $(errors "$2") |"; }
row "GET /healthz (median of $ROUNDS × ${DURATION_S} s)" "$healthz"
row "POST /v1/pose/corners (median of $ROUNDS × ${DURATION_S} s)" "$corners"
row "POST /v1/pose/corners (${SOAK_S} s soak)" soak
row "POST /v1/pose/image, 1280x720 JPEG (median of $ROUNDS × ${DURATION_S} s)" "$image"
echo
echo "corners / healthz rate: $ratio (target >= $TARGET_RATIO)"
echo "RSS during the soak, KiB, every ${SAMPLE_S}s: ${rss[*]}"
echo "RSS growth after warm-up: ${rss_growth} KiB (allowed ${RSS_SLACK_KIB} KiB)"

status=0
if (( total_errors != 0 )); then echo "FAIL: $total_errors errors"; status=1; else echo "PASS: zero errors"; fi
if awk -v r="$ratio" -v t="$TARGET_RATIO" 'BEGIN {exit !(r >= t)}'; then
  echo "PASS: corners at ${ratio} of the /healthz rate"
else
  echo "FAIL: corners at ${ratio} of the /healthz rate, below ${TARGET_RATIO}"; status=1
fi
if (( rss_growth <= RSS_SLACK_KIB )); then echo "PASS: RSS flat"; else echo "FAIL: RSS grew"; status=1; fi
exit "$status"
