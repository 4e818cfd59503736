#!/usr/bin/env bash
# fbar against Claymore GMPM (Wang et al. 2020) on the same GPU, reproducible from this repository: fetch Claymore at
# the commit the benchmark records name, build its GMPM for sm_90 with its own optimisation flags, and run the
# side-by-side box scenes one after the other, in rounds; the table gives ms per step and Claymore / fbar.
#
#   tools/benchmark/claymore_side_by_side.sh build WORK
#       git-clones penn-graphics-research/claymore (CLAYMORE_COMMIT) and wdas/partio (PARTIO_COMMIT) into WORK/src,
#       applies the measurement patches below and builds WORK/gmpm (about 10 minutes on 2 cores). Needs git, nvcc 12.4+,
#       g++ and the Debian / Ubuntu packages libfmt-dev libspdlog-dev libcxxopts-dev librange-v3-dev libglm-dev
#       rapidjson-dev zlib1g-dev (installed when missing and apt-get is usable). The binary links the CUDA runtime
#       statically: build on a machine without a GPU and copy WORK/gmpm to the GPU machine if you like.
#   tools/benchmark/claymore_side_by_side.sh run FBAR WORK [ROUNDS] [SCENES]
#       runs WORK/gmpm and FBAR (build/release/fbar) on each scene, ROUNDS times (default 2), interleaved; SCENES is a
#       comma list of jfluid_1m, jfluid_15m, fcr_15m (default all three). Writes WORK/run/<scene>/... and prints a
#       markdown table.
#
# The scenes (the same boxes for both programs): a box of 0.5 x 0.449 x 0.5 m (1M: 0.25 x 0.125 x 0.25 m) of 8
# particles per cell at dx = 1/256 m, falling at 1 m/s in a 1 m cube with walls, dt 5e-6 s; JFluid (K 4e4 Pa, gamma
# 7.15, viscosity 0.01) or FixedCorotated (E 1e7 Pa, nu 0.4); single precision. fbar's copies are
# tools/benchmark/scenes/claymore_box_*.json; Claymore's are written by `run` (its own scene format).
# Figure: wall-clock ms per step. Claymore: its frames 2 to the last (frame 1 includes its start-up), from the FRAME
# lines the patch prints; fbar: its last frame, from the difference of its progress lines' elapsed times.
#
# What the patches change in Claymore, for measurement only (the physics and kernels are upstream's):
#   settings.h         capacities 16M particles and 40,000 blocks (upstream's 1M and 10,000 do not hold 15M)
#   gmpm.cu            fopen_s -> std::fopen (an MSVC function); no getchar() before the run; a model with
#                      "file": "box" samples Claymore's own sample_uniform_box over offset / span (fractions of the
#                      domain); after the main loop: flush and exit (its teardown does not return)
#   gmpm_simulator.cuh a wall-clock timer around each frame (synchronised), printed as
#                      "FRAME f steps n wall_ms t ms_per_step t/n"; CLAYMORE_NO_DUMP=1 skips the frame's file output
#   CudaTimers.cuh     the per-kernel timer lines only with CLAYMORE_TIMERS=1 (printing them costs time)
#   qr.cuh             an unused overload that names an undeclared variable (nvcc 13 rejects it) is commented out
set -euo pipefail
CLAYMORE_COMMIT=${CLAYMORE_COMMIT:-3b19462f15892bd12291189e997f5b052784cf61}
PARTIO_COMMIT=${PARTIO_COMMIT:-cb91fd7}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
NVCC=${NVCC:-$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)}

fetch() {  # fetch URL COMMIT DIR (CLAYMORE_GIT / PARTIO_GIT may name a local clone or mirror instead of the URL)
  local url=$1 commit=$2 dir=$3
  rm -rf "$dir"
  git clone --quiet --no-checkout "$url" "$dir"
  # The sources only: its images and videos are not needed (and a partial mirror may lack them).
  git -C "$dir" sparse-checkout set --no-cone '/*' '!*.jpg' '!*.png' '!*.gif' '!*.mp4' '!*.pdf'
  git -C "$dir" checkout --quiet "$commit"
}

build() {
  local work=$1 src
  mkdir -p "$work"
  work=$(cd "$work" && pwd)
  src=$work/src
  if command -v apt-get > /dev/null; then
    local need=()
    for p in libfmt-dev libspdlog-dev libcxxopts-dev librange-v3-dev libglm-dev rapidjson-dev zlib1g-dev; do
      dpkg -s "$p" > /dev/null 2>&1 || need+=("$p")
    done
    if [ ${#need[@]} -gt 0 ]; then
      local sudo=; [ "$(id -u)" -ne 0 ] && sudo=sudo
      $sudo apt-get install -y "${need[@]}"
    fi
  fi
  fetch "${CLAYMORE_GIT:-https://github.com/penn-graphics-research/claymore.git}" "$CLAYMORE_COMMIT" "$src/claymore"
  fetch "${PARTIO_GIT:-https://github.com/wdas/partio.git}" "$PARTIO_COMMIT" "$src/partio"
  python3 - "$src/claymore" <<'PY'
import sys
root = sys.argv[1]
def edit(path, old, new, prepend=""):
    p = f"{root}/{path}"
    text = open(p).read()
    if old not in text:
        sys.exit(f"claymore_side_by_side.sh: {path} does not hold the expected text (another Claymore commit?): {old[:60]!r}")
    open(p, "w").write(prepend + text.replace(old, new, 1))
edit("Projects/GMPM/settings.h", "G_MAX_PARTICLE_NUM = 1000000;", "G_MAX_PARTICLE_NUM = 16000000;")
edit("Projects/GMPM/settings.h", "G_MAX_ACTIVE_BLOCK = 10000;", "G_MAX_ACTIVE_BLOCK = 40000;")
edit("Library/MnBase/Math/Matrix/qr.cuh", "rotation.fill<2>(R);", "/* unused overload (undeclared R): rotation.fill<2>(R); */")
edit("Library/MnBase/Profile/CudaTimers.cuh", "\tvoid tock(std::string tag) {\n\t\ttock();\n",
     "\tvoid tock(std::string tag) {\n\t\tif(std::getenv(\"CLAYMORE_TIMERS\") == nullptr) return;\n\t\ttock();\n",
     prepend="#include <cstdlib>\n")
g = "Projects/GMPM/gmpm.cu"
edit(g, "fopen_s(&f, (addr_str + filename).c_str(), \"rb\");", "f = std::fopen((addr_str + filename).c_str(), \"rb\");")
edit(g, "\tgetchar();\n", "")
edit(g, "\tbenchmark->main_loop();\n", "\tbenchmark->main_loop();\n\tmn::IO::flush();\n\tstd::fflush(stdout);\n\tstd::_Exit(0);\n")
edit(g, "if(p.extension() == \".sdf\") {",
     "if(std::string(model[\"file\"].GetString()) == \"box\") {\n"
     "\t\t\t\t\t\t\tmn::ivec3 lo, hi;\n"
     "\t\t\t\t\t\t\tfor(int d = 0; d < 3; ++d) {\n"
     "\t\t\t\t\t\t\t\tlo[d] = static_cast<int>(std::lround(offset[d] * mn::config::G_DOMAIN_SIZE));\n"
     "\t\t\t\t\t\t\t\thi[d] = static_cast<int>(std::lround((offset[d] + span[d]) * mn::config::G_DOMAIN_SIZE));\n"
     "\t\t\t\t\t\t\t}\n"
     "\t\t\t\t\t\t\tauto positions = mn::sample_uniform_box(mn::config::G_DX, lo, hi);\n"
     "\t\t\t\t\t\t\tstd::printf(\"box: %zu particles\\n\", positions.size());\n"
     "\t\t\t\t\t\t\tinit_model(positions, velocity);\n"
     "\t\t\t\t\t\t} else if(p.extension() == \".sdf\") {",
     prepend="#include <cmath>\n#include <cstdio>\n#include <cstdlib>\n")
m = "Projects/GMPM/gmpm_simulator.cuh"
edit(m, "\t\t\tconst Duration next_time = cur_time + seconds_per_frame;\n",
     "\t\t\tconst Duration next_time = cur_time + seconds_per_frame;\n"
     "\t\t\tcudaDeviceSynchronize();\n"
     "\t\t\tconst auto frame_start = std::chrono::steady_clock::now();\n"
     "\t\t\tconst auto frame_first_step = cur_step;\n")
edit(m, "\t\t\tIO::flush();\n\t\t\toutput_model();\n",
     "\t\t\tcudaDeviceSynchronize();\n"
     "\t\t\t{\n"
     "\t\t\t\tconst double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - frame_start).count();\n"
     "\t\t\t\tconst auto steps = cur_step - frame_first_step;\n"
     "\t\t\t\tstd::printf(\"FRAME %d steps %d wall_ms %.3f ms_per_step %.5f\\n\", static_cast<int>(cur_frame), static_cast<int>(steps), ms, ms / static_cast<double>(steps));\n"
     "\t\t\t\tstd::fflush(stdout);\n"
     "\t\t\t}\n"
     "\t\t\tIO::flush();\n"
     "\t\t\tif(std::getenv(\"CLAYMORE_NO_DUMP\") == nullptr) output_model();\n",
     prepend="#include <chrono>\n#include <cstdio>\n#include <cstdlib>\n")
PY
  local b=$work/obj c=$src/claymore p=$src/partio/src/lib
  rm -rf "$b" && mkdir -p "$b"
  local inc=(-I"$c/Library" -I"$c/Externals/variant" -I"$c/Externals/optional" -I"$c/Externals/function_ref" -I"$p"
             -I"$c/Projects/GMPM")
  # Claymore's own CUDA flags (CMake-Utils/setup_cuda.cmake), for sm_90.
  local cuda=("$NVCC" -std=c++17 -O3 --expt-extended-lambda --expt-relaxed-constexpr --default-stream=per-thread
              -gencode arch=compute_90,code=sm_90 -DFMT_HEADER_ONLY -Xcompiler -w)
  "${cuda[@]}" --use_fast_math -lineinfo --ptxas-options=-allow-expensive-optimizations=true "${inc[@]}" \
    '-DAssetDirPath="./Data/"' -c "$c/Projects/GMPM/gmpm.cu" -o "$b/gmpm.o"
  for f in Cuda DeviceUtils MemoryUtils; do "${cuda[@]}" "${inc[@]}" -c "$c/Library/MnSystem/Cuda/$f.cu" -o "$b/$f.o"; done
  g++ -std=c++20 -O2 -w -DFMT_HEADER_ONLY "${inc[@]}" -c "$c/Library/MnSystem/IO/IO.cpp" -o "$b/IO.o"
  for f in "$p"/core/*.cpp "$p"/io/*.cpp; do
    g++ -O2 -w -DPARTIO_USE_ZLIB -I"$p" -c "$f" -o "$b/partio_$(basename "$f" .cpp).o"
  done
  "$NVCC" -o "$work/gmpm" "$b"/*.o -gencode arch=compute_90,code=sm_90 --cudart=static -lz -lpthread
  echo "built $work/gmpm (claymore $CLAYMORE_COMMIT, partio $PARTIO_COMMIT)"
}

claymore_scene() {  # claymore_scene NAME OUT: the box of tools/benchmark/scenes/claymore_box_NAME.json, as Claymore reads it
  python3 - "$ROOT/tools/benchmark/scenes/claymore_box_$1.json" "$2" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
b = s["bodies"][0]
g = b["geometry"][0]
m = b["material"]
law = {"JFluid": "jfluid", "FixedCorotated": "fixed_corotated"}[m["constitutive"]]
model = {"type": "particle", "file": "box", "constitutive": law, "rho": m["rho"],
         "volume": s["simulation"]["default_dx"] ** 3 / m["ppc"],
         "offset": g["offset"], "span": g["span"], "velocity": b["velocity"]}
for k in ("bulk_modulus", "gamma", "viscosity", "youngs_modulus", "poisson_ratio"):
    if k in m:
        model[k] = m[k]
# Claymore's frames of 1/1200 s (167 steps of 5e-6 s): as many steps in all as fbar's frames.
steps = round(s["simulation"]["frames"] / s["simulation"]["fps"] / s["simulation"]["default_dt"])
json.dump({"simulation": {"gpuid": 0, "fps": 1200, "frames": max(3, round(steps / 167)),
                          "default_dt": s["simulation"]["default_dt"]}, "models": [model]}, open(sys.argv[2], "w"), indent=1)
PY
}

run() {
  local fbar work rounds=${3:-2} scenes=${4:-jfluid_1m,jfluid_15m,fcr_15m}
  fbar=$(realpath "$1"); work=$(cd "$2" && pwd)
  [ -x "$work/gmpm" ] || { echo "no $work/gmpm: run '$0 build $2' first" >&2; exit 1; }
  local table=$work/run/side_by_side.md
  mkdir -p "$work/run"
  {
    echo "| scene | round | Claymore ms/step | fbar ms/step | Claymore / fbar |"
    echo "| --- | --- | --- | --- | --- |"
  } > "$table"
  for r in $(seq 1 "$rounds"); do
    for name in ${scenes//,/ }; do
      local d=$work/run/$name/$r
      rm -rf "$d" && mkdir -p "$d/claymore" "$d/fbar"
      claymore_scene "$name" "$d/claymore/scene.json"
      (cd "$d/claymore" && CLAYMORE_NO_DUMP=1 "$work/gmpm" --file=scene.json > log.txt 2>&1)
      local cm
      # (Claymore colours its output: the escape sequences go first.)
      cm=$(sed 's/\x1b\[[0-9;]*m//g' "$d/claymore/log.txt" |
           awk '$1 == "FRAME" && $2 > 1 { ms += $6; n += $4 } END { if (n > 0) printf "%.4f", ms / n }')
      "$fbar" --file="$ROOT/tools/benchmark/scenes/claymore_box_$name.json" --output="$d/fbar" > "$d/fbar/log.txt" 2>&1
      local fb
      fb=$(python3 - "$d/fbar/log.txt" <<'PY'
import re, sys
# Progress lines "frame f/F  t = ...  steps = s  ...  x ms/step": x is the mean over the run so far, so s x is the
# elapsed time at frame f; the last frame's ms per step is the difference of the last two.
rows = []
for line in open(sys.argv[1]):
    m = re.search(r"frame (\d+)/\d+ .*steps = (\d+) .* ([0-9.eE+-]+) ms/step", line)
    if m:
        rows.append((int(m.group(2)), float(m.group(3))))
if len(rows) >= 2:
    (s0, x0), (s1, x1) = rows[-2], rows[-1]
    print(f"{(s1 * x1 - s0 * x0) / (s1 - s0):.4f}")
PY
)
      local ratio=-
      [ -n "$cm" ] && [ -n "$fb" ] && ratio=$(python3 -c "print(f'{$cm / $fb:.2f}')")
      echo "| $name | $r | ${cm:-failed} | ${fb:-failed} | $ratio |" >> "$table"
    done
  done
  cat "$table"
}

case "${1:-}" in
  build) build "${2:?usage: $0 build WORK}" ;;
  run) run "${2:?usage: $0 run FBAR WORK [ROUNDS] [SCENES]}" "${3:?usage: $0 run FBAR WORK [ROUNDS] [SCENES]}" "${4:-2}" "${5:-}" ;;
  *) sed -n 2,34p "$0"; exit 2 ;;
esac
