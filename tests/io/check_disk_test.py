"""`fbar --check`'s disk figures against the frames a run writes (ctest Check.DiskPerFrame).

usage: check_disk_test.py FBAR WORKDIR

For each frame format (.bgeo, .geo, .csv, .h5 in single and double precision) a scene of two bodies with different
attributes is checked, then run on the CPU engine for one frame. --check's "frame on disk" of each body must match
the size of that body's frame file (the .h5 with its .xdmf): .bgeo exactly, .h5 within 2 KiB (the HDF5 library's
own structures, allocated in 2 KiB blocks, are estimated), .csv and .geo from 10 % below to 50 % above (text: each
number's length is estimated, high for round numbers); "disk per frame" is the sum of the bodies' figures and "disk for frames" covers frames 0..frames.
"""
import json
import os
import re
import shutil
import subprocess
import sys

fbar, work = sys.argv[1:3]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
FRAMES = 1
scene = {
    "simulation": {"domain": [0.4, 0.4, 0.4], "default_dx": 0.02, "default_dt": 1e-3, "fps": 100, "frames": FRAMES},
    "bodies": [
        {"material": {"constitutive": "JFluid", "bulk_modulus": 2e5, "viscosity": 0.001},
         "geometry": [{"object": "Box", "span": [0.2, 0.1, 0.1], "offset": [0.1, 0.04, 0.1]}],
         "output_attribs": ["ID", "Velocity_X", "Velocity_Y", "Velocity_Z", "Pressure", "J"]},
        {"material": {"constitutive": "FixedCorotated", "youngs_modulus": 1e5, "poisson_ratio": 0.3, "rho": 500},
         "geometry": [{"object": "Box", "span": [0.06, 0.06, 0.06], "offset": [0.16, 0.2, 0.16]}],
         "output_attribs": ["ID", "Mass", "VonMisesStress", "DefGrad_XX", "StressCauchy_YY"]},
    ],
    "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [0.02, 0.02, 0.02],
                    "domain_end": [0.38, 0.38, 0.38]}],
}
# (bytes, fraction of the file) the figure may be below the file's size, and above it: text estimates err high (a
# solid's round numbers, Mass and DefGrad near 1, write shorter than 11 characters).
TOLERANCE = {".bgeo": ((0, 0.0), (0, 0.0)), ".h5": ((2048, 0.0), (2048, 0.0)), ".csv": ((0, 0.10), (0, 0.50)),
             ".geo": ((0, 0.10), (0, 0.50))}


def figure(line):
    """The exact byte figure "(123456 B)" of a --check row."""
    return int(re.search(r"\((\d+) B\)", line)[1])


for suffix, precision in ((".bgeo", "single"), (".geo", "single"), (".csv", "double"), (".h5", "single"),
                          (".h5", "double")):
    label = f"{suffix} {precision}"
    scene["simulation"].update(save_suffix=suffix, precision=precision)
    out = os.path.join(work, f"{suffix[1:]}_{precision}")
    path = out + ".json"
    with open(path, "w") as f:
        json.dump(scene, f)
    check = subprocess.run([fbar, "--check", f"--file={path}"], capture_output=True, text=True, check=True).stdout
    bodies = [figure(line) for line in check.splitlines() if line.strip().startswith("frame on disk")]
    per_frame = [figure(line) for line in check.splitlines() if line.strip().startswith("disk per frame")]
    all_frames = [line for line in check.splitlines() if line.strip().startswith("disk for frames")]
    assert len(bodies) == 2 and len(per_frame) == 1 and len(all_frames) == 1, check
    assert abs(per_frame[0] - sum(bodies)) <= 1, (label, per_frame, bodies)
    assert f"for the {FRAMES + 1} frames 0..{FRAMES}" in all_frames[0], all_frames
    subprocess.run([fbar, "--backend=cpu", "--quiet", f"--file={path}", f"--output={out}"], check=True)
    for b, estimate in enumerate(bodies):
        name = os.path.join(out, f"model[{b}]_dev[0]_frame[{FRAMES}]{suffix}")
        size = os.path.getsize(name)
        if suffix == ".h5":
            size += os.path.getsize(name[:-3] + ".xdmf")
        (below_b, below_f), (above_b, above_f) = TOLERANCE[suffix]
        low, high = size - below_b - below_f * size, size + above_b + above_f * size
        print(f"{label} body {b}: --check {estimate} B, written {size} B ({estimate - size:+d} B, "
              f"{100.0 * (estimate - size) / size:+.1f} %; allowed {low:.0f} .. {high:.0f})")
        assert low <= estimate <= high, f"{label} body {b}: --check says {estimate} B, the file has {size} B"
print("ok")
