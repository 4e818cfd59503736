#!/usr/bin/env python3
"""The include layers of the source tree, checked: a folder includes only its own layer and the layers below it.

    Library (MnBase, MnSystem), Projects/FBAR/settings.h (compile-time constants, includes nothing)   0
    Projects/FBAR/physics                            1
    Projects/FBAR/geometry, Projects/FBAR/scene      2
    Projects/FBAR/io, Projects/FBAR/comm             3
    Projects/FBAR/engine (cpu, gpu, shared)          4   engine/cpu and engine/gpu never include each other
    Projects/FBAR/*.cpp, *.cu, *.h (the program)     5
    tools/ (benchmarks, studies)                     6

Besides pointing up, three includes are violations: the shared engine code (files directly in Projects/FBAR/engine)
including one engine (engine/cpu or engine/gpu: both engines read what is shared, never the reverse), two folders of
one layer including each other's files (scene and geometry, io and comm: a layer's folders stand side by side), and
anything outside tests/ including a file of tests/ (a tool that needs a test's case takes it from the library).

Every `#include "..."` line of Library/, Projects/FBAR/ and tools/ is resolved (first beside the including file, then from
Projects/FBAR/ and Library/) and compared. An include that points up, or across between the two engines, is a
violation: "path:line: ...". The violations the tree has today are listed in tools/layers_baseline.txt, one
"path -> included path" per line; the check fails on any violation not listed there, and on a listed one that no
longer occurs (the list only shrinks). Exit status 0 when the tree keeps the rule, 1 otherwise.

usage: tools/check_layers.py [--root DIR] [--baseline FILE] [--self-test]
  --self-test  plants an upward include in a scratch tree and checks that it is reported with its file and line.
"""
import argparse
import os
import re
import sys
import tempfile

LEVELS = {"Library": 0, "settings": 0, "physics": 1, "geometry": 2, "scene": 2, "io": 3, "comm": 3, "engine": 4, "program": 5,
          "tools": 6}
SCANNED = ("Library", "Projects/FBAR", "tools")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def folder_of(rel):
    """The layer folder of a path relative to the root (Library/... or Projects/FBAR/...), and the engine side."""
    parts = rel.split("/")
    if parts[0] == "Library":
        return "Library", None
    if parts[0] == "tests":
        return "tests", None
    if parts[0] == "tools":
        return "tools", None
    if parts[:2] == ["Projects", "FBAR"]:
        rest = parts[2:]
        if rest == ["settings.h"]:
            return "settings", None
        if len(rest) == 1:
            return "program", None
        if rest[0] == "engine":
            if len(rest) == 2:
                return "engine", "shared"
            return "engine", rest[1] if rest[1] in ("cpu", "gpu") else None
        if rest[0] in LEVELS:
            return rest[0], None
    return None, None


def resolve(root, including, name):
    """The included file's path relative to root, or None (a system or generated header)."""
    for base in (os.path.dirname(including), "Projects/FBAR", "Library"):
        candidate = os.path.normpath(os.path.join(base, name))
        if os.path.isfile(os.path.join(root, candidate)):
            return candidate.replace(os.sep, "/")
    return None


def violations(root):
    found = []  # (path, line, included path, reason)
    for top in SCANNED:
        for dirpath, _, files in os.walk(os.path.join(root, top)):
            for f in sorted(files):
                if not f.endswith((".h", ".hpp", ".cuh", ".cpp", ".cu")):
                    continue
                rel = os.path.relpath(os.path.join(dirpath, f), root).replace(os.sep, "/")
                src, side = folder_of(rel)
                if src is None:
                    continue
                with open(os.path.join(root, rel), errors="replace") as fh:
                    for n, line in enumerate(fh, 1):
                        m = INCLUDE.match(line)
                        if not m:
                            continue
                        inc = resolve(root, rel, m.group(1))
                        if inc is None:
                            continue
                        dst, dst_side = folder_of(inc)
                        if dst is None:
                            continue
                        if dst == "tests":
                            found.append((rel, n, inc, f"{src} includes a file of tests/: only tests include tests"))
                            continue
                        if LEVELS[dst] > LEVELS[src]:
                            found.append((rel, n, inc, f"{src} (layer {LEVELS[src]}) includes {dst} (layer {LEVELS[dst]}): "
                                                       "an upward include"))
                        elif side == "shared" and dst_side in ("cpu", "gpu"):
                            found.append((rel, n, inc, f"the shared engine code includes engine/{dst_side}: what both "
                                                       "engines read lives in engine/, an engine's entry is declared "
                                                       "there and defined in its folder"))
                        elif side in ("cpu", "gpu") and dst_side in ("cpu", "gpu") and side != dst_side:
                            found.append((rel, n, inc, f"engine/{side} includes engine/{dst_side}: what both engines "
                                                       "share belongs in engine/"))
                        elif LEVELS[dst] == LEVELS[src] and dst != src and src not in ("Library", "settings"):
                            found.append((rel, n, inc, f"{src} includes {dst}, a folder of its own layer "
                                                       f"({LEVELS[src]}): a layer's folders do not include each other"))
    return found


def baseline_lines(path):
    """The entries of a baseline file (tools/check_sizes.py reads its own with it): its lines without comments and
    blanks; none when the path is empty or absent."""
    if not path or not os.path.exists(path):
        return []
    with open(path) as fh:
        return [e for e in (line.split("#", 1)[0].strip() for line in fh) if e]


def read_baseline(path):
    return {tuple(s.strip() for s in entry.split("->")) for entry in baseline_lines(path)}


def check(root, baseline_path, out=sys.stdout):
    found = violations(root)
    allowed = read_baseline(baseline_path)
    new = [v for v in found if (v[0], v[2]) not in allowed]
    seen = {(v[0], v[2]) for v in found}
    stale = sorted(allowed - seen)
    for path, line, inc, why in new:
        print(f"{path}:{line}: includes {inc}: {why}", file=out)
    for a, b in stale:
        print(f"{baseline_path}: '{a} -> {b}' no longer occurs: remove it from the baseline", file=out)
    print(f"layers: {len(found)} violation(s), {len(found) - len(new)} of them listed in the baseline; "
          f"{len(new)} new, {len(stale)} stale baseline entr{'y' if len(stale) == 1 else 'ies'}", file=out)
    return 1 if new or stale else 0


def self_test():
    with tempfile.TemporaryDirectory() as root:
        for rel, text in {
            "Library/MnBase/a.h": "#pragma once\n",
            "Projects/FBAR/physics/law.cuh": '#pragma once\n#include "MnBase/a.h"\n\n#include "engine/run.h"\n',
            "Projects/FBAR/engine/run.h": '#pragma once\n#include "physics/law.cuh"\n',
            "Projects/FBAR/engine/cpu/e.h": '#include "engine/gpu/g.h"\n',
            "Projects/FBAR/engine/gpu/g.h": '#include "../run.h"\n',
            "Projects/FBAR/engine/api.cpp": '#include "engine/run.h"\n#include "engine/cpu/e.h"\n',
            "Projects/FBAR/scene/s.h": '#pragma once\n#include "geometry/g.h"\n',
            "Projects/FBAR/geometry/g.h": '#pragma once\n',
            "tests/case.h": '#pragma once\n',
            "tools/study/s.cu": '#include "../../tests/case.h"\n#include "engine/run.h"\n',
        }.items():
            os.makedirs(os.path.dirname(os.path.join(root, rel)), exist_ok=True)
            open(os.path.join(root, rel), "w").write(text)
        import io
        out = io.StringIO()
        rc = check(root, None, out)
        text = out.getvalue()
        ok = (rc == 1 and "Projects/FBAR/physics/law.cuh:4: includes Projects/FBAR/engine/run.h" in text
              and "Projects/FBAR/engine/cpu/e.h:1: includes Projects/FBAR/engine/gpu/g.h" in text
              and "Projects/FBAR/engine/api.cpp:2: includes Projects/FBAR/engine/cpu/e.h" in text
              and "engine/api.cpp:1:" not in text
              and "Projects/FBAR/scene/s.h:2: includes Projects/FBAR/geometry/g.h" in text
              and "tools/study/s.cu:1: includes tests/case.h" in text
              and "tools/study/s.cu:2:" not in text
              and "engine/run.h:" not in text.replace("physics/law.cuh:4: includes Projects/FBAR/engine/run.h", ""))
        print(text, end="")
        print("self-test: " + ("the planted upward, cross-engine, shared-to-engine, same-layer and tests/ includes were reported" if ok else "FAILED"))
        return 0 if ok else 1


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=os.path.dirname(here))
    ap.add_argument("--baseline", default=os.path.join(here, "layers_baseline.txt"))
    ap.add_argument("--self-test", action="store_true")
    a = ap.parse_args()
    sys.exit(self_test() if a.self_test else check(a.root, a.baseline))


if __name__ == "__main__":
    main()
