#!/usr/bin/env bash
# POST /v1/pose/corners: the pose of a 50 mm QR code from its four corner pixels
# (top-left, top-right, bottom-right, bottom-left), seen by a 1280x720 camera.
# Usage: BASE_URL=http://127.0.0.1:8080 tests/curl/corners.sh
set -euo pipefail
source "$(dirname "$0")/lib/check.sh"

# The default solver (reprojection): position in mm, Euler angles in degrees, diagnostics.
check 200 application/json \
  curl -sS -X POST "$BASE_URL/v1/pose/corners" \
    -H 'Content-Type: application/json' \
    -d '{
          "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
          "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5},
          "marker": {"size_mm": 50}
        }'
body_has '"position_mm"'
body_has '"euler_xyz_deg"'
body_has '"converged":true'

# The paper's iterative method, with its per-iteration trace.
check 200 application/json \
  curl -sS -X POST "$BASE_URL/v1/pose/corners" \
    -H 'Content-Type: application/json' \
    -d '{
          "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
          "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5},
          "marker": {"size_mm": 50},
          "solver": {"method": "paper", "initial_z_mm": 450, "gain": 1.0, "trace": true}
        }'
body_has '"method":"paper"'
body_has '"trace":[{'

# The paper's own form: corners in image-plane millimetres and the lens focal length.
check 200 application/json \
  curl -sS -X POST "$BASE_URL/v1/pose/corners" \
    -H 'Content-Type: application/json' \
    -d '{
          "corners_mm": [[-0.2012, -0.1988], [0.2016, -0.1924], [0.1944, 0.2084], [-0.206, 0.2]],
          "camera": {"focal_length_mm": 4.0},
          "marker": {"size_mm": 50},
          "solver": {"method": "depth-newton"}
        }'
body_has '"method":"depth-newton"'
