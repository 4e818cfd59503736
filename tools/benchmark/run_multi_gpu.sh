#!/usr/bin/env bash
# The multi-GPU checks and scaling on a machine with 2 or more GPUs (two GPUs: the decomposition's correctness and
# 2-GPU scaling; four: the same on 4 GPUs). Uses the binaries in BIN (default build/release) and writes logs to $OUT
# (or ./out); prints a short table last.
#   tools/benchmark/run_multi_gpu.sh                  every stage the visible GPUs allow
#   STAGES="two four" STRONG2=32 STRONG4=64 WEAK=16 STEPS=50 tools/benchmark/run_multi_gpu.sh
# Stages (each skipped when fewer GPUs are visible than it needs):
#   suite  the one-GPU suite (gpu_engine_tests, SUITE_FILTER or every test) on the LAST visible GPU, in the background while "two"
#          runs its correctness checks on the first two (no timing runs meanwhile)
#   two    on the first 2 GPUs: the decomposition tests (NCCL ones included, one rank per GPU as threads); the MPI
#          check with 2 processes, with NCCL's default transports and again with its peer-to-peer and shared-memory
#          transports off (the network path, as between nodes); the command line (--gpus=1|2|3 and mpirun -np 2
#          against one rank, by particle ID)
#   scale2 on the first 2 GPUs: fbar_scaling strong STRONG2 M and weak WEAK M per GPU on 1 and 2 GPUs (threads), then
#          under mpirun -np 2
#   four   on 4 GPUs: the NCCL decomposition tests on 4 GPUs (a body over all four, particles crossing three cuts),
#          the MPI check with 4 processes on the network path, fbar_scaling strong STRONG4 M and weak WEAK M per GPU
#          on 1, 2 and 4 GPUs (threads), then under mpirun -np 4 (the MPI runs with fbar's default, the overlap off)
set -uo pipefail
OUT=${OUT:-$PWD/out}
mkdir -p "$OUT"
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BIN=${BIN:-$ROOT/build/release}
STAGES=${STAGES:-suite two scale2 four}
export NCCL_NVLS_ENABLE=0  # NVLink multicast off: the shared hosts require it
MPI=(mpirun --allow-run-as-root --oversubscribe -x NCCL_NVLS_ENABLE -x CUDA_VISIBLE_DEVICES)
NET=(-x NCCL_P2P_DISABLE=1 -x NCCL_SHM_DISABLE=1)
nvidia-smi -L | tee "$OUT/gpus.txt"
GPUS=$(grep -c "^GPU " "$OUT/gpus.txt")
find_bin() { for d in "$BIN" "$BIN/tests/engine/gpu" "$BIN/tools/benchmark"; do [ -x "$d/$1" ] && { echo "$d/$1"; return; }; done; echo "$1"; }
TESTS=$(find_bin gpu_engine_tests); CHECK=$(find_bin gpu_mpi_decomposition_check); SCALING=$(find_bin fbar_scaling)
FBAR=$(find_bin fbar)
STEPS=${STEPS:-50}
summary() { echo "$1" | tee -a "$OUT/summary.txt"; }
has() { [[ " $STAGES " == *" $1 "* ]]; }
# scaling GPUS RANKS STRONG NAME: fbar_scaling on the visible GPUs as threads (every listed rank count, the halo
# overlap on and off), then under mpirun with one process per GPU (fbar's default, the overlap off).
scaling() {
  timeout 300 "$SCALING" --ranks="$2" --strong="$3" --weak="${WEAK:-16}" --steps="$STEPS" \
    --csv="$OUT/scaling_$4.csv" > "$OUT/scaling_$4.log" 2>&1
  summary "$1 GPUs: scaling (threads) rc=$?"
  timeout 200 "${MPI[@]}" -np "$1" "$SCALING" --strong="$3" --weak="${WEAK:-16}" --steps="$STEPS" \
    --overlap=off --csv="$OUT/scaling_$4_mpi.csv" >> "$OUT/scaling_$4.log" 2>&1
  summary "$1 GPUs: scaling (mpirun -np $1) rc=$?"
}

suite_pid=
if has suite && [ "$GPUS" -ge 3 ]; then
  (CUDA_VISIBLE_DEVICES=$((GPUS - 1)) timeout "${SUITE_TIMEOUT:-540}" "$TESTS" --gtest_filter="${SUITE_FILTER:-*}" > "$OUT/suite.log" 2>&1; echo "$?" > "$OUT/suite.rc") &
  suite_pid=$!
fi

if has two && [ "$GPUS" -ge 2 ]; then
  export CUDA_VISIBLE_DEVICES=0,1
  timeout 400 "$TESTS" --gtest_filter='GpuDecomposition.*' > "$OUT/two_tests.log" 2>&1
  summary "2 GPUs: decomposition tests (threads; NCCL on 2 GPUs) rc=$?"
  timeout 200 "${MPI[@]}" -np 2 "$CHECK" > "$OUT/two_mpi.log" 2>&1
  summary "2 GPUs: MPI check, NCCL default transports rc=$?"
  timeout 200 "${MPI[@]}" -np 2 "${NET[@]}" "$CHECK" >> "$OUT/two_mpi.log" 2>&1
  summary "2 GPUs: MPI check, P2P and SHM off (network path) rc=$?"
  timeout 400 python3 "$ROOT/tests/engine/gpu/gpu_cli_ranks_test.py" "$FBAR" mpirun \
    "$ROOT/tests/scenes/good/decomposed_dam_break.json" /tmp/fbar_gpu_cli_ranks >> "$OUT/two_tests.log" 2>&1
  summary "2 GPUs: command line --gpus=1|2|3 and mpirun -np 2 against one rank rc=$?"
  unset CUDA_VISIBLE_DEVICES
fi
[ -n "$suite_pid" ] && { wait "$suite_pid"; summary "1 GPU: gpu_engine_tests rc=$(cat "$OUT/suite.rc")"; }

if has scale2 && [ "$GPUS" -ge 2 ]; then
  export CUDA_VISIBLE_DEVICES=0,1
  scaling 2 1,2 "${STRONG2:-32}" two
  unset CUDA_VISIBLE_DEVICES
fi

if has four && [ "$GPUS" -ge 4 ]; then
  export CUDA_VISIBLE_DEVICES=0,1,2,3
  timeout 300 "$TESTS" --gtest_filter='GpuDecomposition.Nccl*' > "$OUT/four_tests.log" 2>&1
  summary "4 GPUs: NCCL decomposition tests (threads) rc=$?"
  timeout 200 "${MPI[@]}" -np 4 "${NET[@]}" "$CHECK" > "$OUT/four_mpi.log" 2>&1
  summary "4 GPUs: MPI check, 4 processes, P2P and SHM off (network path) rc=$?"
  scaling 4 1,2,4 "${STRONG4:-64}" four
  unset CUDA_VISIBLE_DEVICES
fi

for f in suite.log two_tests.log four_tests.log; do
  [ -f "$OUT/$f" ] && { echo "== $f"; grep -E "GPU ranks|MPI ranks|^(gpus|mpi)[0-9]|tests? ran|PASSED|FAILED|SKIPPED \]" "$OUT/$f" | tail -25; }
done
for f in two_mpi.log four_mpi.log; do [ -f "$OUT/$f" ] && { echo "== $f"; grep -vE "^\s*$" "$OUT/$f" | tail -8; }; done
for f in scaling_two.log scaling_four.log; do [ -f "$OUT/$f" ] && { echo "== $f"; cat "$OUT/$f"; }; done
echo "== summary"
cat "$OUT/summary.txt"
