#!/usr/bin/env bash
# The GPU suite in one go on a machine with a GPU: every ctest labelled gpu (the GPU engine against the CPU engine,
# the GPU validation cases in gpu_engine_tests, device math and physics, the command line on GPU ranks), with the
# pass / fail / skip counts and each skip's reason recorded with the commit.
#   tools/benchmark/run_gpu_tests.sh            logs in $OUT (or ./out); the record: $OUT/gpu-tests-<date>-<commit>.md,
#                                               to copy to docs/benchmarks/
# Exit status: non-zero when a test failed or skipped for any reason but "needs N GPUs" (.ci/check_skips.py
# --gpu-machine: on a GPU machine "no CUDA device" or "this build has no NCCL" is a failure, not a skip).
set -uo pipefail
OUT=${OUT:-$PWD/out}
mkdir -p "$OUT"
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${FBAR_BUILD_DIR:-$ROOT/build/device}
EXTRA=()
[ -d "$ROOT/.device_deps/include" ] && EXTRA+=(-DRapidJSON_INCLUDE_DIRS="$ROOT/.device_deps/include" -DCMAKE_PREFIX_PATH="$ROOT/.device_deps")
commit=$(git -C "$ROOT" rev-parse --short HEAD 2>/dev/null || echo unknown)
device=$(nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null | head -4)
cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=90 "${EXTRA[@]}" \
  > "$OUT/configure.log" 2>&1 || { tail -30 "$OUT/configure.log"; exit 1; }
ninja -C "$BUILD" -j16 gpu_engine_tests structural_gpu_tests math_device_test test_physics_device fbar \
  > "$OUT/build.log" 2>&1 || { grep -E "error" -A3 "$OUT/build.log" | head -60; exit 1; }
(cd "$BUILD" && ctest -L gpu --output-on-failure --timeout 600 --output-junit gpu_junit.xml > "$OUT/ctest.log" 2>&1)
rc=$?
cp "$BUILD/gpu_junit.xml" "$OUT/" 2>/dev/null
grep -E "\[measured\]" "$OUT/ctest.log" > "$OUT/measured.txt"
record="$OUT/gpu-tests-$(date +%F)-$commit.md"
python3 - "$BUILD/gpu_junit.xml" "$commit" "$device" > "$record" <<'PY'
import sys
import xml.etree.ElementTree as ET
junit, commit, device = sys.argv[1:4]
cases = list(ET.parse(junit).getroot().iter("testcase"))
failed = [c.get("name") for c in cases if c.find("failure") is not None or c.get("status") == "fail"]
skipped = [c for c in cases if c.find("skipped") is not None]
passed = len(cases) - len(failed) - len(skipped)
print(f"# GPU test suite at {commit}\n\n- Device: {device}\n- Command: tools/benchmark/run_gpu_tests.sh (ctest -L gpu)")
print(f"- {len(cases)} tests: {passed} passed, {len(failed)} failed, {len(skipped)} skipped\n")
for name in failed:
    print(f"- failed: {name}")
for c in skipped:
    out = (c.findtext("system-out") or "").strip().splitlines()
    reason = next((l for l in out if "SKIPPED" in l or "skipped" in l or "no CUDA device" in l or "needs" in l), "")
    print(f"- skipped: {c.get('name')}: {reason.strip()}")
PY
cat "$record"
python3 "$ROOT/.ci/check_skips.py" "$BUILD/gpu_junit.xml" "$BUILD" --gpu-machine || rc=1
exit $rc
