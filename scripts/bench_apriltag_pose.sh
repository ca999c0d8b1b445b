#!/usr/bin/env bash
# AprilTag's pose code (libapriltag, C) beside qrpose and OpenCV on the same corner dataset:
# accuracy (one markdown table: qrpose, OpenCV, AprilTag) and per-call time (AprilTag's bench and
# qrpose's pose_timing alternated 3 rounds on one core; the per-round ratio is the result).
# Installs AprilTag's development package (Debian libapriltag-dev) when missing.
#
#   scripts/bench_apriltag_pose.sh
set -euo pipefail
cd "$(dirname "$0")/.."

if [ ! -f /usr/include/apriltag/apriltag_pose.h ]; then
  echo "installing libapriltag-dev" >&2
  if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libapriltag-dev >/dev/null
fi
mkdir -p target/accuracy target/apriltag-bench
cargo run --release -q --example corner_accuracy -- target/accuracy 0.5 2000 2022 >/dev/null
gcc -O2 -std=c11 -Wall benches/apriltag/pose_bench.c -o target/apriltag-bench/pose_bench -lapriltag -lm
cargo build --release -q --example pose_timing

version=$(dpkg-query -W -f='${Version}' libapriltag-dev 2>/dev/null || echo unknown)
echo "libapriltag-dev $version, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"

echo
echo "## Frame check: exact corners projected from the true poses"
target/apriltag-bench/pose_bench --exact target/accuracy/corners.csv

echo
echo "## Accuracy"
# One untimed pass writes every AprilTag pose (one estimate_tag_pose call per case).
# estimate_tag_pose prints "more than one new minimum found" to stderr for some cases; counted below.
target/apriltag-bench/pose_bench target/accuracy/corners.csv target/apriltag-bench/poses.csv --no-timing \
  2>target/apriltag-bench/stderr.txt
echo "(libapriltag printed \"more than one new minimum found\" for $(grep -c 'more than one new minimum' target/apriltag-bench/stderr.txt || true) of the cases; it then keeps the first solution)"
python3 scripts/accuracy_apriltag.py target/apriltag-bench/poses.csv

echo
echo "## Time per call, one core (taskset -c 0), programs alternated"
results=$(for round in 1 2 3; do
  taskset -c 0 target/apriltag-bench/pose_bench target/accuracy/corners.csv 2>/dev/null | sed "s/^/$round /"
  taskset -c 0 target/release/examples/pose_timing target/accuracy/corners.csv | sed "s/^/$round /"
done)
echo "| solver | median ns per call (round 1, 2, 3) |"
echo "|---|---|"
echo "$results" | awk '{ a[$2] = a[$2] " " $3 } END { for (k in a) print k, a[k] }' | sort | while read -r name t1 t2 t3; do
  echo "| $name | $t1, $t2, $t3 |"
done
echo
echo "| round | qrpose_reprojection / apriltag_estimate_tag_pose | qrpose_reprojection / apriltag_homography (our re-implementation of its homography pose, not libapriltag code) |"
echo "|---|---|---|"
echo "$results" | awk '
  $2 == "qrpose_reprojection" { q[$1] = $3 }
  $2 == "apriltag_estimate_tag_pose" { a[$1] = $3 }
  $2 == "apriltag_homography" { h[$1] = $3 }
  END { for (r = 1; r <= 3; r++) if (a[r] && h[r]) printf "| %d | %.4f | %.2f |\n", r, q[r] / a[r], q[r] / h[r] }'
