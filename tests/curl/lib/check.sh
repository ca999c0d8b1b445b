# Shared by tests/curl/*.sh: `check STATUS CONTENT_TYPE curl ARGS...` runs curl, saves the
# body in $BODY and fails unless the status and the content type (a prefix) match;
# `body_has TEXT` fails unless the last body contains TEXT.

BASE_URL="${BASE_URL:-${1:-http://127.0.0.1:8080}}"
BASE_URL="${BASE_URL%/}"
BODY=""
_body_file="$(mktemp)"
trap 'rm -f "$_body_file"' EXIT

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
