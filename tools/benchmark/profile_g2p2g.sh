#!/usr/bin/env bash
# Nsight Compute profile of one G2P2G launch (4M-particle dam break, single) -> $OUT/ncu_g2p2g.txt, key lines printed.
#   tools/benchmark/profile_g2p2g.sh <build dir>
set -uo pipefail
OUT=${OUT:-$PWD/out}
BUILD=${1:-build/device}
ncu --kernel-name regex:g2p2g --launch-skip 40 --launch-count 1 \
    --section SpeedOfLight --section MemoryWorkloadAnalysis --section ComputeWorkloadAnalysis \
    --section Occupancy --section WarpStateStats --section SchedulerStats --section LaunchStats \
    "$BUILD/fbar_benchmark" --sizes=4 --precisions=single --scenes=dam_break --steps=20 --warmup=5 \
    --csv=/tmp/ncu_bench.csv > "$OUT/ncu_g2p2g.txt" 2>&1
grep -E "Duration|Throughput|Achieved Occupancy|Theoretical Occupancy|Registers Per|Stall|Warp Cycles|Issued Ipc|Eligible|No Eligible|Bank|L1/TEX Hit|L2 Hit|Mem Busy|Max Bandwidth|Block Limit" \
  "$OUT/ncu_g2p2g.txt" | head -70
