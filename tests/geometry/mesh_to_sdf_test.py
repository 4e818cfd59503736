#!/usr/bin/env python3
"""tools/mesh_to_sdf.py against the analytic signed distance of a box, from an OBJ and a binary STL of the same box.

usage: mesh_to_sdf_test.py <work dir>; exit 77 (skipped) without numpy.
"""
import os
import struct
import subprocess
import sys

try:
    import numpy as np
except ImportError:
    print("numpy unavailable: skipped")
    sys.exit(77)

HERE = os.path.dirname(os.path.abspath(__file__))
TOOL = os.path.join(HERE, "..", "..", "tools", "mesh_to_sdf.py")
work = sys.argv[1]
os.makedirs(work, exist_ok=True)

lo, hi = np.array([0.1, 0.2, 0.3]), np.array([0.5, 0.45, 0.6])
corners = np.array([[lo[0] if i & 1 == 0 else hi[0], lo[1] if i & 2 == 0 else hi[1], lo[2] if i & 4 == 0 else hi[2]]
                    for i in range(8)])
# 12 triangles, counter-clockwise seen from outside (outward normals)
quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
tris = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
with open(os.path.join(work, "box.obj"), "w") as f:
    for v in corners:
        f.write("v %.17g %.17g %.17g\n" % tuple(v))
    for a, b, c, d in quads:  # quads: the tool triangulates polygons
        f.write(f"f {a + 1} {b + 1} {c + 1} {d + 1}\n")
with open(os.path.join(work, "box.stl"), "wb") as f:
    f.write(b"\0" * 80 + struct.pack("<I", len(tris)))
    for t in tris:
        f.write(struct.pack("<3f", 0, 0, 0))
        for i in t:
            f.write(struct.pack("<3f", *corners[i]))
        f.write(b"\0\0")


def box_sdf(p):
    q = np.abs(p - (lo + hi) / 2) - (hi - lo) / 2
    outside = np.linalg.norm(np.maximum(q, 0), axis=-1)
    inside = np.minimum(q.max(-1), 0)
    return outside + inside


failures = 0
for name, tol in (("box.obj", 1e-9), ("box.stl", 2e-7)):
    out = os.path.join(work, name + ".sdf")
    subprocess.run([sys.executable, TOOL, os.path.join(work, name), out, "--dx", "0.025", "--padding", "2"],
                   check=True)
    tokens = open(out).read().split()
    n = [int(t) for t in tokens[:3]]
    origin = np.array([float(t) for t in tokens[3:6]])
    dx = float(tokens[6])
    phi = np.array([float(t) for t in tokens[7:]])
    if len(phi) != n[0] * n[1] * n[2]:
        print(f"{name}: {len(phi)} values for a {n} grid")
        failures += 1
        continue
    if not np.allclose(origin, lo - 2 * 0.025, atol=1e-7) or dx != 0.025:
        print(f"{name}: origin {origin}, dx {dx}")
        failures += 1
    k, j, i = np.meshgrid(*(np.arange(m) for m in n[::-1]), indexing="ij")
    p = origin + np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1) * dx
    err = np.abs(phi - box_sdf(p)).max()
    print(f"{name}: grid {n}, max |phi - exact| = {err:.3g}")
    if err > tol:
        failures += 1
sys.exit(1 if failures else 0)
