#!/usr/bin/env bash
# The multi-GPU checks and scaling of issue 10 on a machine with 2 (or more) GPUs, e.g. nvidia-h200-x2. Uses the
# binaries in BIN (default build/release) and writes logs to $OUT (or ./out); prints a short table last.
#   tools/benchmark/run_multi_gpu.sh            (STRONG=32 WEAK=16 STEPS=50: sizes in millions of particles)
# 1. the decomposition tests, NCCL ones included (one rank per visible GPU, threads)
# 2. the MPI check: 2 processes, NCCL; then again with NCCL's peer-to-peer and shared-memory transports off, so
#    the network path (sockets / IB) runs as between nodes
# 3. the command line: --gpus=1|2|3 and mpirun -np 2 fbar --backend=gpu against one rank, by particle ID
# 4. fbar_scaling: strong (STRONG M on 1 and 2 GPUs) and weak (WEAK M per GPU), threads; then the same under mpirun
set -uo pipefail
OUT=${OUT:-$PWD/out}
mkdir -p "$OUT"
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BIN=${BIN:-$ROOT/build/release}
export NCCL_NVLS_ENABLE=0  # NVLink multicast off: the shared hosts require it
MPIRUN=(mpirun --allow-run-as-root --oversubscribe -np 2 -x NCCL_NVLS_ENABLE)
nvidia-smi -L | tee "$OUT/gpus.txt"
find_bin() { for d in "$BIN" "$BIN/tests/gpu_engine"; do [ -x "$d/$1" ] && { echo "$d/$1"; return; }; done; echo "$1"; }
TESTS=$(find_bin gpu_engine_tests); CHECK=$(find_bin gpu_mpi_decomposition_check); SCALING=$(find_bin fbar_scaling)
timeout 500 "$TESTS" --gtest_filter='GpuDecomposition.*' > "$OUT/decomposition_tests.log" 2>&1
echo "decomposition tests rc=$?" | tee -a "$OUT/summary.txt"
timeout 300 "${MPIRUN[@]}" "$CHECK" > "$OUT/mpi_check.log" 2>&1
echo "MPI check (NCCL default transports) rc=$?" | tee -a "$OUT/summary.txt"
NCCL_P2P_DISABLE=1 NCCL_SHM_DISABLE=1 timeout 300 "${MPIRUN[@]}" -x NCCL_P2P_DISABLE -x NCCL_SHM_DISABLE "$CHECK" \
  > "$OUT/mpi_check_net.log" 2>&1
echo "MPI check (P2P and SHM off: network path) rc=$?" | tee -a "$OUT/summary.txt"
FBAR=$(find_bin fbar)
timeout 600 python3 "$ROOT/tests/gpu_engine/gpu_cli_ranks_test.py" "$FBAR" mpirun \
  "$ROOT/tests/scenes/good/decomposed_dam_break.json" /tmp/fbar_gpu_cli_ranks > "$OUT/cli_ranks.log" 2>&1
echo "command line --gpus=1|2|3 and mpirun -np 2 rc=$?" | tee -a "$OUT/summary.txt"
timeout 600 "$SCALING" --ranks=1,2 --strong="${STRONG:-32}" --weak="${WEAK:-16}" --steps="${STEPS:-50}" \
  --csv="$OUT/scaling_threads.csv" > "$OUT/scaling_threads.log" 2>&1
timeout 300 "${MPIRUN[@]}" "$SCALING" --strong="${STRONG:-32}" --weak="${WEAK:-16}" --steps="${STEPS:-50}" \
  --csv="$OUT/scaling_mpi.csv" > "$OUT/scaling_mpi.log" 2>&1
grep -E "GPU ranks|OK \]|FAILED|SKIPPED" "$OUT/decomposition_tests.log" | tail -20
grep -h "MPI ranks" "$OUT/mpi_check.log" "$OUT/mpi_check_net.log"
cat "$OUT/cli_ranks.log" "$OUT/scaling_threads.log" "$OUT/scaling_mpi.log"
cat "$OUT/summary.txt"
