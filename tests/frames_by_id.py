"""The outputs of decomposed command-line runs, for the rank tests (tests/comm/mpi_cli_test.py,
tests/comm/mpi_placement_test.py, tests/engine/gpu/gpu_cli_ranks_test.py).

read_run(out, ranks, label) checks run.json (status completed, `ranks` ranks), finds the last frame's CSV files
(model[0]_dev[rank]_frame[f].csv, one per rank) and returns (run.json as a dict, {ID: [x, y, z, vx, vy, vz]}); a
particle written twice is an error. read_frame() reads one such file; read_sensors() and max_sensor_difference()
compare the sensor and tracker CSVs; visible_gpus_or_skip() ends a GPU test with exit 77 without a CUDA device;
scene_declares_sensors() says whether a run must write sensor files.
"""
import csv
import glob
import json
import math
import os
import re
import shutil
import sys


def read_run(out, ranks, label):
    with open(os.path.join(out, "run.json")) as f:
        meta = json.load(f)
    assert meta["status"] == "completed" and meta["ranks"] == ranks, meta
    frame = meta["frames_written"]
    # glob.escape: the brackets of ClaymoreUW's names are literal, not character classes
    files = sorted(glob.glob(os.path.join(glob.escape(out), "model[[]0]_dev[[]*]_frame" + glob.escape(f"[{frame}].csv"))))
    assert len(files) == ranks, f"{label}: wrote {files}"
    particles = {}
    for name in files:
        read_frame(name, particles, label)
    return meta, particles


def read_frame(name, particles, label):
    """Adds the rows of one frame CSV to `particles` ({ID: [x, y, z, vx, vy, vz]}); an ID already there is an
    error."""
    with open(name) as f:
        rows = csv.reader(f)
        col = {h.split(" [")[0]: i for i, h in enumerate(next(rows))}
        for row in rows:
            pid = int(row[col["ID"]])
            assert pid not in particles, f"{label}: particle {pid} written twice"
            particles[pid] = [float(row[col[k]]) for k in
                              ("Position_X", "Position_Y", "Position_Z", "Velocity_X", "Velocity_Y", "Velocity_Z")]


def cuda_device_count():
    """(count, reason): the CUDA devices the CUDA driver reports (cuInit + cuDeviceGetCount through ctypes, the
    library the fbar binary's runtime loads; CUDA_VISIBLE_DEVICES applies), or (0, why not)."""
    import ctypes
    try:
        cuda = ctypes.CDLL("libcuda.so.1")
    except OSError as e:
        return 0, f"no CUDA driver library (libcuda.so.1: {e})"
    rc = cuda.cuInit(0)
    if rc != 0:
        return 0, f"cuInit failed with CUresult {rc} (100 = CUDA_ERROR_NO_DEVICE)"
    n = ctypes.c_int(0)
    rc = cuda.cuDeviceGetCount(ctypes.byref(n))
    if rc != 0:
        return 0, f"cuDeviceGetCount failed with CUresult {rc}"
    return n.value, "" if n.value else "the driver reports 0 devices"


def visible_gpus_or_skip():
    """The CUDA devices the driver reports; without one, prints why ("no CUDA device: ...", the reason .ci/run
    accepts for a skip) and exits 77 (ctest's SKIP_RETURN_CODE)."""
    gpus, reason = cuda_device_count()
    if gpus == 0:
        print(f"no CUDA device: {reason}: skipped")
        sys.exit(77)
    return gpus


def scene_declares_sensors(scene):
    """Whether a scene file (JSON with // comments) has grid or particle sensors or tracked particles: then a run
    must write sensor or tracker CSV files, and their absence is an error, not a comparison to leave out."""
    def strip_comment(line):
        quotes = 0
        for i, ch in enumerate(line):
            if ch == '"' and (i == 0 or line[i - 1] != "\\"):
                quotes += 1
            elif line.startswith("//", i) and quotes % 2 == 0:
                return line[:i]
        return line

    with open(scene) as f:
        text = "\n".join(strip_comment(line) for line in f)
    return any(f'"{key}"' in text for key in ("grid-sensors", "particle-sensors", "track_particle_id"))


def nan_max(values):
    """The largest of `values`, NaN when any is NaN (Python's max keeps or drops a NaN depending on where it stands,
    so a NaN state would pass a `max(...) < tol` check); 0 for none."""
    m = 0.0
    for v in values:
        if math.isnan(v):
            return v
        m = max(m, v)
    return m


def max_differences(many, one):
    """Largest |dx| and |dv| over the particles of `one` (both dicts from read_run); NaN when a state is NaN."""
    dx = nan_max(abs(a - b) for k in one for a, b in zip(many[k][:3], one[k][:3]))
    dv = nan_max(abs(a - b) for k in one for a, b in zip(many[k][3:], one[k][3:]))
    return dx, dv


SENSOR_PATTERNS = ("gridTarget*.csv", "particleTarget*.csv", "particleTrack*.csv")
FRAME_NAME = re.compile(r"model\[\d+\]_dev\[\d+\]_frame\[(\d+)\]\.")


def copy_up_to_checkpoint(src, dst, checkpoint, frame):
    """dst as a user leaves a run's folder to continue it in place from `checkpoint` (a file name in src, one rank's
    file of the set): src's files, less the frames after `frame`, each sensor / tracker CSV cut to the length the
    checkpoint recorded (its /csv group) and followed by a planted row the restart must cut. A restart that writes
    nothing then leaves missing frames and planted rows, instead of src's own files, behind."""
    import h5py
    shutil.copytree(src, dst)
    for name in os.listdir(dst):
        m = FRAME_NAME.match(name)
        if m and int(m.group(1)) > frame:
            os.remove(os.path.join(dst, name))
    with h5py.File(os.path.join(dst, checkpoint), "r") as f:
        a = f["csv"].attrs  # io/checkpoint.cpp: files, name<i>, bytes<i>
        recorded = []
        for i in range(int(a["files"])):
            name = a[f"name{i}"]
            recorded.append((name.decode() if isinstance(name, bytes) else str(name), int(a[f"bytes{i}"])))
    assert recorded, f"{checkpoint}: the checkpoint recorded no sensor file"
    for name, size in recorded:
        path = os.path.join(dst, name)
        with open(path, "rb") as fh:
            data = fh.read()
        assert len(data) >= size, f"{name}: {len(data)} bytes, the checkpoint recorded {size}"
        with open(path, "wb") as fh:
            fh.write(data[:size] + b"9.99,planted row after the checkpoint\n")


def read_sensors(out):
    """Every sensor and tracker CSV of a run: {file name: (header, rows of floats)}. They are written once per run
    (reduced over the ranks), so each name appears once whatever the rank count."""
    found = {}
    for pattern in SENSOR_PATTERNS:
        for name in glob.glob(os.path.join(glob.escape(out), pattern)):
            with open(name) as f:
                rows = csv.reader(f)
                header = next(rows)
                found[os.path.basename(name)] = (header, [[float(v) for v in row] for row in rows])
    return found


def max_sensor_difference(many, one, label):
    """Checks that `many` has the files, headers and sample times of `one` and returns the largest difference of a
    value relative to its column's largest |value| in `one` (0 for columns that are exactly 0), with where it is."""
    assert many.keys() == one.keys(), f"{label}: sensor files {sorted(many)} against {sorted(one)}"
    worst = (0.0, "")
    for name, (header, rows) in one.items():
        h, r = many[name]
        assert h == header, f"{label}: {name} header {h} against {header}"
        assert len(r) == len(rows), f"{label}: {name} has {len(r)} rows against {len(rows)}"
        for c in range(len(header)):
            scale = nan_max(abs(row[c]) for row in rows if not math.isnan(row[c]))
            for i, (a, b) in enumerate(zip(r, rows)):
                if c == 0:
                    assert a[0] == b[0], f"{label}: {name} row {i}: sample time {a[0]} against {b[0]}"
                    continue
                if math.isnan(b[c]) or math.isnan(a[c]):
                    assert math.isnan(b[c]) and math.isnan(a[c]), f"{label}: {name} row {i} column {header[c]}"
                    continue
                d = abs(a[c] - b[c]) / scale if scale > 0 else abs(a[c] - b[c])
                if d > worst[0]:
                    worst = (d, f"{name} row {i} column {header[c]}: {a[c]} against {b[c]}")
    return worst
