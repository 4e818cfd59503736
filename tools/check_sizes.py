#!/usr/bin/env python3
"""Sizes of the source tree, checked: no file of Projects/FBAR, tests/ or tools/ over 1,000 lines, no class body over
1,000, no function over 150.

A function is a brace block opened outside any other function whose header (the text since the previous `;`, `{`
or `}`) has a parameter list and is not a namespace, class, struct, union or enum: free functions, member functions
defined in or out of a class, kernels, constructors (their initialiser lists count). Lambdas and nested blocks count
towards the function that holds them. Comments, string and character literals are blanked before the braces are
counted. A function's length is the number of lines from its header's first line to its closing brace.

A class body is the brace block of a class, struct or union, from its header to its closing brace (the member
functions defined inside count; those defined outside are counted as functions).

Every violation is printed as "path:line: ..." (the file's first line, the class's or the function's header).
tools/sizes_baseline.txt lists the violations the tree still has, one "path: what" per line ("path: file",
"path: function NAME", "path: class NAME"); the check fails on any violation not listed there and on a listed one
that no longer occurs (the list only shrinks). Exit status 0 when the tree keeps the limits, 1 otherwise.

usage: tools/check_sizes.py [--root DIR] [--max-file N] [--max-function N] [--baseline FILE] [--self-test]
  --self-test  writes over-long functions, files and a class, a listed file and a stale baseline entry to a scratch
               tree and checks that each is reported (the listed file not).
"""
import argparse
import os
import re
import sys
import tempfile

from check_layers import baseline_lines

EXTENSIONS = (".h", ".hpp", ".cuh", ".cpp", ".cu")
CONTAINER = re.compile(r"\b(namespace|class|struct|union|enum)\b")
CLASS = re.compile(r"\b(class|struct|union)\s+(?:alignas\s*\([^)]*\)\s*)?([A-Za-z_]\w*)")
SCANNED = ("Projects/FBAR", "tests", "tools")
CONTROL = re.compile(r"^\s*(if|for|while|switch|catch|do|else|try)\b")


def blank(text):
    """The text with comments and string / character literals replaced by spaces (newlines kept)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == '"' and text.startswith('R"', i - 1) and (i < 2 or not text[i - 2].isalnum()):
            m = re.match(r'"([^(\s]*)\(', text[i:])
            end = text.find(")" + (m.group(1) if m else "") + '"', i)
            j = n if end < 0 else end + len(m.group(1) if m else "") + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c in "\"'":
            if c == "'" and i > 0 and text[i - 1].isalnum() and i + 1 < n and text[i + 1].isalnum():
                out.append(c)  # a digit separator (1'000)
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(c + " " * (j - i - 2) + c if j - i >= 2 else text[i:j])
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def without_templates(header):
    """The header without its `template <...>` parameter lists (their `class` / `typename` name no container)."""
    out, i = [], 0
    while True:
        m = re.compile(r"\btemplate\s*<").search(header, i)
        if not m:
            out.append(header[i:])
            return "".join(out)
        out.append(header[i:m.start()])
        depth, j = 1, m.end()
        while j < len(header) and depth:
            depth += {"<": 1, ">": -1}.get(header[j], 0)
            j += 1
        i = j


def line_numbers(code):
    """The line number of each character of the text."""
    line_at = []
    line = 1
    for ch in code:
        line_at.append(line)
        if ch == "\n":
            line += 1
    return line_at


def functions(text):
    """(first line, last line, header) of every outermost function body in the text."""
    code = blank(text)
    found = []
    stack = []  # per open brace: "container", "function" or "other"
    header_start = 0
    line_at = line_numbers(code)
    for i, ch in enumerate(code):
        if ch in ";":
            header_start = i + 1
        elif ch == "{":
            inside_function = "function" in stack
            header = code[header_start:i]
            kind = "other"
            if not inside_function:
                stripped = re.sub(r"#[^\n]*", "", header).strip()  # preprocessor lines are not part of a header
                if CONTAINER.search(without_templates(stripped).split("(")[0]) or stripped.startswith("extern"):
                    kind = "container"
                elif ")" in stripped and not CONTROL.match(stripped) and not stripped.endswith("="):
                    kind = "function"
                    first = header_start + (len(header) - len(header.lstrip()))
                    while first < i and code[first] == "#":  # skip a preprocessor line before the header
                        first = code.find("\n", first) + 1
                    stack.append(kind)
                    named = [l for l in stripped.splitlines() if "(" in l]
                    found.append([line_at[first], None, (named[0].strip() if named else stripped)[:80]])
                    header_start = i + 1
                    continue
            stack.append(kind)
            header_start = i + 1
        elif ch == "}":
            if stack:
                kind = stack.pop()
                if kind == "function" and "function" not in stack:
                    found[-1][1] = line_at[i]
            header_start = i + 1
    return [tuple(f) for f in found if f[1] is not None]


def classes(text):
    """(first line, last line, name) of every class, struct or union body in the text, nested ones included."""
    code = blank(text)
    line_at = line_numbers(code)
    found = []
    stack = []  # per open brace: the index into found, or None
    header_start = 0
    for i, ch in enumerate(code):
        if ch == ";":
            header_start = i + 1
        elif ch == "{":
            header = code[header_start:i]
            head = without_templates(re.sub(r"#[^\n]*", "", header).strip()).split("(")[0]
            m = CLASS.search(head)
            if m and not re.search(r"\benum\b", head) and "=" not in head:
                first = header_start + (len(header) - len(header.lstrip()))
                found.append([line_at[first], None, m.group(2)])
                stack.append(len(found) - 1)
            else:
                stack.append(None)
            header_start = i + 1
        elif ch == "}":
            if stack:
                k = stack.pop()
                if k is not None:
                    found[k][1] = line_at[i]
            header_start = i + 1
    return [tuple(f) for f in found if f[1] is not None]


def check(root, max_file, max_function, baseline=None):
    """Violations not in the baseline, then listed ones that no longer occur."""
    found = scan(root, max_file, max_function)
    allowed = set(baseline_lines(baseline))
    new = [text for key, text in found if key not in allowed]
    stale = sorted(allowed - {key for key, _ in found})
    return new + [f"{baseline}: '{k}' no longer occurs: remove it from the baseline" for k in stale]


def scan(root, max_file, max_function):
    """(baseline key, message) of every file, class body and function over its limit."""
    problems = []
    for top in SCANNED:
        for dirpath, _, files in os.walk(os.path.join(root, top)):
            for f in sorted(files):
                if f.endswith(EXTENSIONS):
                    problems += file_problems(root, os.path.join(dirpath, f), max_file, max_function)
    return problems


def file_problems(root, path, max_file, max_function):
    problems = []
    rel = os.path.relpath(path, root).replace(os.sep, "/")
    with open(path, errors="replace") as fh:
        text = fh.read()
    lines = text.count("\n") + (0 if text.endswith("\n") or not text else 1)
    if lines > max_file:
        problems.append((f"{rel}: file", f"{rel}:1: {lines} lines; a file holds at most {max_file} "
                                         "(split it by what its parts do)"))
    for first, last, name in classes(text):
        length = last - first + 1
        if length > max_file:
            problems.append((f"{rel}: class {name}",
                             f"{rel}:{first}: class {name} of {length} lines; a class body holds at most {max_file}"))
    for first, last, header in functions(text):
        length = last - first + 1
        if length > max_function:
            words = header.split("(")[0].split()
            problems.append((f"{rel}: function {words[-1] if words else header}",
                             f"{rel}:{first}: function of {length} lines ({header}); at most {max_function}"))
    return problems


def self_test():
    with tempfile.TemporaryDirectory() as root:
        folder = os.path.join(root, "Projects", "FBAR", "physics")
        os.makedirs(folder)
        body = "".join(f"  x += {i};  // {{ not a brace\n" for i in range(160))
        with open(os.path.join(folder, "long.h"), "w") as fh:
            fh.write("namespace fbar {\nstruct S {\n  int f(int x) const {\n" + body + "    return x;\n  }\n};\n"
                     "template <class E>\nint h(E e) {\n" + body + "  return e;\n}\ninline int g(int x) {\n  auto l = [&](int y) { return y; };\n  return l(x);\n}\n}\n")
        with open(os.path.join(folder, "big.cpp"), "w") as fh:
            fh.write("const char* s = \"}\";\n" * 1001)
        os.makedirs(os.path.join(root, "tests", "engine"))
        members = "".join(f"  int m{i}() const {{ return {i}; }}\n" for i in range(1001))
        with open(os.path.join(root, "tests", "engine", "wide.h"), "w") as fh:
            fh.write("template <class T>\nclass Wide {\n" + members + "};\n")
        os.makedirs(os.path.join(root, "tools"))
        with open(os.path.join(root, "tools", "listed.cpp"), "w") as fh:
            fh.write("int x;\n" * 1001)
        baseline = os.path.join(root, "baseline.txt")
        with open(baseline, "w") as fh:
            fh.write("tools/listed.cpp: file\ntools/gone.cpp: file\n")
        problems = check(root, 1000, 150, baseline)
        want = ["Projects/FBAR/physics/long.h:3: function of 163 lines", "Projects/FBAR/physics/long.h:167: function of 164 lines", "Projects/FBAR/physics/big.cpp:1: 1001 lines",
                "tests/engine/wide.h:1: 1004 lines", "tests/engine/wide.h:1: class Wide of 1004 lines",
                baseline + ": 'tools/gone.cpp: file' no longer occurs"]
        missing = [w for w in want if not any(p.startswith(w) for p in problems)]
        extra = [p for p in problems if not any(p.startswith(w) for w in want)]
        if missing or extra:
            print("self-test failed: missing", missing, "unexpected", extra)
            return 1
        print("self-test: the planted long functions, files and class, and a stale baseline entry, are reported; the "
              "listed file is not:\n  " + "\n  ".join(problems))
        return 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    ap.add_argument("--max-file", type=int, default=1000)
    ap.add_argument("--max-function", type=int, default=150)
    ap.add_argument("--baseline", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "sizes_baseline.txt"))
    ap.add_argument("--self-test", action="store_true")
    args = ap.parse_args()
    if args.self_test:
        return self_test()
    problems = check(os.path.abspath(args.root), args.max_file, args.max_function, args.baseline)
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} size violation(s)")
        return 1
    print("sizes: every file and class body within", args.max_file, "lines, every function within", args.max_function,
          "(beyond the baseline)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
