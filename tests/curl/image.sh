#!/usr/bin/env bash
# POST /v1/pose/image: every QR code in a photo, with its payload, sub-pixel corners and pose.
# Usage: BASE_URL=http://127.0.0.1:8080 IMAGE_PATH=code.jpg tests/curl/image.sh
#        (or tests/curl/image.sh BASE_URL IMAGE_PATH)
# The photo must show a 50 mm code to a 1280x720 camera with f = 1000 px, such as
#   qrpose-sim render --out code.jpg --payload SKU-1 --marker-size-mm 50 --z-mm 400 --alpha-deg 20
# (the curl suite renders one that way before it runs the scripts).
set -euo pipefail
source "$(dirname "$0")/lib/check.sh"
IMAGE_PATH="${IMAGE_PATH:-${2:-}}"
if [[ ! -r "$IMAGE_PATH" ]]; then
  echo "usage: BASE_URL=http://HOST:PORT IMAGE_PATH=code.jpg $0" >&2
  exit 2
fi

# The JPEG as the raw body; camera, marker and solver as query parameters.
check 200 application/json \
  curl -sS -X POST \
    "$BASE_URL/v1/pose/image?fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50" \
    -H 'Content-Type: image/jpeg' \
    --data-binary "@$IMAGE_PATH"
body_has '"image":{"width_px":1280,"height_px":720}'
body_has '"markers":[{"payload":'
body_has '"position_mm"'

# The same as multipart/form-data: the photo and the corners request without corners.
check 200 application/json \
  curl -sS -X POST "$BASE_URL/v1/pose/image" \
    -F "image=@$IMAGE_PATH;type=image/jpeg" \
    -F 'request={
          "camera": {"fx_px": 1000, "fy_px": 1000, "cx_px": 639.5, "cy_px": 359.5},
          "marker": {"size_mm": 50},
          "solver": {"method": "paper"},
          "detector": "rqrr"
        };type=application/json'
body_has '"detector":"rqrr"'
body_has '"method":"paper"'

# 422 missing_field: the marker size is required; `field` names the query parameter.
check 422 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/image?fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5" \
    -H 'Content-Type: image/jpeg' --data-binary "@$IMAGE_PATH"
body_has '"code":"missing_field"'
body_has '"field":"marker_size_mm"'

# 422 undecodable_image: not an image.
check 422 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/image?fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50" \
    -H 'Content-Type: image/jpeg' --data-binary 'not a jpeg'
body_has '"code":"undecodable_image"'

# 413 image_too_large: a PNG header declaring 100000 x 100000 pixels, refused unread.
check 413 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/image?fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50" \
    -H 'Content-Type: image/png' \
    --data-binary @<(printf '\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR\x00\x01\x86\xa0\x00\x01\x86\xa0\x08\x00\x00\x00\x00\x00\x00\x00\x00')
body_has '"code":"image_too_large"'

# 415 unsupported_media_type: send image/jpeg, image/png or multipart/form-data.
check 415 application/problem+json \
  curl -sS -X POST "$BASE_URL/v1/pose/image" \
    -H 'Content-Type: application/octet-stream' --data-binary "@$IMAGE_PATH"
body_has '"code":"unsupported_media_type"'
