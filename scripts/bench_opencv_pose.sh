#!/usr/bin/env bash
# Per-call time of qrpose's solvers beside OpenCV's planar pose (C++), same cases, same loop,
# one core, same session. Installs OpenCV's development package (Debian) when missing.
#
#   scripts/bench_opencv_pose.sh
set -euo pipefail
cd "$(dirname "$0")/.."

if ! pkg-config --exists opencv4; then
  echo "installing libopencv-dev" >&2
  if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libopencv-dev >/dev/null
fi
mkdir -p target/accuracy target/opencv-bench
cargo run --release -q --example corner_accuracy -- target/accuracy 0.5 2000 2022 >/dev/null
g++ -O2 -std=c++17 benches/opencv/pose_bench.cpp -o target/opencv-bench/pose_bench $(pkg-config --cflags --libs opencv4)
cargo build --release -q --example pose_timing

echo "OpenCV $(pkg-config --modversion opencv4), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
# Pin both to one core; alternate the two programs to share the machine's noise.
results=$(for round in 1 2 3; do
  taskset -c 0 target/opencv-bench/pose_bench target/accuracy/corners.csv
  taskset -c 0 target/release/examples/pose_timing target/accuracy/corners.csv
done)
echo "| solver | median ns per call (3 sessions) |"
echo "|---|---|"
echo "$results" | awk '{ a[$1] = a[$1] " " $2 } END { for (k in a) print k, a[k] }' | sort | while read -r name t1 t2 t3; do
  echo "| $name | $t1, $t2, $t3 |"
done
echo "$results" | awk '
  $1 == "qrpose_reprojection" { q += $2; nq++ }
  $1 == "opencv_ippe_square+refine_lm" { o += $2; no++ }
  END { if (nq && no) printf "\nqrpose reprojection (both candidates + LM + covariance) / OpenCV IPPE_SQUARE + RefineLM: %.2f\n", (q / nq) / (o / no) }'
