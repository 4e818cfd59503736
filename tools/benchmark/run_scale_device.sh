#!/usr/bin/env bash
# The one-GPU scale runs on a GPU machine: GPU tests, the engine benchmark rows (compact tank_box and spreading
# dam_break, single precision), then the command-line runs of the large tank scenes with device and host peaks.
#   tools/benchmark/run_scale_device.sh BIN_DIR "SIZES" [scene.json ...]
# BIN_DIR is a build of this source tree (build/release, say); run the script from the tree's root, at the path the
# build was configured in (the tests find their files through FBAR_SOURCE_DIR, compiled in).
set -uo pipefail
OUT=${OUT:-$PWD/out}
mkdir -p "$OUT"
BIN=$1; SIZES=$2; shift 2
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee "$OUT/device.txt"
if [ -x "$BIN/gpu_engine_tests" ] && [ "${FBAR_SKIP_TESTS:-0}" != "1" ]; then
  "$BIN/gpu_engine_tests" --gtest_brief=1 > "$OUT/gpu_tests.log" 2>&1
  echo "gpu tests rc=$?"; grep -E "PASSED|FAILED|SKIPPED" "$OUT/gpu_tests.log" | head -20
fi
"$BIN/fbar_benchmark" --scenes=tank_box,dam_break --precisions=single --sizes="$SIZES" --steps=20 --warmup=5 \
  --csv="$OUT/scale_benchmark.csv" > "$OUT/scale_benchmark.log" 2>&1
grep -v "^fbar: GPU engine:" "$OUT/scale_benchmark.log" | tail -14
[ $# -gt 0 ] && tools/benchmark/run_scale.sh "$BIN" "$@"
