#!/usr/bin/env bash
# Large-scene runs of the fbar command line on a GPU machine: per scene the progress log, device memory sampled by
# nvidia-smi (peak), the host process's peak resident memory, and the run's wall time. Logs go to $OUT.
#   tools/benchmark/run_scale.sh BUILD_DIR scene.json [scene.json ...]
set -uo pipefail
OUT=${OUT:-$PWD/out}
mkdir -p "$OUT"
BUILD=$1; shift
summary="$OUT/scale_summary.txt"
printf "%-28s %6s %12s %12s %10s %s\n" scene rc dev_peak_MiB host_peak_MiB wall_ms last_progress >> "$summary"
for scene in "$@"; do
  name=$(basename "$scene" .json)
  outdir=/tmp/fbar_scale_$name
  rm -rf "$outdir"
  nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 200 > "$OUT/$name.smi" 2>/dev/null &
  smi=$!
  start=$(date +%s%N)
  "$BUILD/fbar" --file="$scene" --output="$outdir" > "$OUT/$name.log" 2>&1 &
  pid=$!
  hwm=0
  while kill -0 $pid 2>/dev/null; do
    h=$(awk '/VmHWM/ {print $2}' /proc/$pid/status 2>/dev/null)
    [ -n "$h" ] && hwm=$h
    sleep 0.5
  done
  wait $pid; rc=$?
  wall=$(( ($(date +%s%N) - start) / 1000000 ))
  kill $smi 2>/dev/null
  peak=$(sort -n "$OUT/$name.smi" | tail -1)
  last=$(grep -E "^frame|error" "$OUT/$name.log" | tail -1)
  printf "%-28s %6s %12s %12s %10s %s\n" "$name" "$rc" "$peak" "$((hwm / 1024))" "$wall" "$last" >> "$summary"
  rm -rf "$outdir"
done
cat "$summary"
