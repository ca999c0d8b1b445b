#!/usr/bin/env bash
# Health, readiness, metrics, the OpenAPI document and the interactive docs.
# Usage: BASE_URL=http://127.0.0.1:8080 tests/curl/operations.sh
set -euo pipefail
source "$(dirname "$0")/lib/check.sh"

# Liveness and readiness (readiness says 503 shutting_down while draining).
check 200 application/json curl -sS "$BASE_URL/healthz"
body_has '"status":"ok"'
check 200 application/json curl -sS "$BASE_URL/readyz"
body_has '"status":"ready"'

# Prometheus metrics, OpenMetrics text format.
check 200 application/openmetrics-text curl -sS "$BASE_URL/metrics"
body_has 'qrpose_http_requests_total'
body_has 'qrpose_estimation_queue_depth'

# The OpenAPI 3.1 document (the same as openapi/openapi.json and `qrpose openapi`).
check 200 application/json curl -sS "$BASE_URL/openapi.json"
body_has '"openapi": "3.1.0"'

# Swagger UI, served from the binary (/docs redirects to /docs/).
check 200 text/html curl -sSL "$BASE_URL/docs"
body_has 'swagger-ui'

# Every response carries x-request-id: yours if you send a short token, else a fresh UUID.
headers="$(curl -sS -D - -o /dev/null -H 'X-Request-Id: robot-7.req-42' "$BASE_URL/healthz")"
if ! grep -qi '^x-request-id: robot-7.req-42' <<<"$headers"; then
  echo "FAIL: x-request-id not echoed: $headers" >&2
  exit 1
fi
echo "ok   x-request-id echoed"
