#!/usr/bin/env bash
# ClaymoreUW's own scene files on fbar's GPU engine: --check of each, a short run of the ones that pass, and the
# checkpoint pair (Create to frame 22, Resume from its frame 20, compared by particle ID).
# usage: tools/benchmark/run_claymoreuw_scenes.sh FBAR SCENES_DIR [WORK_DIR]
#   SCENES_DIR holds ClaymoreUW's Projects/OSU_LWF/scene*.json (not shipped with fbar); the pair is looked up as
#   *CreateCheckpoint*.json and *ResumeCheckpoint*.json. Prints one line per scene, then the pair's comparison.
set -u
FBAR=$(realpath "$1"); SCENES=$(realpath "$2"); WORK=${3:-/tmp/fbar_claymoreuw}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
rm -rf "$WORK"; mkdir -p "$WORK/run" "$WORK/checkpoint"
cp "$SCENES"/*.json "$WORK/run/"
cd "$WORK/run"
for f in *.json; do
  if "$FBAR" --check "$f" > "$WORK/${f%.json}.check" 2>&1; then
    case "$f" in *Checkpoint*) echo "$f: --check passes"; continue;; esac
    s0=$SECONDS
    "$FBAR" --backend=gpu --quiet --file="$f" --output="$WORK/${f%.json}" --frames=2 > "$WORK/${f%.json}.log" 2>&1
    echo "$f: --check passes; 2 frames rc=$? in $((SECONDS - s0)) s"
  else
    echo "$f: --check: $(grep -m1 'error' "$WORK/${f%.json}.check")"
  fi
done
create=$(ls *CreateCheckpoint*.json 2>/dev/null | head -1); resume=$(ls *ResumeCheckpoint*.json 2>/dev/null | head -1)
[ -n "$create" ] && [ -n "$resume" ] || exit 0
"$FBAR" --backend=gpu --quiet --file="$create" --output="$WORK/create" --frames=22 || exit 1
cp "$WORK/create/model[0]_dev[0]_frame[20].bgeo" "$WORK/checkpoint/"
"$FBAR" --backend=gpu --quiet --file="$resume" --output="$WORK/resume" --frames=2 || exit 1
python3 - "$ROOT" "$WORK" <<'PY'
import sys
sys.path.insert(0, sys.argv[1] + "/tools/plot")
from fbar_frames import read_frame
import numpy as np
work = sys.argv[2]
for k in (0, 1, 2):
    a = read_frame(f"{work}/create/model[0]_dev[0]_frame[{20 + k}].bgeo")
    b = read_frame(f"{work}/resume/model[0]_dev[0]_frame[{k}].bgeo")
    ia, ib = np.argsort(a["ID"].ravel()), np.argsort(b["ID"].ravel())
    if len(ia) != len(ib):
        print(f"resume frame {k}: {len(ib)} water particles, create frame {20 + k}: {len(ia)}"); continue
    d = np.abs(a["P"][ia] - b["P"][ib])
    print(f"resume frame {k} vs create frame {20 + k}: {len(ia)} water particles, max |dx| {d.max():.3g} m, "
          f"rms {np.sqrt((d ** 2).mean()):.3g} m")
PY
