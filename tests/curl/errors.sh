#!/usr/bin/env bash
# Errors are RFC 9457 problem documents (application/problem+json) with a stable `code`
# and, when one field is at fault, `field` (a JSON pointer).
# Usage: BASE_URL=http://127.0.0.1:8080 tests/curl/errors.sh
set -euo pipefail
source "$(dirname "$0")/lib/check.sh"

# 400 malformed_json: not JSON.
check 400 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/corners" -H 'Content-Type: application/json' -d '{"corners_px": [['
body_has '"code":"malformed_json"'

# 422 duplicate_corners: JSON, but unusable; `field` names the culprit.
check 422 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/corners" \
    -H 'Content-Type: application/json' \
    -d '{
          "corners_px": [[589.2, 309.8], [689.9, 311.4], [589.2, 309.8], [588.0, 409.5]],
          "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5},
          "marker": {"size_mm": 50}
        }'
body_has '"code":"duplicate_corners"'
body_has '"field":"/corners_px/2"'

# 422 missing_field.
check 422 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/corners" -H 'Content-Type: application/json' \
    -d '{"corners_px": [[0, 0], [1, 0], [1, 1], [0, 1]], "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 0, "cy_px": 0}}'
body_has '"field":"/marker"'

# 415 unsupported_media_type: the body must be sent as application/json.
check 415 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/corners" -H 'Content-Type: text/plain' -d '{}'
body_has '"code":"unsupported_media_type"'

# 413 payload_too_large: 30 MB is over the default 24 MiB limit.
check 413 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/corners" -H 'Content-Type: application/json' \
    --data-binary @<(head -c 30000000 /dev/zero)
body_has '"code":"payload_too_large"'

# 404 not_found and 405 method_not_allowed (with an Allow header).
check 404 application/problem+json curl -sS "$BASE_URL/v1/pose/nowhere"
body_has '"code":"not_found"'
check 405 application/problem+json curl -sS "$BASE_URL/v1/pose/corners"
body_has '"code":"method_not_allowed"'

# The service is still up.
check 200 application/json curl -sS "$BASE_URL/healthz"
