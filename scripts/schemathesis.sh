#!/usr/bin/env bash
# Schemathesis against the documents the server serves (docs/service.md, Fuzzing): generated requests
# for every operation, with every check schemathesis has (`--checks all`): no 5xx, status
# codes, content types, headers and answers as documented, 405 for other methods, valid data
# accepted (`positive_data_acceptance`: a request valid by the document is answered 2xx) and
# invalid data refused (`negative_data_rejection`: one that is not is answered 4xx). Run by
# .ci/run after `cargo test` (which builds the binary).
#
#   scripts/schemathesis.sh [BINARY] [SECONDS]      # defaults: target/debug/qrpose, 180
#
# Four servers: with a site (cameras by id, sizes by payload) and without, each with an auth
# file (its document declares the bearer scheme and each operation's scope; schemathesis
# holds a valid token) and without one (its document asks for no token). Each serves its
# own document and gets two bounded runs with a fixed seed, an eighth of SECONDS each:
#   1. positive data (valid by the document) for every operation. A valid request is refused
#      only for what no schema can say (the residue: docs/service.md, Fuzzing); the
#      hooks (scripts/schemathesis_hooks.py) map generated requests into the valid subset
#      for each rule of it, in this run only, each mapping documented there with its rule.
#   2. negative data (invalid by the document), sent as generated.
# No check may fail in any run. The share of requests answered 200 is printed per operation
# for the positive runs; with QRPOSE_ST_MIN_OK_SHARE=0.9 the script fails below that share
# of positive POSTs answered 200.
# Schemathesis (PyPI, pinned) goes into target/st-venv, created on first use.
set -euo pipefail
cd "$(dirname "$0")/.."

binary=${1:-target/debug/qrpose}
# The photos come from the renderer beside it (`cargo test` and `cargo build` build both).
render="$(dirname "$binary")/qrpose-sim"
seconds=${2:-180}
eighth=$((seconds / 8))
venv=target/st-venv
report=target/schemathesis
version=4.32.5

if [[ ! -x "$venv/bin/st" ]] || ! "$venv/bin/st" --version | grep -q "$version"; then
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "schemathesis==$version"
fi

rm -rf "$report"
mkdir -p "$report"
# Photos of codes for the image endpoints and the calibration, and the site of the server
# that has one.
"$render" render --out "$report/code.png" --z-mm 400 >/dev/null
"$render" render --out "$report/code.jpg" --z-mm 600 --payload TOTE-1 >/dev/null
# Views of one code from four angles, small, for the calibration.
views=()
for angles in "0 0" "25 0" "0 25" "-20 15"; do
  read -r alpha beta <<<"$angles"
  view="$report/view_${alpha}_${beta}.jpg"
  "$render" render --out "$view" --z-mm 250 --alpha-deg "$alpha" --beta-deg "$beta" \
    --width-px 320 --height-px 240 >/dev/null
  views+=("$view")
done
cat >"$report/site.yaml" <<'YAML'
cameras:
  front:
    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}
markers:
  default_size_mm: 50
YAML
# The documents of the servers with an auth file describe a server that checks tokens
# (src/http/openapi/security.rs: each protected operation names its scope); schemathesis
# sends the token of a client with every scope through their `bearer` scheme, so that
# `ignored_auth` checks that a missing or wrong token is refused (401). The servers without
# one serve a document with no security requirement, and get no token.
export QRPOSE_ST_TOKEN=$("$binary" auth add schemathesis --scopes pose,site,admin,metrics \
  --file "$report/auth.yaml" 2>/dev/null)
[[ -n "$QRPOSE_ST_TOKEN" ]] || { echo "qrpose auth add printed no token" >&2; exit 1; }
cat >"$report/schemathesis.toml" <<'TOML'
[auth.openapi.bearer]
bearer = "${QRPOSE_ST_TOKEN}"
TOML
export QRPOSE_ST_IMAGES="$report/code.png:$report/code.jpg"
QRPOSE_ST_VIEWS=$(IFS=:; echo "${views[*]}")
export QRPOSE_ST_VIEWS
export SCHEMATHESIS_HOOKS=schemathesis_hooks
export PYTHONPATH="$PWD/scripts${PYTHONPATH:+:$PYTHONPATH}"

servers=()
trap 'for pid in "${servers[@]}"; do kill "$pid" 2>/dev/null || true; done' EXIT
# Starts a server named $1 with the options after it; its URL in $url. (Not in a command
# substitution: a subshell would keep the server's pid from the exit trap.)
start() {
  local name=$1
  shift
  # A long queue: the queue is not what is tested here. The server answers every request
  # within its timeout, 503 `timeout` at worst (a `thorough` detection of a large photo in
  # the debug build can take longer on a loaded machine); 8 s keeps every answer within the
  # response time `--checks all` allows (`max_response_time`, 10 s by default), which so
  # checks that the timeout bounds each answer. Schemathesis itself waits up to 30 s.
  "$binary" serve --addr 127.0.0.1:0 --queue-length 1000 --request-timeout-ms 8000 "$@" \
    >"$report/$name.address" 2>"$report/$name.log" &
  servers+=($!)
  for _ in $(seq 100); do
    [[ -s "$report/$name.address" ]] && break
    sleep 0.1
  done
  url=$(sed -n 's|^listening on \(http://[^ ]*\).*|\1|p' "$report/$name.address")
  [[ -n "$url" ]] || { echo "the $name server did not start: $(cat "$report/$name.log")" >&2; exit 1; }
}
start site --auth-file "$report/auth.yaml" --site "$report/site.yaml"
site_url=$url
start no-site --auth-file "$report/auth.yaml"
plain_url=$url
start site-open --site "$report/site.yaml"
site_open_url=$url
start no-site-open
plain_open_url=$url
: >"$report/open.toml"

# Runs schemathesis: $1 the server's name, $2 its URL, $3 positive or negative.
failed=()
run() {
  local name=$1 url=$2 mode=$3
  local site_file= config="$report/schemathesis.toml"
  [[ $name == site* ]] && site_file="$report/site.yaml"
  [[ $name == *-open ]] && config="$report/open.toml"
  echo "== $name, $mode data"
  # Fuzzing only: the examples phase would send the document's examples with an `image`
  # part that is no image and cannot be mapped without schemathesis counting it negative.
  # One worker: with two threads, hypothesis's `ast.parse` (describing a strategy) fails now
  # and then with "SystemError: AST constructor recursion depth mismatch", CPython's
  # AST recursion counter not being thread-safe (python/cpython#106905, Python 3.11).
  if ! QRPOSE_ST_MODE=$mode QRPOSE_ST_SITE=$site_file QRPOSE_ST_DROPPED="$report/$name-$mode.dropped" \
    "$venv/bin/st" --config-file "$config" run "$url/openapi.json" --seed 1 --mode "$mode" --phases fuzzing \
    --max-time "$eighth" --checks all --no-color --workers 1 --request-timeout 30 \
    --suppress-health-check all --generation-database none \
    --report har --report-har-path "$report/$name-$mode.har"; then
    failed+=("$name $mode")
  fi
  # Reports of valid requests that schemathesis labelled negative (the hooks' filter_failure).
  echo "$name, $mode data: $(cat "$report/$name-$mode.dropped" 2>/dev/null | wc -l) reports of valid requests labelled negative dropped"
}
run site "$site_url" positive
run site "$site_url" negative
run no-site "$plain_url" positive
run no-site "$plain_url" negative
run site-open "$site_open_url" positive
run site-open "$site_open_url" negative
run no-site-open "$plain_open_url" positive
run no-site-open "$plain_open_url" negative

"$venv/bin/python" - "${QRPOSE_ST_MIN_OK_SHARE:-0}" "$report"/*.har <<'EOF'
import collections, json, sys
minimum = float(sys.argv[1])
short = []
for har in sys.argv[2:]:
    entries = json.load(open(har))["log"]["entries"]
    sent = collections.Counter()
    ok = collections.Counter()
    for e in entries:
        operation = e["request"]["method"] + " /" + e["request"]["url"].split("?")[0].split("/", 3)[-1]
        sent[operation] += 1
        ok[operation] += e["response"]["status"] == 200
    print(f"{har.rsplit('/', 1)[-1]}:")
    for operation in sorted(sent):
        print(f"  {operation}: {sent[operation]} requests, {ok[operation]} answered 200 "
              f"({100 * ok[operation] / sent[operation]:.0f} %)")
    if "positive" in har:
        posts = [o for o in sent if o.startswith("POST /v1/pose")]
        total, answered = sum(sent[o] for o in posts), sum(ok[o] for o in posts)
        print(f"  positive pose POSTs: {answered} of {total} answered 200 "
              f"({100 * answered / max(total, 1):.0f} %)")
        if total == 0 or answered < minimum * total:
            short.append(har)
if short:
    sys.exit(f"fewer than {minimum:.0%} of the positive pose POSTs were answered 200: {short}")
EOF
if ((${#failed[@]})); then
  echo "schemathesis found failures in: ${failed[*]}" >&2
  exit 1
fi
