#!/usr/bin/env python3
"""Output that cannot be written: a full disk, a folder that vanishes and one that turns read-only mid-run
(ctest Output.FullDiskAndVanishingFolderAreReported).

usage: output_failure_test.py FBAR SCENE WORKDIR

SCENE is scenes/fem_post_dam_break.json (water breaking against an FEM post), run on the CPU engine with .h5 frames
and a checkpoint every 2 frames. Each case runs fbar in a mount namespace of its own (`unshare --map-root-user
--mount`, or `unshare --mount` as root) whose output folder is a small tmpfs:
- full: 12 MiB (frames of 1.3 MB, checkpoints of 4.2 MB: frames 0-4 and the checkpoint of frame 2 fit, that of
  frame 4 does not). The run must exit with code 2 and print one error line naming the file that failed, the system's
  reason ("No space left on device") and what is complete (the last whole frame, the last checkpoint); none of
  HDF5's own error stack; no .part file left; every frame the message calls complete is there whole (.h5 and
  .xdmf); run.json says "failed" with the same message.
- vanished: the folder is removed once frame 1 is written: exit 2, the message names the file and "No such file or
  directory", and says that run.json could not be kept.
- read-only: the tmpfs is remounted read-only once frame 1 is written: exit 2, "Read-only file system", and the
  message says that run.json keeps the record written when the run started.
The full disk's run.json, written when the run started with room reserved, is rewritten in place and holds the
final record.
"""
import json
import os
import re
import shutil
import subprocess
import sys

fbar, scene_file, work = sys.argv[1:4]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)


def strip_comments(text):
    return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("//"))


with open(scene_file) as f:
    scene = json.loads(strip_comments(f.read()))
# Frames 1/300 s apart (about 35 steps): the disk fills within a few hundred steps.
scene["simulation"].update({"save_suffix": ".h5", "frames": 15, "fps": 300, "checkpoint_every": 2,
                            "precision": "single"})
scene_path = os.path.join(work, "scene.json")
with open(scene_path, "w") as f:
    json.dump(scene, f, indent=1)


def namespace_prefix():
    for prefix in (["unshare", "--map-root-user", "--mount"], ["unshare", "--mount"]):
        if subprocess.run(prefix + ["true"], capture_output=True).returncode == 0:
            return prefix
    sys.exit("cannot make a mount namespace (unshare --map-root-user --mount, unshare --mount): "
             "this test needs one to give fbar a small filesystem")


PREFIX = namespace_prefix()
DATA = os.path.join(os.path.dirname(os.path.abspath(scene_file)), "..", "Data")


def run(label, size, action=""):
    """fbar in a namespace whose output folder ({out}) lies on a tmpfs ({mnt}) of `size`; `action` (shell, with
    {out} and {mnt} filled in) runs once frame 1 is written. Returns (exit code, stderr, run.json or None, the
    folder's file names after the run, the folder where its .h5 / .xdmf / run.json were kept)."""
    case = os.path.join(work, label)
    mnt = os.path.join(case, "mnt")
    out = os.path.join(mnt, "run")
    keep = os.path.join(case, "kept")
    os.makedirs(mnt)
    os.makedirs(keep)
    frame1 = os.path.join(out, "model[0]_dev[0]_frame[1].xdmf")
    action = action.format(out=out, mnt=mnt)
    script = f"""
mount -t tmpfs -o size={size} fbar_test "{mnt}" || exit 90
"{fbar}" --backend=cpu --quiet --data-dir="{DATA}" --output="{out}" "{scene_path}" 2>"{case}/stderr" &
pid=$!
if [ -n '{"1" if action else ""}' ]; then
  while [ ! -e '{frame1}' ] && kill -0 $pid 2>/dev/null; do sleep 0.02; done
  {action}
fi
wait $pid
echo $? > "{case}/rc"
ls "{out}" > "{case}/listing" 2>/dev/null
cp "{out}/run.json" "{keep}/" 2>/dev/null
for f in "{out}"/*.h5 "{out}"/*.xdmf; do [ -e "$f" ] && cp "$f" "{keep}/"; done
exit 0
"""
    p = subprocess.run(PREFIX + ["sh", "-c", script], capture_output=True, text=True, timeout=900,
                       env=dict(os.environ, OMP_NUM_THREADS="2"))
    assert p.returncode == 0, f"{label}: the namespace script failed ({p.returncode}): {p.stdout} {p.stderr}"
    with open(os.path.join(case, "rc")) as f:
        rc = int(f.read())
    with open(os.path.join(case, "stderr")) as f:
        err = f.read()
    listing = []
    if os.path.exists(os.path.join(case, "listing")):
        with open(os.path.join(case, "listing")) as f:
            listing = f.read().split()
    meta = None
    if os.path.exists(os.path.join(keep, "run.json")):
        with open(os.path.join(keep, "run.json")) as f:
            meta = json.load(f)
    print(f"{label}: exit {rc}; stderr:\n{err}")
    return rc, err, meta, listing, keep


def error_line(label, err):
    assert "HDF5-DIAG" not in err and "#000" not in err, f"{label}: HDF5's error stack reached stderr:\n{err}"
    errors = [line for line in err.splitlines() if line.startswith("fbar: error:")]
    assert len(errors) == 1, f"{label}: expected one error line, got {errors}\n{err}"
    return errors[0]


# 1. A full disk.
rc, err, meta, listing, keep = run("full", "12m")
assert rc == 2, f"full: exit {rc}"
line = error_line("full", err)
assert "No space left on device" in line, line
assert re.search(r"cannot (write|close|create|open)[^:]*(model\[\d+\]_dev\[\d+\]_frame\[\d+\]\.h5|checkpoint_frame\[\d+\]_dev\[0\]\.h5)",
                 line), f"full: the message does not name the file that failed: {line}"
m = re.search(r"Complete: frames 0 to (\d+)", line)
assert m, f"full: the message does not say which frames are complete: {line}"
last = int(m.group(1))
assert last >= 1, line
assert not [n for n in listing if n.endswith(".part")], f"full: .part files left: {listing}"
for f in range(last + 1):
    for ext in (".h5", ".xdmf"):
        name = f"model[0]_dev[0]_frame[{f}]{ext}"
        assert name in listing, f"full: {name}, complete by the message, is missing: {listing}"
c = re.search(r"the checkpoint (\S+checkpoint_frame\[(\d+)\]_dev\[0\]\.h5)", line)
assert c, f"full: the message names no complete checkpoint: {line}"
assert os.path.basename(c.group(1)) in listing, f"full: the checkpoint the message names is missing: {listing}"
assert f"--restart={c.group(1)}" in line, line
assert meta is not None, "full: no run.json"
assert meta["status"] == "failed" and meta["exit_code"] == 2, meta["status"]
assert "No space left on device" in meta["message"], meta["message"]
assert meta["frames_written"] == last, (meta["frames_written"], last)
try:  # the last complete frame reads back
    import h5py
    with h5py.File(os.path.join(keep, f"model[0]_dev[0]_frame[{last}].h5"), "r") as h:
        assert h["Position"].shape[1] == 3 and h["Position"].shape[0] > 0
except ImportError:
    sys.exit("h5py is missing (tools/plot/requirements.txt)")

# 2. The folder vanishes mid-run: the frames cannot be written, nor run.json (the message says both).
rc, err, meta, listing, _ = run("vanished", "64m", 'rm -rf "{out}"')
assert rc == 2, f"vanished: exit {rc}"
line = error_line("vanished", err)
assert "No such file or directory" in line and "/run/" in line, line
assert "Complete: frames 0 to " in line, line
assert "cannot write" in line and "run.json" in line, f"vanished: the message does not say run.json is lost: {line}"

# 3. The folder turns read-only mid-run: nothing more can be written there; the message says so for run.json too,
# which holds the record written when the run started.
rc, err, meta, listing, _ = run("read_only", "64m", 'mount -o remount,ro "{mnt}"')
assert rc == 2, f"read_only: exit {rc}"
line = error_line("read_only", err)
assert "Read-only file system" in line, line
assert "Complete: frames 0 to " in line, line
assert "run.json" in line and "status \"running\"" in line, line
assert meta is not None and meta["status"] == "running", meta and meta["status"]
print("ok")
