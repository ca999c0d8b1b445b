#!/usr/bin/env bash
# What auth and TLS cost (docs/security.md): requests/s, p50/p99 latency and the server's CPU
# time per request of POST /v1/pose/corners and GET /healthz on four servers started side by
# side from the same release binary: plain, with an auth file (bearer token checked on every
# corners request), with TLS (kept-alive connections: the handshake is paid once per
# connection), and with both. Then `reconnect`: /healthz with a new connection for every
# request (`Connection: close`) on the plain and the TLS server, where TLS pays a full
# handshake each time.
#
# Rounds alternate over the servers and endpoints, and each is reported by its median round,
# so that load from other processes on a shared machine hits all of them alike. The server's
# CPU time per request (from /proc) does not depend on that load: its difference between the
# plain and the auth server is the token check's cost.
#
# Checks (exit 1 when one fails): zero errors, and the load bar of scripts/load.sh on every
# server: corners rate >= TARGET_RATIO of the same server's /healthz rate (/healthz is open,
# so it carries no token check).
#
# Usage: scripts/security_load.sh   (installs wrk from Debian if missing; builds release)
# Knobs: ROUNDS=3 DURATION_S=10 CONNECTIONS=32 WRK_THREADS=2 TARGET_RATIO=0.70
#        CARGO_TARGET_DIR (where the release binary is built), QRPOSE_BIN (a binary to use
#        instead of building one), RUST_LOG=info, KEEP_LOGS=1 (keep the servers' access logs
#        in target/security-load/; deleted by default, they run to gigabytes)
# Only loopback traffic; every wrk run is bounded by its duration.
set -euo pipefail
cd "$(dirname "$0")/.."

ROUNDS="${ROUNDS:-3}"
DURATION_S="${DURATION_S:-10}"
CONNECTIONS="${CONNECTIONS:-32}"
WRK_THREADS="${WRK_THREADS:-2}"
TARGET_RATIO="${TARGET_RATIO:-0.70}"
OUT="target/security-load"
rm -rf "$OUT"
mkdir -p "$OUT"

for tool in wrk openssl; do
  if ! command -v "$tool" >/dev/null; then
    echo "installing $tool (Debian package)"
    sudo=""
    [[ "$(id -u)" == 0 ]] || sudo=sudo
    $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$tool"
  fi
done

if [[ -n "${QRPOSE_BIN:-}" ]]; then
  BIN="$QRPOSE_BIN"
else
  cargo build --release --quiet --bin qrpose
  BIN="${CARGO_TARGET_DIR:-target}/release/qrpose"
fi

# A certificate for localhost and 127.0.0.1 (P-256, one day), and a client holding `pose`.
openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 1 \
  -subj /CN=localhost -addext subjectAltName=DNS:localhost,IP:127.0.0.1 \
  -keyout "$OUT/key.pem" -out "$OUT/cert.pem" 2>/dev/null
TOKEN="$("$BIN" auth add load --scopes pose --file "$OUT/auth.yaml" 2>/dev/null)"
AUTH=(--auth-file "$OUT/auth.yaml")
TLS=(--tls-cert "$OUT/cert.pem" --tls-key "$OUT/key.pem")

declare -A URL PID
# start NAME ARGS...: `qrpose serve` on a free loopback port, the access log on, in a file.
start() {
  local name="$1"
  shift
  RUST_LOG="${RUST_LOG:-info}" "$BIN" serve --addr 127.0.0.1:0 "$@" \
    >"$OUT/$name.out" 2>"$OUT/$name.log" &
  PID[$name]=$!
  for _ in $(seq 100); do
    grep -q '^listening on ' "$OUT/$name.out" 2>/dev/null && break
    sleep 0.1
  done
  URL[$name]="$(sed -n 's/^listening on //p' "$OUT/$name.out")"
  [[ -n "${URL[$name]}" ]] || { echo "$name did not start"; cat "$OUT/$name.log"; exit 1; }
}
SERVERS=(plain auth tls tls-auth)
trap 'for p in "${PID[@]}"; do kill "$p" 2>/dev/null || true; done' EXIT
start plain
start auth "${AUTH[@]}"
start tls "${TLS[@]}"
start tls-auth "${AUTH[@]}" "${TLS[@]}"
echo "servers ${URL[*]} ($(nproc) CPUs, load average $(cut -d' ' -f1 /proc/loadavg); wrk -t$WRK_THREADS -c$CONNECTIONS)"

cat >"$OUT/corners.lua" <<'LUA'
wrk.method = "POST"
wrk.headers["Content-Type"] = "application/json"
wrk.body = [==[{"corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
  "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5},
  "marker": {"size_mm": 50}}]==]
LUA

# The token is checked, not just carried: without it the auth servers answer 401.
for name in auth tls-auth; do
  code="$(curl -sS -k -o /dev/null -w '%{http_code}' -X POST "${URL[$name]}/v1/pose/corners" \
    -H 'Content-Type: application/json' -d '{}')"
  [[ "$code" == 401 ]] || { echo "FAIL: $name answered $code without a token"; exit 1; }
done

cpu_ticks() { awk '{print $14 + $15}' "/proc/${PID[$1]}/stat"; }
# run SERVER ENDPOINT SECONDS TAG: one bounded wrk run; its report in $OUT/TAG.txt and the
# server's CPU time over the run (clock ticks) in $OUT/TAG.cpu. The token goes with every
# request to an auth server (it is ignored on /healthz).
run() {
  local server="$1" endpoint="$2" seconds="$3" tag="$4"
  local args=(-t"$WRK_THREADS" -c"$CONNECTIONS" -d"${seconds}s" --timeout 5s --latency)
  [[ "$server" == *auth ]] && args+=(-H "Authorization: Bearer $TOKEN")
  local path=/healthz
  if [[ "$endpoint" == corners ]]; then
    args+=(-s "$OUT/corners.lua")
    path=/v1/pose/corners
  elif [[ "$endpoint" == reconnect ]]; then
    args+=(-H "Connection: close")
  fi
  local before
  before="$(cpu_ticks "$server")"
  wrk "${args[@]}" "${URL[$server]}$path" >"$OUT/$tag.txt"
  echo $(( $(cpu_ticks "$server") - before )) >"$OUT/$tag.cpu"
}
rate() { awk '/^Requests\/sec:/ {print $2}' "$OUT/$1.txt"; }
count() { awk '/ requests in / {print $1}' "$OUT/$1.txt"; }
cpu_us() {
  awk -v t="$(cat "$OUT/$1.cpu")" -v n="$(count "$1")" -v hz="$(getconf CLK_TCK)" \
    'BEGIN {printf "%.0f", t * 1e6 / hz / n}'
}
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
median_round() {
  for ((r = 1; r <= ROUNDS; r++)); do echo "$(rate "$1-r$r") $1-r$r"; done |
    sort -n | awk -v m=$(( (ROUNDS + 1) / 2 )) 'NR == m {print $2}'
}

echo "warm-up"
for s in "${SERVERS[@]}"; do
  run "$s" healthz 2 "warmup-$s-healthz"
  run "$s" corners 2 "warmup-$s-corners"
done
for ((r = 1; r <= ROUNDS; r++)); do
  echo "round $r/$ROUNDS: /healthz and corners on ${SERVERS[*]}, ${DURATION_S}s each"
  for s in "${SERVERS[@]}"; do
    run "$s" healthz "$DURATION_S" "$s-healthz-r$r"
    run "$s" corners "$DURATION_S" "$s-corners-r$r"
  done
  for s in plain tls; do
    run "$s" reconnect "$DURATION_S" "$s-reconnect-r$r"
  done
done

status=0
echo
echo "| server | endpoint | requests/s | p50 ms | p99 ms | server CPU µs/request | errors |"
echo "|---|---|---:|---:|---:|---:|---:|"
for s in "${SERVERS[@]}"; do
  for e in healthz corners; do
    m="$(median_round "$s-$e")"
    echo "| $s | $e | $(rate "$m") | $(pct "$m" 50) | $(pct "$m" 99) | $(cpu_us "$m") | $(errors "$m") |"
  done
done
for s in plain tls; do
  m="$(median_round "$s-reconnect")"
  echo "| $s | healthz, a new connection each | $(rate "$m") | $(pct "$m" 50) | $(pct "$m" 99) | $(cpu_us "$m") | $(errors "$m") |"
done
echo
total_errors=0
for f in "$OUT"/*-r*.txt; do
  total_errors=$(( total_errors + $(errors "$(basename "$f" .txt)") ))
done
plain_corners="$(rate "$(median_round plain-corners)")"
for s in "${SERVERS[@]}"; do
  h="$(rate "$(median_round "$s-healthz")")"
  c="$(rate "$(median_round "$s-corners")")"
  ratio="$(awk -v c="$c" -v h="$h" 'BEGIN {printf "%.2f", c / h}')"
  vs="$(awk -v c="$c" -v p="$plain_corners" 'BEGIN {printf "%.2f", c / p}')"
  if awk -v r="$ratio" -v t="$TARGET_RATIO" 'BEGIN {exit !(r >= t)}'; then
    echo "PASS: $s: corners at $ratio of its /healthz rate (target >= $TARGET_RATIO); $vs of plain corners"
  else
    echo "FAIL: $s: corners at $ratio of its /healthz rate, below $TARGET_RATIO; $vs of plain corners"
    status=1
  fi
done
if (( total_errors != 0 )); then echo "FAIL: $total_errors errors"; status=1; else echo "PASS: zero errors"; fi
# The access logs (one line per request) run to gigabytes: kept only on request.
[[ -n "${KEEP_LOGS:-}" ]] || rm -f "$OUT"/*.log
exit "$status"
