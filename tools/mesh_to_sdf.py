#!/usr/bin/env python3
"""Turn a closed triangle mesh (.obj or .stl, ASCII or binary) into an SDFGen .sdf level set for fbar's File geometry.

    python3 tools/mesh_to_sdf.py debris.obj debris.sdf --dx 0.01 --padding 2

Output (SDFGen's text format, which fbar and ClaymoreUW read):
    ni nj nk
    origin_x origin_y origin_z      (the mesh's bounding-box minimum minus padding * dx)
    dx
    ni*nj*nk values, i fastest, the signed distance in the mesh's units: negative inside

Grid point (i, j, k) lies at origin + (i, j, k) * dx; the grid covers the bounding box plus `padding` cells on each
side, so in a scene `offset` places the mesh's bounding-box minimum (grid index `padding`) and `scaling_factor`
converts the mesh's units to metres. The distance is exact (closest point on any triangle); the sign comes from the
generalised winding number (inside where it exceeds 1/2), so small holes in the mesh do not flip whole regions.
Cost is (grid points) x (triangles): about a second per 10^8 pairs with numpy. Needs numpy only.
"""
import argparse
import struct
import sys

import numpy as np


def read_obj(path):
    vertices, faces = [], []
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                vertices.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                idx = []
                for p in parts[1:]:
                    i = int(p.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(vertices) + i)
                if len(idx) < 3:
                    sys.exit(f"{path}: line {number}: a face with fewer than 3 vertices")
                for k in range(1, len(idx) - 1):  # fan triangulation of polygons
                    faces.append([idx[0], idx[k], idx[k + 1]])
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        sys.exit(f"{path}: no faces")
    if f.min() < 0 or f.max() >= len(v):
        sys.exit(f"{path}: a face refers to a vertex that does not exist")
    return v[f]


def read_stl(path):
    data = open(path, "rb").read()
    if len(data) >= 84:
        count = struct.unpack("<I", data[80:84])[0]
        if len(data) == 84 + 50 * count:  # binary
            rec = np.frombuffer(data[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
            return rec["v"].astype(np.float64)
    tris, current = [], []
    for line in data.decode("utf-8", errors="replace").splitlines():
        parts = line.split()
        if parts and parts[0] == "vertex":
            current.append([float(x) for x in parts[1:4]])
            if len(current) == 3:
                tris.append(current)
                current = []
    if not tris:
        sys.exit(f"{path}: no facets (neither binary nor ASCII STL)")
    return np.asarray(tris, dtype=np.float64)


def closest_distance(p, tri):
    """Distance from points p (P, 3) to triangles tri (T, 3, 3): (P, T) (Ericson, Real-Time Collision Detection 5.1.5)."""
    a, b, c = tri[:, 0][None], tri[:, 1][None], tri[:, 2][None]
    p = p[:, None]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        q = a + ab * v[..., None] + ac * w[..., None]  # interior
        # edges and vertices, each where its region test holds
        t_ab = np.clip(d1 / (d1 - d3), 0, 1)
        t_ac = np.clip(d2 / (d2 - d6), 0, 1)
        t_bc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
    q = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[..., None], a + ab * np.nan_to_num(t_ab)[..., None], q)
    q = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[..., None], a + ac * np.nan_to_num(t_ac)[..., None], q)
    q = np.where(((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0))[..., None],
                 b + (c - b) * np.nan_to_num(t_bc)[..., None], q)
    q = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, q)
    q = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, q)
    return np.sqrt(((p - q) ** 2).sum(-1))


def winding_number(p, tri):
    """Generalised winding number of the mesh at points p (van Oosterom & Strackee solid angles)."""
    a = tri[:, 0][None] - p[:, None]
    b = tri[:, 1][None] - p[:, None]
    c = tri[:, 2][None] - p[:, None]
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    det = (a * np.cross(b, c)).sum(-1)
    den = la * lb * lc + (a * b).sum(-1) * lc + (b * c).sum(-1) * la + (c * a).sum(-1) * lb
    return (2.0 * np.arctan2(det, den)).sum(-1) / (4.0 * np.pi)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mesh", help=".obj or .stl (closed, consistently oriented triangles)")
    ap.add_argument("out", help="the .sdf to write")
    ap.add_argument("--dx", type=float, required=True, help="grid spacing, in the mesh's units")
    ap.add_argument("--padding", type=int, default=1, help="grid cells around the bounding box (default 1)")
    ap.add_argument("--chunk", type=int, default=4096, help="grid points per batch (memory: chunk x triangles)")
    args = ap.parse_args(argv)
    if not args.dx > 0:
        sys.exit("--dx must be positive")
    if args.padding < 1:
        sys.exit("--padding must be >= 1")
    ext = args.mesh.lower().rsplit(".", 1)[-1]
    if ext == "obj":
        tri = read_obj(args.mesh)
    elif ext == "stl":
        tri = read_stl(args.mesh)
    else:
        sys.exit(f"{args.mesh}: expected a .obj or .stl file")
    lo = tri.reshape(-1, 3).min(0) - args.padding * args.dx
    hi = tri.reshape(-1, 3).max(0) + args.padding * args.dx
    n = np.ceil((hi - lo) / args.dx - 1e-9).astype(int) + 1
    axes = [lo[d] + np.arange(n[d]) * args.dx for d in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")  # i fastest in C order
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    phi = np.empty(len(points))
    for s in range(0, len(points), args.chunk):
        p = points[s:s + args.chunk]
        d = closest_distance(p, tri).min(axis=1)
        inside = winding_number(p, tri) > 0.5
        phi[s:s + args.chunk] = np.where(inside, -d, d)
    with open(args.out, "w") as f:
        f.write(f"{n[0]} {n[1]} {n[2]}\n{lo[0]:.17g} {lo[1]:.17g} {lo[2]:.17g}\n{args.dx:.17g}\n")
        for row in phi.reshape(-1, n[0]):
            f.write(" ".join(f"{v:.9g}" for v in row) + "\n")
    inside = int((phi <= 0).sum())
    print(f"{args.out}: {n[0]} x {n[1]} x {n[2]} grid, dx {args.dx:g}, {len(tri)} triangles, {inside} points inside")
    return 0


if __name__ == "__main__":
    sys.exit(main())
