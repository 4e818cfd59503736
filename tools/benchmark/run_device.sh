#!/usr/bin/env bash
# Build (Release, sm_90), run the GPU tests, then the benchmark, on a machine with a GPU. Logs go to $OUT (or ./out).
#   tools/benchmark/run_device.sh [benchmark arguments...]      (FBAR_SKIP_BENCH=1: tests only)
set -uo pipefail
OUT=${OUT:-$PWD/out}
mkdir -p "$OUT"
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${FBAR_BUILD_DIR:-$ROOT/build/device}
EXTRA=()
[ -d "$ROOT/.device_deps/include" ] && EXTRA+=(-DRapidJSON_INCLUDE_DIRS="$ROOT/.device_deps/include" -DCMAKE_PREFIX_PATH="$ROOT/.device_deps")
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee "$OUT/device.txt"
cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=90 "${EXTRA[@]}" \
  > "$OUT/configure.log" 2>&1 || { tail -30 "$OUT/configure.log"; exit 1; }
ninja -C "$BUILD" -j16 gpu_engine_tests fbar_benchmark fbar > "$OUT/build.log" 2>&1 || { grep -E "error" -A3 "$OUT/build.log" | head -60; exit 1; }
echo "build ok"
(cd "$BUILD" && ctest -R "Gpu" --output-on-failure --timeout 120 > "$OUT/ctest.log" 2>&1); rc=$?
grep -E "\[measured\]|tests passed|Failed|FAILED|Passed|\*\*\*" "$OUT/ctest.log" | head -80
"$BUILD/tests/engine/gpu/gpu_engine_tests" --gtest_filter='GpuVsCpu.*:GpuFailures.*:GpuScenes.*' 2>&1 | grep "\[measured\]" | head -40
if [ "${FBAR_SKIP_BENCH:-0}" != "1" ]; then
  "$BUILD/fbar_benchmark" --csv="$OUT/benchmark.csv" "$@" 2>&1 | tee "$OUT/benchmark.log" | tail -40
fi
exit $rc
