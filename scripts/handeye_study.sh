#!/usr/bin/env bash
# Hand-eye calibration against ground truth (docs/measurements/hand-eye.md): renders
# 20 sessions per setup, calibrates them with qrpose at two flange-noise levels, runs
# OpenCV's calibrateHandEye (five methods, two anchors) on the same photos and poses, and
# prints the tables.
#
#   scripts/handeye_study.sh [SEEDS]        # default 20; writes target/handeye-study/
#
# Python packages go to a venv in target/handeye-venv (pinned below, from PyPI).
set -euo pipefail
cd "$(dirname "$0")/.."
SEEDS="${1:-20}"
TARGET="${CARGO_TARGET_DIR:-target}"
OUT="$TARGET/handeye-study"
VENV="$TARGET/handeye-venv"
if [[ ! -x "$VENV/bin/python" ]] || ! "$VENV/bin/python" -c "import cv2, zxingcpp, numpy" 2>/dev/null; then
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install --quiet opencv-python-headless==4.10.0.84 zxing-cpp==2.3.0 numpy==2.2.6
fi
cargo build --release -p qrpose-sim --example handeye_study
mkdir -p "$OUT"
"$TARGET/release/examples/handeye_study" "$OUT" --seeds "$SEEDS" | tee "$OUT/qrpose.log"
"$VENV/bin/python" scripts/handeye_study.py "$OUT" | tee "$OUT/tables.md"
