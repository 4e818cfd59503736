#!/usr/bin/env python3
"""Fails CI on a skipped test that is not a GPU test skipping for want of a CUDA device.

usage: check_skips.py JUNIT_XML BUILD_DIR [--gpu-machine]

JUNIT_XML is ctest's --output-junit file (each test's status and output); BUILD_DIR is where `ctest --show-only=json-v1`
reads each test's labels. A skip is accepted only when the test has the label `gpu` and its output says
"no CUDA device" (FBAR_REQUIRE_DEVICE, the Python GPU tests' frames_by_id.visible_gpus_or_skip). Any other skip (a
missing Python package, MPI, a test that cannot run in this build) fails: CI installs what the tests need. Prints
the count of passed, failed, accepted and refused skips.

--gpu-machine (tools/benchmark/run_gpu_tests.sh, on a machine with a GPU): the accepted skips are then a GPU test's
"needs N GPUs, M visible" (the machine has fewer) and the one test that exists for machines without a GPU ("a CUDA
device is present"); "no CUDA device", a build without NCCL or anything else fails there.
"""
import json
import subprocess
import sys
import xml.etree.ElementTree as ET

junit, build = sys.argv[1], sys.argv[2]
gpu_machine = "--gpu-machine" in sys.argv[3:]
GPU_MACHINE_REASONS = ("GPUs, ", "a CUDA device is present")  # "needs 2 GPUs, 1 visible"; test_cli_gpu.cu's fallback


def accepted_skip(name, out):
    if "gpu" not in labels.get(name, set()):
        return False
    if gpu_machine:
        return any(r in out for r in GPU_MACHINE_REASONS) and "no CUDA device" not in out
    return "no CUDA device" in out


listing = json.loads(subprocess.run(["ctest", "--test-dir", build, "--show-only=json-v1"], check=True,
                                    capture_output=True, text=True).stdout)
labels = {}
for t in listing["tests"]:
    for prop in t.get("properties", []):
        if prop["name"] == "LABELS":
            labels[t["name"]] = set(prop["value"])
accepted, refused, ran = [], [], 0
for case in ET.parse(junit).getroot().iter("testcase"):
    name = case.get("name")
    if case.find("skipped") is None:
        ran += 1
        continue
    out = (case.findtext("system-out") or "").strip()
    reason = next((line for line in out.splitlines() if "SKIPPED" in line or "skipped" in line or "no CUDA device" in line),
                  out[-300:])
    if accepted_skip(name, out):
        accepted.append(name)
    else:
        refused.append((name, reason.strip()))
why = "fewer GPUs than they need" if gpu_machine else "no CUDA device"
print(f"ci: {ran} tests ran, {len(accepted)} GPU tests skipped ({why}), {len(refused)} other skips")
for name, reason in refused:
    print(f"ci: unexpected skip: {name}: {reason}")
sys.exit(1 if refused else 0)
