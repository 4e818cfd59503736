#!/usr/bin/env python3
"""`fbar --backend=gpu --gpus=N` (thread ranks) and `mpirun -np 2 fbar --backend=gpu` against one GPU rank.

usage: gpu_cli_ranks_test.py FBAR MPIEXEC SCENE WORKDIR

Runs the scene with --gpus=1, 2 (with the halo overlap off, the default, and on) and 3 (ranks beyond the visible GPUs
share them: peer copies between threads), and,
when two GPUs are visible and MPIEXEC is given, with 2 MPI processes (NCCL). Each rank writes
model0_dev[rank]_frame[f].csv. Checks that every run completes (run.json: status completed, ranks N, the same step
count), that the merged last frame holds every particle ID exactly once, and that positions (double) agree with one
rank's bit for bit (the order-free sums: every rank count writes one rank's values; NaN fails). When the scene has
sensors or trackers, their CSV files (written once, reduced over the ranks) must have the same names, headers, sample
times and values as one rank's. When the scene writes frame checkpoints, the 2-GPU run is also restarted from its
frame-1 checkpoints (--gpus=2 --restart) in a folder holding only what the run had written by then
(frames_by_id.copy_up_to_checkpoint) and must write the same last frame and CSVs. Exit 77 (skipped) without a CUDA
device.
"""
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import frames_by_id  # noqa: E402

fbar, mpiexec, scene, work = sys.argv[1:5]
gpus = frames_by_id.visible_gpus_or_skip()
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
env = dict(os.environ, NCCL_NVLS_ENABLE="0")


def run(label, ranks, prefix, extra):
    out = os.path.join(work, label)
    cmd = prefix + [fbar, "--backend=gpu", "--quiet", f"--output={out}", scene] + extra
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        sys.exit(f"{label}: exit {p.returncode}\n{p.stdout}\n{p.stderr}")
    meta, particles = frames_by_id.read_run(out, ranks, label)
    assert meta["backend"] == "gpu", meta
    return meta["steps"], particles, frames_by_id.read_sensors(out)


steps1, one, sensors1 = run("gpus1", 1, [], [])
# A scene with sensors or trackers must write their CSVs; one without writes none (no comparison is left out).
assert bool(sensors1) == frames_by_id.scene_declares_sensors(scene), \
    f"one GPU wrote sensor files {sorted(sensors1)}; the scene declares sensors: {frames_by_id.scene_declares_sensors(scene)}"
# --keep-gpus: these test scenes are far below the size where several GPUs pay, which fbar would otherwise run on one.
cases = [("gpus2", 2, [], ["--gpus=2", "--keep-gpus"]),
         ("gpus2_overlap", 2, [], ["--gpus=2", "--keep-gpus", "--halo-overlap=on"]),
         ("gpus3", 3, [], ["--gpus=3", "--keep-gpus"])]
if gpus >= 2 and mpiexec:
    cases.append(("mpi2", 2, [mpiexec, "-np", "2", "--allow-run-as-root", "-x", "NCCL_NVLS_ENABLE"], []))
for label, n, prefix, extra in cases:
    steps, many, sensors = run(label, n, prefix, extra)
    assert steps == steps1, f"{label}: {steps} steps, one rank {steps1}"
    assert many.keys() == one.keys(), f"{label}: particle IDs differ ({len(many)} vs {len(one)})"
    dx, dv = frames_by_id.max_differences(many, one)
    print(f"{label}: {len(many)} particles, {steps} steps, max |dx| {dx:.3g} m, max |dv| {dv:.3g} m/s")
    assert dx == 0.0 and dv == 0.0, "states differ from one rank's"  # NaN differs too
    worst, where = frames_by_id.max_sensor_difference(sensors, sensors1, label)
    print(f"{label}: {len(sensors)} sensor and tracker files, largest difference {worst:.3g} of the column ({where})")
    assert worst == 0.0, "sensor or tracker values differ from one rank's"
    restart_from = os.path.join(work, label, "checkpoint_frame[1]_dev[0].h5")
    if label == "gpus2" and os.path.exists(restart_from):
        # Restart equality on 2 GPUs: the run's output up to frame 1, continued from its frame-1 checkpoints (one
        # per rank), writes frame 2 and the CSV rows after frame 1; they must be the run's bytes.
        again = os.path.join(work, "gpus2_restarted")
        frames_by_id.copy_up_to_checkpoint(os.path.join(work, label), again, "checkpoint_frame[1]_dev[0].h5", 1)
        steps_r, restarted, sensors_r = run("gpus2_restarted", 2, [],
                                            ["--gpus=2", "--keep-gpus",
                                             "--restart=" + os.path.join(again, "checkpoint_frame[1]_dev[0].h5")])
        assert steps_r == steps, f"restarted: {steps_r} steps, the run {steps}"
        dx, dv = frames_by_id.max_differences(restarted, many)
        worst, where = frames_by_id.max_sensor_difference(sensors_r, sensors, "restarted")
        print(f"gpus2 restarted from frame 1: max |dx| {dx:.3g} m, max |dv| {dv:.3g} m/s, sensors {worst:.3g} ({where})")
        assert dx == 0.0 and dv == 0.0 and worst == 0.0, "the restarted run differs from the run"
print("ok")
