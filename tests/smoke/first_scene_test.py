"""docs/first_scene.md, run as written (ctest FirstScene.WalkThrough).

The page's snippets are the test's input, so the walk-through cannot drift from the release:
  * a fenced block after `<!-- test: file PATH -->` must be PATH's text exactly (PATH relative to the repository);
  * every line of a ```sh block that starts with `fbar ` or `python3 ` runs, in page order, in WORKDIR (which holds
    links to the repository's scenes/ and tools/), `fbar` being the binary under test; each must exit 0. The
    python3 lines run only where numpy and matplotlib import (tools/plot/requirements.txt);
  * the lines of a block after `<!-- test: lines in output -->` must appear, in order, in the output (stdout and
    stderr) of the last command run before the block; after `<!-- test: lines in PATH -->`, in the file PATH under
    WORKDIR as it is at that point of the page.
Usage: first_scene_test.py FBAR WORKDIR.
"""
import os
import re
import shlex
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
PAGE = os.path.join(REPO, "docs", "first_scene.md")

fbar, work = os.path.abspath(sys.argv[1]), sys.argv[2]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
for name in ("scenes", "tools"):
    os.symlink(os.path.join(REPO, name), os.path.join(work, name))
try:
    import numpy  # noqa: F401
    import matplotlib  # noqa: F401
    have_plot = True
except ImportError:
    have_plot = False

text = open(PAGE, encoding="utf-8").read()
# Every fenced block with the marker comment (if any) on the line before its opening fence.
blocks = re.finditer(r"(?:<!-- test: (?P<marker>[^>]*?) -->\n)?```(?P<lang>\w*)\n(?P<body>.*?)```", text, re.S)

failures = []
last_output = ""
commands = 0


def fail(message):
    failures.append(message)
    print("FAIL:", message)


def lines_in_order(expected, actual, where):
    actual_lines = [l.rstrip() for l in actual.splitlines()]
    at = 0
    for line in expected:
        line = line.rstrip()
        if not line or line == "...":
            continue
        try:
            at = actual_lines.index(line, at) + 1
        except ValueError:
            fail(f"{where}: the page shows {line!r}, which is not there (in this order)")
            return


for b in blocks:
    marker, lang, body = b.group("marker"), b.group("lang"), b.group("body")
    if marker and marker.startswith("file "):
        path = marker[len("file "):]
        if body != open(os.path.join(REPO, path), encoding="utf-8").read():
            fail(f"the block marked {path} is not that file's text")
    elif marker and marker.startswith("lines in "):
        target = marker[len("lines in "):]
        if target == "output":
            lines_in_order(body.splitlines(), last_output, "output of the command before")
        else:
            path = os.path.join(work, target)
            if not os.path.exists(path):
                fail(f"{target}: no such file after the commands before it")
            else:
                lines_in_order(body.splitlines(), open(path, encoding="utf-8").read(), target)
    elif lang == "sh":
        for line in body.splitlines():
            words = shlex.split(line)
            if not words or words[0] not in ("fbar", "python3"):
                continue
            if words[0] == "python3" and not have_plot:
                print("skipped (no numpy / matplotlib):", line)
                continue
            argv = [fbar if words[0] == "fbar" else sys.executable] + words[1:]
            print("$", line, flush=True)
            r = subprocess.run(argv, cwd=work, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            last_output = r.stdout
            print(r.stdout)
            commands += 1
            if r.returncode != 0:
                fail(f"{line!r} exited with {r.returncode}")

if commands < 3:
    fail(f"only {commands} commands found on the page")
if failures:
    print(f"{len(failures)} failure(s)")
    sys.exit(1)
print(f"docs/first_scene.md: {commands} commands run, every shown line found")
