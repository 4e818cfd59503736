#!/usr/bin/env bash
# Side by side with ClaymoreUW on the same GPU: each scene file run by ClaymoreUW's osu_lwf (built outside the
# repository) and by fbar, one after the other, for the same simulated time; then one table per scene: particles per
# body (frame 0) and, per sensor file both wrote, both means, the RMS difference and the correlation over common times.
# fbar runs a copy of the scene whose sensors of each kind all sample at the last one's rate, which is what ClaymoreUW
# does (it keeps one rate per kind); fbar on its own samples each sensor at its own rate (user guide §7 item 24).
# usage: tools/benchmark/compare_claymoreuw.sh OSU_LWF FBAR WORK SCENE.json[:SECONDS] ...
#   OSU_LWF  ClaymoreUW's binary (it runs in the scene's folder, writes there and never exits: it is stopped once its
#            last frame file exists, or after CUW_WALL_PER_SECOND (default 80) x the simulated time in seconds (+60 s) of
#            wall time)
#   SECONDS  simulated time to run (default 1); frames = ceil(SECONDS x fps) for both
#   Motion files a scene names are looked up beside the scene file and copied next to it and one folder up; geometry
#   files are copied to the same path relative to the run folder as to the scene (both programs resume from one file).
# Prints the tables (markdown) and writes WORK/<scene>/{cuw,fbar}/... and WORK/compare.md.
set -u
CUW=$(realpath "$1"); FBAR=$(realpath "$2"); WORK=$3; shift 3
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$WORK"
: > "$WORK/compare.md"
for arg in "$@"; do
  scene=${arg%%:*}; secs=1; [ "$scene" != "$arg" ] && secs=${arg#*:}
  name=$(basename "$scene" .json); dir="$WORK/$name"
  rm -rf "$dir"; mkdir -p "$dir/cuw/run" "$dir/fbar"
  # The scene with frames set to cover `secs` (the only key changed), and the files it names.
  frames=$(python3 - "$scene" "$secs" "$dir/cuw/run/scene.json" <<'PY'
import json, math, sys, shutil, os
s = json.load(open(sys.argv[1])); secs = float(sys.argv[2])
fps = s["simulation"].get("fps", 60)
s["simulation"]["frames"] = max(1, math.ceil(secs * fps - 1e-9))
json.dump(s, open(sys.argv[3], "w"), indent=1)
# fbar's copy samples as ClaymoreUW does: every sensor of a kind at the last one's rate (host_gt_freq, host_pt_freq),
# so that both files hold the same instants and their means compare.
for kind in ("grid-sensors", "particle-sensors"):
    sensors = s.get(kind, [])
    if sensors:
        last = sensors[-1].get("output_frequency", sensors[-1].get("output_freq", 60))
        for t in sensors:
            t.pop("output_freq", None); t["output_frequency"] = last
json.dump(s, open(os.path.join(os.path.dirname(sys.argv[3]), "fbar_scene.json"), "w"), indent=1)
src = os.path.dirname(os.path.abspath(sys.argv[1])); run = os.path.dirname(sys.argv[3])
for b in s.get("boundaries", []) + s.get("grid-boundaries", []):
    f = b.get("file")
    if f:
        p = os.path.join(src, os.path.basename(f))
        for d in (run, os.path.dirname(run)):
            if os.path.exists(p): shutil.copy(p, d)
# Geometry files (a ResumeCheckpoint scene's ../checkpoint/...bgeo) at the same place relative to the run folder.
for b in s.get("bodies", []) + s.get("models", []):
    for g in b.get("geometry", []) + [b]:
        f = g.get("file") if isinstance(g, dict) else None
        if f and os.path.exists(os.path.join(src, f)):
            dst = os.path.normpath(os.path.join(run, f)); os.makedirs(os.path.dirname(dst), exist_ok=True)
            shutil.copy(os.path.join(src, f), dst)
print(s["simulation"]["frames"])
PY
)
  last="model[0]_dev[0]_frame[$frames].bgeo"
  ( cd "$dir/cuw/run" && s0=$(date +%s.%N)
    "$CUW" --file=scene.json > ../log.txt 2>&1 & pid=$!
    limit=$(python3 -c "print(int(${CUW_WALL_PER_SECOND:-80} * $secs + 60))"); t=0
    while [ ! -f "$last" ] && kill -0 $pid 2>/dev/null && [ $t -lt $((limit * 10)) ]; do sleep 0.1; t=$((t + 1)); done
    sleep 1; kill $pid 2>/dev/null; wait $pid 2>/dev/null
    echo "wall $(python3 -c "import time; print(round(time.time() - $s0, 1))") s" > ../time.txt )
  ( cd "$dir/cuw/run" && s0=$(date +%s.%N)
    "$FBAR" --check --file=fbar_scene.json > "$dir/fbar/check.txt" 2>&1
    "$FBAR" --backend=gpu --quiet --file=fbar_scene.json --output="$dir/fbar" > "$dir/fbar/log.txt" 2>&1
    echo "rc $? wall $(python3 -c "import time; print(round(time.time() - $s0, 1))") s" > "$dir/fbar/time.txt" )
  python3 - "$ROOT" "$dir" "$name" "$secs" >> "$WORK/compare.md" <<'PY'
import sys, os, glob, csv
import numpy as np
sys.path.insert(0, sys.argv[1] + "/tools/plot")
from fbar_frames import read_frame
d, name, secs = sys.argv[2], sys.argv[3], float(sys.argv[4])
cuw, fb = d + "/cuw/run", d + "/fbar"
import json
sim = json.load(open(cuw + "/scene.json"))["simulation"]
t0 = float(sim.get("time", sim.get("initial_time", 0.0)))  # a resumed run starts at its time
print(f"\n### {name} (first {secs:g} s)\n")
print(f"ClaymoreUW: {open(d + '/cuw/time.txt').read().strip()}; fbar: {open(fb + '/time.txt').read().strip()}\n")
print("| body | particles ClaymoreUW | particles fbar |\n| --- | --- | --- |")
import re
cuw_counts = {}  # ClaymoreUW's log: "GPU[0] MODEL[m] Particle Count[N]" (its bgeo frames carry a header partio adds)
for line in open(d + "/cuw/log.txt", errors="replace"):
    for m, n in re.findall(r"MODEL\[(\d+)\] Particle Count\[(\d+)\]", line):
        cuw_counts.setdefault(int(m), int(n))
    for m, n in re.findall(r"MODEL\[(\d+)\] Initialized device array with \[(\d+)\] particles", line):
        cuw_counts.setdefault(int(m), int(n))
# fbar's bodies in order from --check ("particles  N (volume ..."): frames may hold the exterior particles only.
fb_counts = [int(m) for m in re.findall(r"^\s*particles\s+(\d+) \(", open(fb + "/check.txt").read(), re.M)] \
    if os.path.exists(fb + "/check.txt") else []
for m in range(max(len(fb_counts), max(cuw_counts, default=-1) + 1)):
    print(f"| {m} | {cuw_counts.get(m, '-')} | {fb_counts[m] if m < len(fb_counts) else '-'} |")
def series(p):
    t, v = [], []
    with open(p) as f:
        r = csv.reader(f); next(r, None)
        for row in r:
            try: t.append(float(row[0])); v.append(float(row[1]))
            except (ValueError, IndexError): pass
    return np.array(t), np.array(v)
print("\n| file | samples | mean ClaymoreUW | mean fbar | RMS difference | correlation |\n| --- | --- | --- | --- | --- | --- |")
for a in sorted(glob.glob(cuw + "/gridTarget*.csv") + glob.glob(cuw + "/particleTarget*.csv")):
    f = os.path.basename(a); b = fb + "/" + f
    if not os.path.exists(b): print(f"| {f} | fbar wrote none | | | | |"); continue
    ta, va = series(a); tb, vb = series(b)
    keep = (ta <= t0 + secs + 1e-9) & np.isfinite(va)
    ta, va = ta[keep], va[keep]
    if len(ta) < 2 or len(tb) < 2: print(f"| {f} | {len(ta)} / {len(tb)} | | | | |"); continue
    vbi = np.interp(ta, tb, vb)  # fbar's samples at ClaymoreUW's times (ClaymoreUW writes step-end times)
    ok = np.isfinite(vbi)
    c = np.corrcoef(va[ok], vbi[ok])[0, 1] if np.std(va[ok]) > 0 and np.std(vbi[ok]) > 0 else float("nan")
    print(f"| {f} | {ok.sum()} | {va[ok].mean():.5g} | {vbi[ok].mean():.5g} | "
          f"{np.sqrt(np.mean((va[ok] - vbi[ok]) ** 2)):.4g} | {c:.3f} |")
PY
done
cat "$WORK/compare.md"
