#!/usr/bin/env python3
"""Fails CI on a skipped test that is not a GPU test skipping for want of a CUDA device.

usage: check_skips.py JUNIT_XML BUILD_DIR

JUNIT_XML is ctest's --output-junit file (each test's status and output); BUILD_DIR is where `ctest --show-only=json-v1`
reads each test's labels. A skip is accepted only when the test has the label `gpu` and its output says
"no CUDA device" (FBAR_REQUIRE_DEVICE, the Python GPU tests' frames_by_id.visible_gpus_or_skip). Any other skip (a
missing Python package, MPI, a test that cannot run in this build) fails: CI installs what the tests need. Prints
the count of passed, failed, accepted and refused skips.
"""
import json
import subprocess
import sys
import xml.etree.ElementTree as ET

junit, build = sys.argv[1], sys.argv[2]
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
    if "gpu" in labels.get(name, set()) and "no CUDA device" in out:
        accepted.append(name)
    else:
        refused.append((name, reason.strip()))
print(f"ci: {ran} tests ran, {len(accepted)} GPU tests skipped (no CUDA device), {len(refused)} other skips")
for name, reason in refused:
    print(f"ci: unexpected skip: {name}: {reason}")
sys.exit(1 if refused else 0)
