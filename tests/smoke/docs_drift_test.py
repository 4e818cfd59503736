#!/usr/bin/env python3
"""The user guide against the program it describes (ctest Docs.GuideMatchesTheProgram).

usage: docs_drift_test.py FBAR SOURCE_DIR WORKDIR

- The command-line table of docs/user_guide.md §1 lists exactly the options `fbar --help` prints (each `--name`).
- Every error message the guide quotes as the program's (a backticked `fbar: error: ...` or `<path>: got ...;
  expected ...` line in docs/user_guide.md, docs/first_scene.md, README.md) is printed by the program: the quoted
  messages of bad scenes come from tests/scenes/bad/expectations.txt (the corpus the command-line tests run), and a
  message the guide quotes must match one of them, or one this script produces by running fbar (listed below), with
  its variable parts (numbers, paths) free.
- `--check`'s throughput label names the GPU and the date of the record the figures come from, and that record
  exists under docs/benchmarks/.
A quoted message, option or figure that the program no longer prints fails here, naming the file and line.
"""
import glob
import json
import os
import re
import shutil
import subprocess
import sys

fbar, source, work = (os.path.abspath(a) for a in sys.argv[1:4])
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
failures = []


def read(path):
    with open(os.path.join(source, path)) as f:
        return f.read()


# 1. Options: the guide's table against --help.
help_text = subprocess.run([fbar, "--help"], capture_output=True, text=True).stdout
program_options = set(re.findall(r"^\s+(?:-\w(?: \w+)?, )?(--[a-z][a-z-]*)", help_text, re.M))
guide = read("docs/user_guide.md")
section = guide[guide.index("## 1. Command line"):]
section = section[:section.index("\n## ", 10)]
table = [line for line in section.splitlines() if line.startswith("| `")]
guide_options = set()
for line in table:
    first_cell = line.split("|")[1]
    guide_options.update(re.findall(r"(--[a-z][a-z-]*)", first_cell))
for o in sorted(program_options - guide_options):
    failures.append(f"docs/user_guide.md §1: `fbar --help` lists {o}, the option table does not")
for o in sorted(guide_options - program_options):
    failures.append(f"docs/user_guide.md §1: the option table lists {o}, `fbar --help` does not")

# 2. Quoted messages. The program's messages: every bad scene's (`fbar --check` on tests/scenes/bad), and the runs
# below; a message no run here can produce (a build without NCCL, say) must be in the sources, its fixed text whole.
def run(args, cwd=work):
    p = subprocess.run([fbar] + args, capture_output=True, text=True, cwd=cwd, timeout=300)
    return p.stdout + p.stderr


def scene(obj, name):
    path = os.path.join(work, name)
    with open(path, "w") as f:
        json.dump(obj, f)
    return path


outputs = [help_text]
for bad in sorted(glob.glob(os.path.join(source, "tests/scenes/bad/*.json"))):
    outputs.append(run(["--check", bad]))
tiny = {"simulation": {"domain": [0.2, 0.2, 0.2], "default_dx": 0.02, "fps": 10, "frames": 1},
        "bodies": [{"material": {"constitutive": "JFluid", "bulk_modulus": 2e4},
                    "geometry": [{"object": "Box", "span": [0.06, 0.06, 0.06], "offset": [0.06, 0.06, 0.06]}]}]}
placed = dict(tiny, bodies=[tiny["bodies"][0], dict(tiny["bodies"][0], gpu=3, model=0)])
os.makedirs(os.path.join(work, "blocked", "run.json"))  # a run.json that cannot be written: a folder of that name
outputs += [run(["--version"]), run(["--chek", "x.json"]), run(["--gpus=0", "x.json"]), run(["--frames=0", "x.json"]),
            run(["x.json"]), run(["--backend=gpu", "--quiet", scene(tiny, "tiny.json")]),
            run(["--restart=missing.h5", "tiny.json"]), run(["--backend=cpu", "--quiet", scene(placed, "placed.json")]),
            run(["--backend=cpu", "--quiet", "--output=" + os.path.join(work, "blocked"), "tiny.json"])]
# A block that leaves the domain (tests/engine/test_checkpoint.cpp's failure case).
leaving = {"simulation": {"domain": [0.3, 1, 1], "default_dx": 0.025, "default_dt": 1e-3, "gravity": [0, 0, 0],
                          "fps": 50, "frames": 15},
           "bodies": [{"velocity": [1.0, 0, 0], "material": {"constitutive": "JFluid", "bulk_modulus": 1e4},
                       "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.2, 0.2, 0.2]}]}]}
outputs.append(run(["--backend=cpu", "--quiet", "--output=" + os.path.join(work, "leaving"),
                    scene(leaving, "leaving.json")]))
# Sweeps (user guide §10.1): a path past the scene's end, and a case the scene refuses.
with open(os.path.join(work, "s.sweep.json"), "w") as f:
    json.dump({"scene": "tiny.json", "parameters": [{"name": "rho", "path": "bodies[3].material.rho", "values": [1]}]}, f)
with open(os.path.join(work, "r.sweep.json"), "w") as f:
    json.dump({"scene": "tiny.json", "parameters": [{"name": "rho", "path": "bodies[0].material.rho",
                                                     "values": [1000, -1]}]}, f)
outputs += [run(["--check", "--sweep=s.sweep.json"]), run(["--check", "--sweep=r.sweep.json"])]
known = []
for line in "\n".join(outputs).splitlines():
    line = line.strip()
    if line:
        known.append(line[len("fbar: error: "):] if line.startswith("fbar: error: ") else line)
sources = ""
for ext in ("cpp", "h", "cu", "cuh"):
    for f in glob.glob(os.path.join(source, "Projects", "FBAR", "**", f"*.{ext}"), recursive=True):
        with open(f) as fh:
            sources += fh.read()


def free_parts(text, names=()):
    """A regular expression of `text` with its variable parts free: numbers, paths, `...`, <placeholders> and the
    words in `names` (the key names of the message's JSON path)."""
    out, i = "", 0
    token = r"\.\.\.|<[^>]+>|\S*/\S*|-?\d+(?:\.\d+)?(?:e-?\d+)?" + "".join(rf"|\b{re.escape(n)}\b" for n in names)
    for m in re.finditer(token, text):
        t = m.group(0)
        out += re.escape(text[i:m.start()])
        out += r"-?[\d.e+-]+" if re.fullmatch(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", t) else r"\w+" if t in names else ".*"
        i = m.end()
    return out + re.escape(text[i:])


def pattern(quoted):
    """A quoted message as a regular expression. `<path>: got <value>; expected <text>` (the scene errors): the path
    and the value are free, and so are the path's key names in the expectation (`rho is given twice`)."""
    m = re.fullmatch(r"(\S+): got (.*?); expected (.*)", quoted)
    if not m:
        return free_parts(quoted)
    names = [n for n in re.findall(r"[A-Za-z_]\w*", m.group(1)) if len(n) > 1]
    return r"\S+: got .*?; expected " + free_parts(m.group(3), names)


QUOTE = re.compile(r"`(fbar: error: [^`]+|[a-z_\[\].0-9-]+: got [^`]+; expected [^`]+)`")
checked = 0
for doc in ("docs/user_guide.md", "docs/first_scene.md", "README.md"):
    for n, line in enumerate(read(doc).splitlines(), 1):
        for q in QUOTE.findall(line):
            text = q[len("fbar: error: "):] if q.startswith("fbar: error: ") else q
            rx = re.compile(pattern(text))
            checked += 1
            if any(rx.search(k) for k in known):
                continue
            # Not produced here: its fixed fragments (between numbers, paths and <...>) must be in the sources.
            fragments = [f for f in re.split(r"-?\d+(?:\.\d+)?(?:e-?\d+)?|\.\.\.|<[^>]+>|\S*/\S*", text)
                         if len(f.strip()) >= 12]
            if not fragments or not all(f.strip() in sources for f in fragments):
                failures.append(f"{doc}:{n}: the program prints no message like `{q}`")
print(f"{len(program_options)} options, {checked} quoted messages checked")

# 3. --check's throughput label: a GPU and the date of a record that exists.
check = run(["--check", os.path.join(work, "tiny.json")])
m = re.search(r"ms per step on an? ([A-Z]\w+) \(measured (\d{4}-\d{2}-\d{2})", check)
if not m:
    failures.append("fbar --check: the GPU time row names no GPU and date ('on an H200 (measured YYYY-MM-DD')")
else:
    gpu, date = m.group(1).lower(), m.group(2)
    if not glob.glob(os.path.join(source, "docs/benchmarks", f"{date}-{gpu}*.md")):
        failures.append(f"fbar --check: its throughputs cite a {gpu} record of {date}, not in docs/benchmarks/")

for f in failures:
    print("FAIL:", f)
sys.exit(1 if failures else 0)
