# Shared by tests/curl/*.sh: `check STATUS CONTENT_TYPE curl ARGS...` runs curl, saves the
# body in $BODY and fails unless the status and the content type (a prefix) match;
# `body_has TEXT` fails unless the last body contains TEXT.
#
# With auth and TLS on (docs/security.md), every `curl` of the scripts sends
# `Authorization: Bearer $TOKEN` when TOKEN is set (from a header file, so the token stays
# out of the process list) and trusts the CA file CACERT when it is set:
#   BASE_URL=https://qrpose.internal:8443 CACERT=ca.pem TOKEN=... tests/curl/corners.sh

BASE_URL="${BASE_URL:-${1:-http://127.0.0.1:8080}}"
BASE_URL="${BASE_URL%/}"
BODY=""
_body_file="$(mktemp)"
_header_file="$(mktemp)"
trap 'rm -f "$_body_file" "$_header_file"' EXIT

_curl_extra=()
if [[ -n "${TOKEN:-}" ]]; then
  printf 'Authorization: Bearer %s\n' "$TOKEN" >"$_header_file"
  _curl_extra+=(-H "@$_header_file")
fi
if [[ -n "${CACERT:-}" ]]; then
  _curl_extra+=(--cacert "$CACERT")
fi
curl() {
  command curl "${_curl_extra[@]}" "$@"
}

check() {
  local want_status="$1" want_type="$2"
  shift 2
  local got status type
  got="$("$@" -o "$_body_file" -w '%{http_code} %{content_type}')"
  status="${got%% *}"
  type="${got#* }"
  BODY="$(cat "$_body_file")"
  if [[ "$status" != "$want_status" || "$type" != "$want_type"* ]]; then
    echo "FAIL: got $status '$type', want $want_status '$want_type' from: $*" >&2
    echo "$BODY" | head -c 2000 >&2
    echo >&2
    exit 1
  fi
  echo "ok   $status $type"
}

body_has() {
  if [[ "$BODY" != *"$1"* ]]; then
    echo "FAIL: the body lacks '$1':" >&2
    echo "$BODY" | head -c 2000 >&2
    echo >&2
    exit 1
  fi
}
