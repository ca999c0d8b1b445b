#!/usr/bin/env bash
# The picking anchor (docs/measurements/pick.md): a venv under target/ with pinned
# opencv-python-headless, zxing-cpp and numpy, then scripts/pick_anchor.py on a rendered
# picking study.
#
#   scripts/pick_anchor.sh DIR          # DIR: qrpose-sim render --pick-study … --out DIR
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="$root/target/pick-anchor-venv"
if [ ! -x "$venv/bin/python3" ]; then
  python3 -m venv "$venv"
fi
if ! "$venv/bin/python3" -c "import cv2, zxingcpp, numpy" 2>/dev/null; then
  "$venv/bin/python3" -m pip install -q \
    "opencv-python-headless==4.12.0.88" "zxing-cpp==2.3.0" "numpy==2.2.6"
fi
exec "$venv/bin/python3" "$root/scripts/pick_anchor.py" "$@"
