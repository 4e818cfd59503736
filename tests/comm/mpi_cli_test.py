#!/usr/bin/env python3
"""`mpirun -np N fbar --backend=cpu scene.json` against one rank: the same particles by ID in the last frame.

usage: mpi_cli_test.py FBAR MPIEXEC SCENE WORKDIR

Runs the scene on 1 rank (no launcher), 2, 3 and 4 MPI ranks; each rank writes model0_dev[rank]_frame[f].csv. Checks
that every run completes (exit 0, run.json: status completed, ranks N, the same step count), that the merged last
frame holds every particle ID exactly once, and that positions and velocities agree with one rank's to 1e-12
(double precision; the unit test tests/engine/cpu/test_decomposition.cpp measures 2e-16 m and 5e-15 m/s). When the scene
has sensors or trackers, their CSV files (written once, reduced over the ranks) must have the same names, headers
and sample times as one rank's, and values within 1e-8 of each column's largest value (the CSVs print 9 digits).
"""
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import frames_by_id  # noqa: E402

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
    meta, particles = frames_by_id.read_run(out, ranks, f"{ranks} ranks")
    return meta["steps"], particles, frames_by_id.read_sensors(out)


steps1, one, sensors1 = run(1)
# A scene with sensors or trackers must write their CSVs; one without writes none (no comparison is left out).
assert bool(sensors1) == frames_by_id.scene_declares_sensors(scene), \
    f"one rank wrote sensor files {sorted(sensors1)}; the scene declares sensors: {frames_by_id.scene_declares_sensors(scene)}"
for n in (2, 3, 4):
    steps, many, sensors = run(n)
    assert steps == steps1, f"{n} ranks: {steps} steps, one rank {steps1}"
    assert many.keys() == one.keys(), f"{n} ranks: particle IDs differ ({len(many)} vs {len(one)})"
    dx, dv = frames_by_id.max_differences(many, one)
    print(f"{n} ranks: {len(many)} particles, {steps} steps, max |dx| {dx:.3g} m, max |dv| {dv:.3g} m/s")
    assert dx < 1e-12 and dv < 1e-12, "states differ"
    # CSV values carry 9 significant digits: sums over ranks agree with one rank's to their last digit.
    worst, where = frames_by_id.max_sensor_difference(sensors, sensors1, f"{n} ranks")
    print(f"{n} ranks: {len(sensors)} sensor and tracker files, largest difference {worst:.3g} of the column ({where})")
    assert worst < 1e-8, "sensor or tracker values differ"
print("ok")
