"""Reading fbar's output files without fbar: particle frames (.bgeo, .geo, .csv, .h5) and sensor / tracker CSVs.

The classic bgeo reader follows the format's description (docs/user_guide.md section 4.1, the header comment of
Library/MnSystem/IO/particle_io.h): big-endian; 'Bgeo' 'V' version 5; counts; a point-attribute dictionary (name,
width, type 0 float / 1 int / 5 vector, defaults); per point x y z w then every attribute's components. The .geo
reader reads the ASCII form of the same (PGEOMETRY V5, as fbar writes it); .h5 frames are read with h5py (one dataset
per quantity, /Position for 'P').

read_frame(path) returns {name: array} with 'P' (n, 3); frame_units(path) the units the file records ({} for bgeo
and geo, which have none).
"""
import csv
import re
import struct

import numpy as np


def read_bgeo(path):
    """Returns {name: array}: 'P' (n, 3) float32 and every point attribute ((n,) or (n, width))."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"Bgeo" or data[4:5] != b"V":
        raise ValueError(f"{path}: not a classic bgeo file")
    version, n, prims, point_groups, prim_groups, n_attr, vert_attr, prim_attr, detail_attr = struct.unpack_from(
        ">9i", data, 5)
    if version != 5:
        raise ValueError(f"{path}: bgeo version {version} (expected 5)")
    if prims or point_groups or prim_groups or vert_attr or prim_attr or detail_attr:
        raise ValueError(f"{path}: primitives, groups or non-point attributes are not particle frames")
    at = 41
    fields = [("P", ">f4", (4,))]
    attrs = []
    for _ in range(n_attr):
        (length,) = struct.unpack_from(">h", data, at)
        at += 2
        name = data[at:at + length].decode("ascii")
        at += length
        width, kind = struct.unpack_from(">Hi", data, at)
        at += 6 + 4 * width  # the defaults
        if kind not in (0, 1, 5):
            raise ValueError(f"{path}: attribute {name} has type {kind} (expected 0, 1 or 5)")
        fields.append((name, ">i4" if kind == 1 else ">f4", (width,)))
        attrs.append(name)
    dtype = np.dtype(fields)
    end = at + n * dtype.itemsize
    if len(data) != end + 2 or data[end:end + 2] != b"\x00\xff":
        raise ValueError(f"{path}: {len(data)} bytes, expected {end + 2} (points and the extra section)")
    points = np.frombuffer(data, dtype=dtype, count=n, offset=at)
    out = {"P": points["P"][:, :3].astype(np.float32)}
    for name in attrs:
        values = points[name]
        out[name] = values[:, 0].copy() if values.shape[1] == 1 else values.copy()
    return out


_UNIT = re.compile(r"^(.*?)(?: \[(.*)\])?$")


def split_header(column):
    """'Pressure [Pa]' -> ('Pressure', 'Pa'); 'J' -> ('J', '')."""
    m = _UNIT.match(column)
    return m.group(1), m.group(2) or ""


def read_frame_csv(path):
    """Returns {name: array} like read_bgeo: 'P' from Position_X/Y/Z, every other column by its name."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    names = [split_header(h)[0] for h in rows[0]]
    table = np.array(rows[1:], dtype=np.float64).reshape(len(rows) - 1, len(names))
    out = {name: table[:, i] for i, name in enumerate(names)}
    out["P"] = np.stack([out.pop("Position_X"), out.pop("Position_Y"), out.pop("Position_Z")], axis=1)
    return out


def read_geo(path):
    """Classic ASCII geometry (PGEOMETRY V5) as fbar writes it: {name: array} like read_bgeo."""
    with open(path) as f:
        lines = f.read().split("\n")
    if not lines[0].startswith("PGEOMETRY V5"):
        raise ValueError(f"{path}: not a classic ASCII geo file")
    head = " ".join(lines[1:4]).split()
    counts = {head[i]: int(head[i + 1]) for i in range(0, len(head) - 1, 2)}
    n, n_attr = counts["NPoints"], counts["NPointAttrib"]
    at = 4
    attrs = []
    if n_attr:
        if lines[at] != "PointAttrib":
            raise ValueError(f"{path}: expected PointAttrib at line {at + 1}")
        at += 1
        for _ in range(n_attr):
            name, width, kind = lines[at].split()[:3]
            attrs.append((name, int(width), kind == "int"))
            at += 1
    rows = lines[at:at + n]
    if len(rows) != n:
        raise ValueError(f"{path}: {len(rows)} point lines, expected {n}")
    width = sum(w for _, w, _ in attrs)
    values = np.array(" ".join(r.replace("(", " ").replace(")", " ").replace("\t", " ") for r in rows).split(),
                      dtype=np.float64).reshape(n, 4 + width)
    out = {"P": values[:, :3].copy()}
    col = 4
    for name, w, integer in attrs:
        v = values[:, col:col + w]
        v = v.astype(np.int32) if integer else v.astype(np.float32)
        out[name] = v[:, 0].copy() if w == 1 else v.copy()
        col += w
    return out


def _h5py():
    try:
        import h5py
    except ImportError as e:
        raise ImportError(f"reading .h5 frames needs h5py ({e}; pip install h5py, or Debian's python3-h5py)") from e
    return h5py


def read_frame_h5(path):
    """An fbar .h5 frame: {name: array}, 'P' from /Position (float32 or float64 as written)."""
    with _h5py().File(path, "r") as h:
        out = {name: h[name][()] for name in h}
    out["P"] = out.pop("Position")
    return out


def frame_units(path):
    """{attribute: unit} that a frame file records (.h5 datasets' "unit", .csv headers); {} for .bgeo and .geo."""
    path = str(path)
    if path.endswith(".h5"):
        with _h5py().File(path, "r") as h:
            units = {}
            for name in h:
                u = h[name].attrs.get("unit")
                if u is not None:
                    units[name] = u.decode() if isinstance(u, bytes) else str(u)
            units["P"] = units.pop("Position", "m")
            return units
    if path.endswith(".csv"):
        with open(path, newline="") as f:
            header = next(csv.reader(f))
        return {name: unit for name, unit in map(split_header, header) if unit and not name.startswith("Position_")}
    return {}


def read_frame(path):
    path = str(path)
    if path.endswith(".bgeo"):
        return read_bgeo(path)
    if path.endswith(".csv"):
        return read_frame_csv(path)
    if path.endswith(".h5"):
        return read_frame_h5(path)
    if path.endswith(".geo"):
        return read_geo(path)
    raise ValueError(f"{path}: expected a .bgeo, .geo, .csv or .h5 frame")


def read_series(path):
    """A sensor or tracker CSV: (times, {column header: values})."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    table = np.array(rows[1:], dtype=np.float64).reshape(len(rows) - 1, len(header))
    return table[:, 0], {h: table[:, i] for i, h in enumerate(header) if i > 0}
