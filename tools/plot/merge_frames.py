#!/usr/bin/env python3
"""Merges the per-rank frame files of an fbar run into one file per body and frame.

    python3 tools/plot/merge_frames.py RUN_DIR [--out DIR] [--frame F ...] [--body bodies[i] ...] [--format .h5]

A run on several ranks writes one file per body, rank and frame: model[m]_dev[d]_frame[f]<suffix>, each with the
particles that rank held (model numbers repeat on different GPUs: which files are one body's comes from the run's
run.json, its rank count and bodies' gpu and model). This writes bodies[i]_frame[f]<suffix> to --out (default
RUN_DIR/merged), i the body's index in the scene: every rank's particles of that body and frame, sorted by ID when the frames have an ID attribute (a particle found twice is an
error), otherwise rank after rank. Attributes, their order and units (.h5, .csv) are kept. --format writes another
format than the run's (.geo frames become .bgeo unless --format says otherwise). .bgeo positions are float32, .h5
keeps the positions' precision, .csv writes each value's shortest text. An .h5 output gets its .xdmf, and the merged
frames their own frames.xdmf time series (times from the run's frames.xdmf, else from run.json's simulation.time and
fps). Reads .bgeo, .geo, .csv and .h5 (h5py for .h5).
"""
import argparse
import glob
import json
import os
import re
import struct
import sys
import xml.etree.ElementTree as ET

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fbar_frames import frame_units, read_frame  # noqa: E402

NAME = re.compile(r"^model\[(\d+)\]_dev\[(\d+)\]_frame\[(\d+)\](\.bgeo|\.geo|\.csv|\.h5)$")


def body_files(run_dir):
    """[(label, [(model, device), ...]) per body]: the files each body of the run writes, from run.json (its ranks and
    resolved scene), as the run loop names them: one rank writes dev[gpu]; several ranks write a placed body (the
    scene's bodies name more than one gpu) on its gpu's rank and every other body on every rank. Without run.json:
    one body per model, every device. None then."""
    meta = os.path.join(run_dir, "run.json")
    if not os.path.exists(meta):
        return None
    with open(meta) as f:
        run = json.load(f)
    ranks = int(run.get("ranks", 1))
    bodies = run["scene"]["bodies"]
    gpus = [b.get("gpu", 0) for b in bodies]
    places = len({str(g) for g in gpus}) > 1
    out = []
    for i, b in enumerate(bodies):
        model, gpu = int(b.get("model", 0)), gpus[i]
        numbered = isinstance(gpu, int) and gpu >= 0
        if ranks <= 1:
            devices = [gpu if numbered else 0]
        elif places and numbered:
            devices = [gpu]
        else:
            devices = list(range(ranks))
        out.append((f"bodies[{i}]", [(model, d) for d in devices]))
    return out


def find_frames(run_dir):
    """{(label, frame, suffix): [path, ...] by device}: label "bodies[i]" (from run.json) or "model[m]"."""
    found = {}
    for path in glob.glob(os.path.join(glob.escape(run_dir), "model[[]*")):
        m = NAME.match(os.path.basename(path))
        if m:
            found[(int(m[1]), int(m[2]), int(m[3]), m[4])] = path
    bodies = body_files(run_dir)
    if bodies is None:
        print(f"note: no run.json in {run_dir}: each model's files are taken as one body's")
        bodies = [(f"model[{m}]", sorted((m2, d) for (m2, d, _, _) in found if m2 == m))
                  for m in sorted({k[0] for k in found})]
    groups = {}
    for label, files in bodies:
        for frame, suffix in sorted({(f, s) for (m, d, f, s) in found if (m, d) in files}):
            paths = [found.get((m, d, frame, suffix)) for m, d in files]
            missing = [f"model[{m}]_dev[{d}]_frame[{frame}]{suffix}" for (m, d), p in zip(files, paths) if p is None]
            if missing:
                raise SystemExit(f"merge_frames.py: {label} frame {frame}: {', '.join(missing)} not in {run_dir}")
            groups[(label, frame, suffix)] = paths
    return groups


def merge(paths, label):
    """The particles of every file in `paths` as one frame ({name: array}), sorted by ID when there is one."""
    frames = [read_frame(p) for p in paths]
    names = list(frames[0])
    for p, f in zip(paths, frames):
        if set(f) != set(names):
            raise ValueError(f"{label}: {p} has attributes {sorted(f)}, {paths[0]} has {sorted(names)}")
    out = {}
    for name in names:
        arrays = [np.asarray(f[name]) for f in frames]
        dtype = np.result_type(*arrays)
        out[name] = np.concatenate([a.astype(dtype) for a in arrays])
    if "ID" in out:
        ids = out["ID"].astype(np.int64)
        order = np.argsort(ids, kind="stable")
        sorted_ids = ids[order]
        twice = sorted_ids[1:][sorted_ids[1:] == sorted_ids[:-1]]
        if len(twice):
            raise ValueError(f"{label}: particle {int(twice[0])} is in more than one file")
        out = {name: v[order] for name, v in out.items()}
    return out


def _attributes(frame):
    """(name, values as (n, width), integer?) for every attribute but P, in the frame's order."""
    n = len(frame["P"])
    for name, v in frame.items():
        if name == "P":
            continue
        v = np.asarray(v).reshape(n, -1)
        integer = name == "ID" or np.issubdtype(v.dtype, np.integer)
        yield name, v, integer


def write_bgeo(path, frame):
    """Classic bgeo, version 5 (particle_io.h's layout): big-endian, positions and floats as float32, ints int32."""
    n = len(frame["P"])
    attrs = list(_attributes(frame))
    head = b"BgeoV" + struct.pack(">9i", 5, n, 0, 0, 0, len(attrs), 0, 0, 0)
    fields = [("P", ">f4", (4,))]
    for name, v, integer in attrs:
        width = v.shape[1]
        kind = 1 if integer else (5 if width == 3 else 0)
        raw = name.encode("ascii")
        head += struct.pack(">h", len(raw)) + raw + struct.pack(">Hi", width, kind) + b"\0" * (4 * width)
        fields.append((name, ">i4" if integer else ">f4", (width,)))
    points = np.zeros(n, dtype=np.dtype(fields))
    points["P"][:, :3] = np.asarray(frame["P"], dtype=np.float32)
    points["P"][:, 3] = 1.0
    for name, v, integer in attrs:
        points[name] = v.astype(np.int32 if integer else np.float32)
    with open(path + ".part", "wb") as f:
        f.write(head)
        f.write(points.tobytes())
        f.write(b"\x00\xff")
    os.replace(path + ".part", path)


def _text(v):
    """Each value's shortest text that reads back to it (float32 values as float32's)."""
    if np.issubdtype(v.dtype, np.integer):
        return [str(int(x)) for x in v]
    if v.dtype == np.float32:
        return [np.format_float_positional(x, unique=True, trim="-") if 1e-4 <= abs(x) < 1e16 or x == 0
                else np.format_float_scientific(x, unique=True, trim="-") for x in v]
    return [repr(float(x)) for x in v]


def write_csv(path, frame, units):
    """fbar's CSV layout: Position_X/Y/Z [m], then every attribute ("Name [unit]"; width 3: _X/_Y/_Z)."""
    P = np.asarray(frame["P"])
    header = ["Position_X [m]", "Position_Y [m]", "Position_Z [m]"]
    columns = [P[:, 0], P[:, 1], P[:, 2]]
    for name, v, integer in _attributes(frame):
        width = v.shape[1]
        unit = f" [{units[name]}]" if units.get(name) else ""
        for c in range(width):
            suffix = "" if width == 1 else "_" + ("XYZ"[c] if width == 3 else str(c))
            header.append(name + suffix + unit)
            columns.append(v[:, c].astype(np.int64) if integer else v[:, c])
    texts = [_text(c) for c in columns]
    with open(path + ".part", "w") as f:
        f.write(",".join(header) + "\n")
        for row in zip(*texts):
            f.write(",".join(row) + "\n")
    os.replace(path + ".part", path)


def xdmf_grid(h5_name, n, frame, indent, name="particles"):
    """A Uniform Polyvertex grid pointing into an .h5 frame (h5_frame.h's layout)."""
    P = np.asarray(frame["P"])

    def item(width, integer, size, dataset):
        dims = f"{n}" if width == 1 else f"{n} {width}"
        kind = "Int" if integer else "Float"
        return (f'<DataItem Dimensions="{dims}" NumberType="{kind}" Precision="{size}" Format="HDF">'
                f"{h5_name}:/{dataset}</DataItem>")

    s = indent
    x = [f'{s}<Grid Name="{name}" GridType="Uniform">',
         f'{s} <Topology TopologyType="Polyvertex" NumberOfElements="{n}" NodesPerElement="1"/>',
         f'{s} <Geometry GeometryType="XYZ">', f"{s}  {item(3, False, P.dtype.itemsize, 'Position')}",
         f"{s} </Geometry>"]
    for name_, v, integer in _attributes(frame):
        width = v.shape[1]
        kind = "Scalar" if width == 1 else "Vector" if width == 3 else "Matrix"
        x += [f'{s} <Attribute Name="{name_}" AttributeType="{kind}" Center="Node">',
              f"{s}  {item(width, integer, 4, name_)}", f"{s} </Attribute>"]
    x.append(f"{s}</Grid>")
    return "\n".join(x) + "\n"


def write_h5(path, frame, units):
    """fbar's .h5 layout (/Position, one dataset per attribute with a "unit") and its .xdmf next to it."""
    try:
        import h5py
    except ImportError as e:
        raise SystemExit(f"merge_frames.py: writing .h5 needs h5py ({e})")
    n = len(frame["P"])
    with h5py.File(path + ".part", "w") as h:
        h.create_dataset("Position", data=np.asarray(frame["P"]))
        h["Position"].attrs["unit"] = np.bytes_("m")
        for name, v, integer in _attributes(frame):
            data = v.astype(np.int32 if integer else np.float32)
            h.create_dataset(name, data=data[:, 0] if data.shape[1] == 1 else data)
            if units.get(name):
                h[name].attrs["unit"] = np.bytes_(units[name])
    os.replace(path + ".part", path)
    xdmf = os.path.splitext(path)[0] + ".xdmf"
    with open(xdmf + ".part", "w") as f:
        f.write('<?xml version="1.0" ?>\n<Xdmf Version="3.0">\n <Domain>\n')
        f.write(xdmf_grid(os.path.basename(path), n, frame, "  "))
        f.write(" </Domain>\n</Xdmf>\n")
    os.replace(xdmf + ".part", xdmf)


def frame_times(run_dir):
    """{frame: time [s]} from the run's frames.xdmf, else from run.json (simulation.time + f / fps), else {}."""
    series = os.path.join(run_dir, "frames.xdmf")
    if os.path.exists(series):
        root = ET.parse(series).getroot()
        out = {}
        for grid in root.find("Domain/Grid").findall("Grid"):
            f = int(re.match(r"frame\[(\d+)\]", grid.get("Name"))[1])
            out[f] = float(grid.find("Time").get("Value"))
        return out
    meta = os.path.join(run_dir, "run.json")
    if os.path.exists(meta):
        with open(meta) as f:
            sim = json.load(f)["scene"]["simulation"]
        return {"fps": sim["fps"], "t0": sim.get("time", 0.0)}
    return {}


def write_series(out_dir, written, times):
    """frames.xdmf in out_dir: the merged .h5 frames ({(label, frame): (file name, n, frame)}) as a time series."""
    frames = sorted({f for (_, f) in written})
    lines = ['<?xml version="1.0" ?>', '<Xdmf Version="3.0">', " <Domain>",
             '  <Grid Name="frames" GridType="Collection" CollectionType="Temporal">']
    for f in frames:
        t = times[f] if f in times else times["t0"] + f / times["fps"]
        lines += [f'   <Grid Name="frame[{f}]" GridType="Collection" CollectionType="Spatial">',
                  f'    <Time Value="{t!r}"/>']
        body = "".join(xdmf_grid(name, n, frame, "    ", label)
                       for (label, f2), (name, n, frame) in sorted(written.items()) if f2 == f and n > 0)
        lines.append(body.rstrip("\n"))
        lines.append("   </Grid>")
    lines += ["  </Grid>", " </Domain>", "</Xdmf>"]
    path = os.path.join(out_dir, "frames.xdmf")
    with open(path + ".part", "w") as fh:
        fh.write("\n".join(line for line in lines if line) + "\n")
    os.replace(path + ".part", path)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", help="the run's output folder (save_path or --output)")
    parser.add_argument("--out", help="folder for the merged files (default RUN_DIR/merged)")
    parser.add_argument("--frame", type=int, action="append", help="merge only this frame (repeatable)")
    parser.add_argument("--body", action="append", help='merge only this body, e.g. "bodies[1]" (repeatable)')
    parser.add_argument("--format", choices=[".bgeo", ".csv", ".h5"], help="output format (default: the run's)")
    args = parser.parse_args(argv)
    groups = find_frames(args.run_dir)
    if not groups:
        parser.error(f"no model[m]_dev[d]_frame[f] files in {args.run_dir}")
    out_dir = args.out or os.path.join(args.run_dir, "merged")
    os.makedirs(out_dir, exist_ok=True)
    written = {}
    for (label, frame, suffix), paths in sorted(groups.items()):
        if (args.frame and frame not in args.frame) or (args.body and label not in args.body):
            continue
        merged = merge(paths, f"{label} frame[{frame}]")
        units = frame_units(paths[0])
        fmt = args.format or (suffix if suffix != ".geo" else ".bgeo")
        name = f"{label}_frame[{frame}]{fmt}"
        path = os.path.join(out_dir, name)
        if fmt == ".bgeo":
            write_bgeo(path, merged)
        elif fmt == ".csv":
            write_csv(path, merged, units)
        else:
            write_h5(path, merged, units)
            # the series needs only the attributes' names, widths and types: one particle's row of each
            written[(label, frame)] = (name, len(merged["P"]), {k: v[:1] for k, v in merged.items()})
        print(f"{path}: {len(merged['P'])} particles from {len(paths)} file(s)")
    if written:
        times = frame_times(args.run_dir)
        if times:
            write_series(out_dir, written, times)
            print(os.path.join(out_dir, "frames.xdmf"))


if __name__ == "__main__":
    main()
