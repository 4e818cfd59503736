"""The outputs of decomposed command-line runs, for the rank tests (tests/comm/mpi_cli_test.py,
tests/comm/mpi_placement_test.py, tests/gpu_engine/gpu_cli_ranks_test.py).

read_run(out, ranks, label) checks run.json (status completed, `ranks` ranks), finds the last frame's CSV files
(model[0]_dev[rank]_frame[f].csv, one per rank) and returns (run.json as a dict, {ID: [x, y, z, vx, vy, vz]}); a
particle written twice is an error. read_frame() reads one such file; read_sensors() and max_sensor_difference()
compare the sensor and tracker CSVs; visible_gpus_or_skip() ends a GPU test with exit 77 without a device.
"""
import csv
import glob
import json
import math
import os
import subprocess
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


def visible_gpus_or_skip():
    """The CUDA devices nvidia-smi lists; without one, prints why and exits 77 (ctest's SKIP_RETURN_CODE)."""
    try:
        gpus = subprocess.run(["nvidia-smi", "-L"], capture_output=True, text=True, timeout=60).stdout.count("GPU ")
    except (OSError, subprocess.SubprocessError):
        gpus = 0
    if gpus == 0:
        print("no CUDA device: skipped")
        sys.exit(77)
    return gpus


def max_differences(many, one):
    """Largest |dx| and |dv| over the particles of `one` (both dicts from read_run)."""
    dx = max(max(abs(a - b) for a, b in zip(many[k][:3], one[k][:3])) for k in one)
    dv = max(max(abs(a - b) for a, b in zip(many[k][3:], one[k][3:])) for k in one)
    return dx, dv


SENSOR_PATTERNS = ("gridTarget*.csv", "particleTarget*.csv", "particleTrack*.csv")


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
            scale = max(abs(row[c]) for row in rows)
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
