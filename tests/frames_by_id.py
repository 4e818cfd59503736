"""The last frame of a decomposed command-line run, merged by particle ID (tests/comm/mpi_cli_test.py and
tests/gpu_engine/gpu_cli_ranks_test.py).

read_run(out, ranks, label) checks run.json (status completed, `ranks` ranks), finds the last frame's CSV files
(model[0]_dev[rank]_frame[f].csv, one per rank) and returns (run.json as a dict, {ID: [x, y, z, vx, vy, vz]}); a
particle written twice is an error.
"""
import csv
import glob
import json
import os


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
        with open(name) as f:
            rows = csv.reader(f)
            header = next(rows)
            col = {h.split(" [")[0]: i for i, h in enumerate(header)}
            for row in rows:
                pid = int(row[col["ID"]])
                assert pid not in particles, f"{label}: particle {pid} written twice"
                particles[pid] = [float(row[col[k]]) for k in
                                  ("Position_X", "Position_Y", "Position_Z", "Velocity_X", "Velocity_Y", "Velocity_Z")]
    return meta, particles


def max_differences(many, one):
    """Largest |dx| and |dv| over the particles of `one` (both dicts from read_run)."""
    dx = max(max(abs(a - b) for a, b in zip(many[k][:3], one[k][:3])) for k in one)
    dv = max(max(abs(a - b) for a, b in zip(many[k][3:], one[k][3:])) for k in one)
    return dx, dv
