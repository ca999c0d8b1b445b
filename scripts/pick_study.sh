#!/usr/bin/env bash
# The picking study through the service's own path (docs/measurements/pick.md): renders a
# study, runs the anchor (scripts/pick_anchor.sh) and qrpose's CLI on the same photos, and
# prints the tables (scripts/pick_study.py, stdlib only).
#
#   scripts/pick_study.sh SEED [--picks 200] [--out DIR] [--sigma-seed S]
#                              [--tolerance-scale 0.1 ...] [--jobs 2]
#
# Builds the release binaries first (a no-op when they are up to date).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
cargo build --release -q -p qrpose -p qrpose-sim --bins
exec python3 "$root/scripts/pick_study.py" --bin "$root/target/release" "$@"
