#!/usr/bin/env python3
"""`mpirun -np N fbar --backend=cpu scene.json` against one rank: the same particles by ID in the last frame.

usage: mpi_cli_test.py FBAR MPIEXEC SCENE WORKDIR

Runs the scene on 1 rank (no launcher), 2, 3 and 4 MPI ranks; each rank writes model0_dev[rank]_frame[f].csv. Checks
that every run completes (exit 0, run.json: status completed, ranks N, the same step count), that the merged last
frame holds every particle ID exactly once, and that positions and velocities agree with one rank's to 1e-12
(double precision; the unit test tests/physics/test_decomposition.cpp measures 2e-16 m and 5e-15 m/s).
"""
import csv
import glob
import json
import os
import shutil
import subprocess
import sys

fbar, mpiexec, scene, work = sys.argv[1:5]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
env = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="PASSIVE")


def run(ranks):
    out = os.path.join(work, f"ranks{ranks}")
    cmd = [fbar, "--backend=cpu", "--quiet", f"--output={out}", scene]
    if ranks > 1:
        cmd = [mpiexec, "-np", str(ranks), "--oversubscribe", "--allow-run-as-root"] + cmd
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        sys.exit(f"{ranks} ranks: exit {p.returncode}\n{p.stdout}\n{p.stderr}")
    with open(os.path.join(out, "run.json")) as f:
        meta = json.load(f)
    assert meta["status"] == "completed" and meta["ranks"] == ranks, meta
    frame = meta["frames_written"]
    files = sorted(glob.glob(os.path.join(out, f"model0_dev*_frame{frame}.csv")))
    assert len(files) == ranks, f"{ranks} ranks wrote {files}"
    particles = {}
    for name in files:
        with open(name) as f:
            rows = csv.reader(f)
            header = next(rows)
            col = {h.split(" [")[0]: i for i, h in enumerate(header)}
            for row in rows:
                pid = int(row[col["ID"]])
                assert pid not in particles, f"{ranks} ranks: particle {pid} written twice"
                particles[pid] = [float(row[col[k]]) for k in
                                  ("Position_X", "Position_Y", "Position_Z", "Velocity_X", "Velocity_Y", "Velocity_Z")]
    return meta["steps"], particles


steps1, one = run(1)
for n in (2, 3, 4):
    steps, many = run(n)
    assert steps == steps1, f"{n} ranks: {steps} steps, one rank {steps1}"
    assert many.keys() == one.keys(), f"{n} ranks: particle IDs differ ({len(many)} vs {len(one)})"
    dx = max(max(abs(a - b) for a, b in zip(many[k][:3], one[k][:3])) for k in one)
    dv = max(max(abs(a - b) for a, b in zip(many[k][3:], one[k][3:])) for k in one)
    print(f"{n} ranks: {len(many)} particles, {steps} steps, max |dx| {dx:.3g} m, max |dv| {dv:.3g} m/s")
    assert dx < 1e-12 and dv < 1e-12, "states differ"
print("ok")
