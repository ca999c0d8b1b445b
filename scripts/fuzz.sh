#!/usr/bin/env bash
# cargo fuzz targets of qrpose (fuzz/), each for SECONDS (default 600):
#
#   scripts/fuzz.sh [SECONDS] [TARGET...]      # targets: json_request decode detect estimators splice
#
# Installs cargo-fuzz from crates.io when missing. The machine's toolchain is stable, so the
# build runs with RUSTC_BOOTSTRAP=1 (cargo fuzz passes -Z flags) and without a sanitizer
# (`--sanitizer none`: libFuzzer's coverage guidance only; panics and aborts are still
# crashes). The corpus starts from fuzz/seeds/TARGET (committed) and grows in
# fuzz/corpus/TARGET (ignored); a crash is written to fuzz/artifacts/TARGET and becomes a
# regression test under tests/ or the crate it is in.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
shift || true
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=(json_request decode detect estimators splice)
command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz --locked
for target in "${targets[@]}"; do
  mkdir -p "fuzz/corpus/$target"
  cp -n "fuzz/seeds/$target/"* "fuzz/corpus/$target/" 2>/dev/null || true
  (cd fuzz && RUSTC_BOOTSTRAP=1 cargo fuzz run --sanitizer none -O "$target" "corpus/$target" -- \
    -max_total_time="$seconds" -seed=1 -rss_limit_mb=2048 -print_final_stats=1) 2>&1 \
    | tee "fuzz/$target.log" | grep -E "^(#[0-9]+\s+DONE|Done|==[0-9]+==|stat::)" || true
  grep -q "^Done" "fuzz/$target.log" || { echo "$target: did not finish cleanly (fuzz/$target.log)" >&2; exit 1; }
done
