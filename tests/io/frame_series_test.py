"""frames.xdmf, merge_frames.py and .h5 plotting against real runs (ctest FrameSeries.*).

usage: frame_series_test.py FBAR MPIEXEC|none WORKDIR

Runs three bodies (a water column placed on GPU 0, a soft block placed on GPU 1, a column spread over every rank) on
the CPU engine, on one rank and, with MPIEXEC, on two MPI ranks, writing .h5 frames; then
  * parses frames.xdmf (python's xml): a Temporal collection of frames 0..frames with Time f / fps exactly, each a
    Spatial collection of the bodies' grids; every DataItem names an existing dataset of an existing .h5 with the
    stated dimensions and precision; each body's grids hold each of its particle IDs once, as many as one rank's
    run, at the same positions (the decomposed CPU run agrees with one rank to 1e-12 m);
  * reads frames.xdmf with VTK's XDMF reader when the vtk module is installed (what ParaView's "XDMF Reader" is):
    the time steps and the points per time step;
  * merges the two-rank run's frames with tools/plot/merge_frames.py (.h5, and .bgeo and .csv runs of two ranks
    too): one file per body and frame, with the particle count and IDs of the one-rank run;
  * draws an .h5 frame of each rank with tools/plot/render_frame.py (a PNG).
Exit 77 (skipped) without numpy or h5py.
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
TOOLS = os.path.join(HERE, "..", "..", "tools", "plot")
try:
    import numpy as np
    import h5py
except ImportError as e:
    print(f"skipped: {e} (pip install -r tools/plot/requirements.txt)")
    sys.exit(77)
sys.path.insert(0, TOOLS)
from fbar_frames import read_frame  # noqa: E402

fbar, mpiexec, work = sys.argv[1:4]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
env = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="PASSIVE")
FPS, FRAMES = 50, 3
water = {"constitutive": "JFluid", "ppc": 8, "CFL": 0.5, "rho": 1000, "bulk_modulus": 2e5, "gamma": 7.1,
         "viscosity": 0.001}
attribs = ["ID", "Velocity_Y", "Pressure"]
scene = {
    "simulation": {"domain": [0.64, 0.4, 0.2], "default_dx": 0.02, "default_dt": 1e-3, "fps": FPS,
                   "frames": FRAMES, "precision": "double"},
    "bodies": [
        {"gpu": 0, "material": water, "output_attribs": attribs,
         "geometry": [{"object": "Box", "span": [0.3, 0.2, 0.12], "offset": [0.04, 0.04, 0.04]}]},
        {"gpu": 1, "velocity": [0, -1, 0], "output_attribs": attribs,
         "material": {"constitutive": "FixedCorotated", "ppc": 8, "CFL": 0.5, "rho": 500, "youngs_modulus": 1e5,
                      "poisson_ratio": 0.3},
         "geometry": [{"object": "Box", "span": [0.08, 0.06, 0.08], "offset": [0.2, 0.26, 0.06]}]},
        {"gpu": "all", "material": water, "output_attribs": attribs,
         "geometry": [{"object": "Box", "span": [0.14, 0.28, 0.12], "offset": [0.44, 0.04, 0.04]}]},
    ],
    "boundaries": [{"object": "Walls", "contact": "Slip", "domain_start": [0.02, 0.02, 0.02],
                    "domain_end": [0.62, 0.38, 0.18]}],
}


def run(ranks, suffix):
    scene["simulation"]["save_suffix"] = suffix
    out = os.path.join(work, f"ranks{ranks}{suffix}")
    path = out + ".json"
    with open(path, "w") as f:
        json.dump(scene, f)
    cmd = [fbar, "--backend=cpu", "--quiet", f"--output={out}", f"--file={path}"]
    if ranks > 1:
        cmd = [mpiexec, "-np", str(ranks), "--oversubscribe", "--allow-run-as-root"] + cmd
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        sys.exit(f"{ranks} ranks {suffix}: exit {p.returncode}\n{p.stdout}\n{p.stderr}")
    assert "fbar: warning" not in p.stderr, p.stderr
    return out


def read_series(out, label):
    """{frame: {body: {ID: position}}} from frames.xdmf, every reference checked."""
    assert not os.path.exists(os.path.join(out, "frames.xdmf.part")), label
    root = ET.parse(os.path.join(out, "frames.xdmf")).getroot()
    assert root.tag == "Xdmf" and root.get("Version") == "3.0", label
    series = root.find("Domain/Grid")
    assert series.get("GridType") == "Collection" and series.get("CollectionType") == "Temporal", label
    frames = {}
    for grid in series.findall("Grid"):
        f = int(re.fullmatch(r"frame\[(\d+)\]", grid.get("Name"))[1])
        assert grid.get("CollectionType") == "Spatial", label
        t = float(grid.find("Time").get("Value"))
        assert t == f / FPS, f"{label}: frame {f} at t = {t!r}, expected {f / FPS!r}"
        bodies = {}
        for body in grid.findall("Grid"):
            b = int(re.fullmatch(r"bodies\[(\d+)\]", body.get("Name"))[1])
            particles = {}
            for piece in body.findall("Grid"):
                assert re.fullmatch(r"model\[\d+\]_dev\[\d+\]", piece.get("Name")), piece.get("Name")
                n = int(piece.find("Topology").get("NumberOfElements"))
                assert n > 0, f"{label}: an empty grid in the series"
                data = {}
                items = [("Position", piece.find("Geometry/DataItem"))]
                items += [(a.get("Name"), a.find("DataItem")) for a in piece.findall("Attribute")]
                assert [name for name, _ in items] == ["Position"] + attribs, items
                for name, item in items:
                    file_name, dataset = item.text.strip().split(":/")
                    assert dataset == name and file_name.endswith(f"_frame[{f}].h5"), item.text
                    assert file_name.startswith(piece.get("Name") + "_"), (piece.get("Name"), file_name)
                    with h5py.File(os.path.join(out, file_name), "r") as h:
                        values = h[dataset][()]
                    dims = tuple(int(d) for d in item.get("Dimensions").split())
                    assert values.shape == dims and dims[0] == n, (item.text, values.shape, dims)
                    assert values.dtype.itemsize == int(item.get("Precision")), item.text
                    assert (item.get("NumberType") == "Int") == (name == "ID"), item.text
                    data[name] = values
                for pid, x in zip(data["ID"], data["Position"]):
                    assert int(pid) not in particles, f"{label}: frame {f} body {b}: particle {pid} twice"
                    particles[int(pid)] = x
            bodies[b] = particles
        frames[f] = bodies
    assert sorted(frames) == list(range(FRAMES + 1)), f"{label}: frames {sorted(frames)}"
    return frames


def check_vtk(out, label, counts):
    """VTK's XDMF reader (ParaView's): the series' time steps and the points of each; skipped without vtk."""
    try:
        import vtk
    except ImportError:
        print("note: vtk not installed: frames.xdmf not read through VTK's XDMF reader")
        return False
    reader = vtk.vtkXdmfReader()
    reader.SetFileName(os.path.join(out, "frames.xdmf"))
    reader.UpdateInformation()
    key = vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS()
    times = list(reader.GetOutputInformation(0).Get(key) or [])
    assert len(times) == FRAMES + 1 and all(abs(t - f / FPS) < 1e-12 for f, t in enumerate(times)), (label, times)
    for f, t in enumerate(times):
        reader.UpdateTimeStep(t)
        it = reader.GetOutputDataObject(0).NewIterator()
        it.InitTraversal()
        points = 0
        while not it.IsDoneWithTraversal():
            points += it.GetCurrentDataObject().GetNumberOfPoints()
            it.GoToNextItem()
        assert points == counts[f], f"{label}: VTK reads {points} points at t = {t}, the series holds {counts[f]}"
    return True


one = read_series(run(1, ".h5"), "1 rank")
total = sum(len(p) for p in one[0].values())
for f, bodies in one.items():
    assert sorted(bodies) == [0, 1, 2], bodies.keys()
    for b, particles in bodies.items():
        assert sorted(particles) == list(range(len(one[0][b]))), f"1 rank: frame {f} body {b}: IDs"
moved = max(abs(one[FRAMES][2][i][1] - one[0][2][i][1]) for i in one[0][2])
assert moved > 1e-3, "the spread column did not move: a static run proves nothing"
vtk_used = check_vtk(os.path.join(work, "ranks1.h5"), "1 rank", {f: total for f in one})
print(f"1 rank: frames.xdmf lists {len(one)} frames of {total} particles in 3 bodies")

if mpiexec == "none":
    print("note: no MPI launcher: the two-rank series and the merge tool are not tested")
    sys.exit(0)

out2 = run(2, ".h5")
two = read_series(out2, "2 ranks")
with open(os.path.join(out2, "frames.xdmf")) as fh:
    text = fh.read()
for f in two:
    for b in (0, 1, 2):
        assert two[f][b].keys() == one[f][b].keys(), f"2 ranks: frame {f} body {b}: other particle IDs"
        # np.max keeps a NaN (Python's max may drop it): a NaN position fails the check below
        worst = float(np.max([np.max(np.abs(two[f][b][i] - one[f][b][i])) for i in one[f][b]]))
        assert worst < 1e-12, f"2 ranks: frame {f} body {b}: positions differ by {worst}"
# the spread body has a grid per rank, the placed ones one each
assert text.count('<Grid Name="model[') == (FRAMES + 1) * 4, "2 ranks: expected 4 grids per frame"
if vtk_used:
    check_vtk(out2, "2 ranks", {f: total for f in two})
print(f"2 ranks: frames.xdmf lists every frame's particles once, as one rank's")

# merge_frames.py on the two-rank runs, each format, against one rank's particles (IDs and counts per body)
merge = os.path.join(TOOLS, "merge_frames.py")
runs = {".h5": out2, ".bgeo": run(2, ".bgeo"), ".csv": run(2, ".csv")}
for suffix, out in runs.items():
    merged_dir = os.path.join(work, "merged" + suffix)
    subprocess.run([sys.executable, merge, out, "--out", merged_dir], check=True, capture_output=True, text=True)
    for f in range(FRAMES + 1):
        for b in (0, 1, 2):
            m = read_frame(os.path.join(merged_dir, f"bodies[{b}]_frame[{f}]{suffix}"))
            ids = np.asarray(m["ID"]).astype(np.int64)
            assert list(ids) == sorted(one[f][b]), f"merged {suffix}: frame {f} body {b}: IDs"
            ref = np.array([one[f][b][i] for i in ids])
            tol = 1e-6 if suffix == ".bgeo" else 1e-12  # bgeo positions are float32
            assert np.max(np.abs(np.asarray(m["P"], dtype=np.float64) - ref)) < tol, f"merged {suffix} frame {f} {b}"
    left = sorted(os.listdir(merged_dir))
    assert len([n for n in left if n.endswith(suffix)]) == 3 * (FRAMES + 1), left
    if suffix == ".h5":  # the merged frames' own series
        root = ET.parse(os.path.join(merged_dir, "frames.xdmf")).getroot()
        times = [float(g.find("Time").get("Value")) for g in root.find("Domain/Grid").findall("Grid")]
        assert times == [f / FPS for f in range(FRAMES + 1)], times
        if vtk_used:
            check_vtk(merged_dir, "merged", {f: total for f in range(FRAMES + 1)})
# the conversion of a run's frames to another format keeps the values
subprocess.run([sys.executable, merge, runs[".bgeo"], "--out", os.path.join(work, "converted"), "--format", ".h5",
                "--frame", str(FRAMES)], check=True, capture_output=True)
a = read_frame(os.path.join(work, "merged.bgeo", f"bodies[2]_frame[{FRAMES}].bgeo"))
c = read_frame(os.path.join(work, "converted", f"bodies[2]_frame[{FRAMES}].h5"))
for name in ("P", "Velocity_Y", "Pressure", "ID"):
    assert np.array_equal(np.asarray(a[name]), np.asarray(c[name])), name
assert not any(math.isnan(v) for v in np.asarray(c["Pressure"]).tolist())
print("merge_frames.py: .h5, .bgeo and .csv frames of 2 ranks merge to one rank's particles")

# render_frame.py draws .h5 frames (every file of the last frame together)
png = os.path.join(work, "h5_frame.png")
files = sorted(os.path.join(out2, n) for n in os.listdir(out2) if n.endswith(f"_frame[{FRAMES}].h5"))
assert len(files) == 4, files  # the placed bodies' files and the spread body's two
try:
    import matplotlib  # noqa: F401
except ImportError:
    print("note: matplotlib not installed: render_frame.py not run")
else:
    subprocess.run([sys.executable, os.path.join(TOOLS, "render_frame.py"), *files, "--color", "Pressure", "--out",
                    png], check=True, capture_output=True)
    with open(png, "rb") as fh:
        assert fh.read(8) == b"\x89PNG\r\n\x1a\n", png
    print("render_frame.py: the .h5 files of a frame of 2 ranks drawn")
print("ok")
