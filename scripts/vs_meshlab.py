#!/usr/bin/env python3
"""The whole face-scan run against the nearest MeshLab pipeline, side by side (issue #27).

Development only: not run in CI. Needs pymeshlab (``pip install pymeshlab``, e.g. in a venv:
``python3 -m venv /tmp/pml && /tmp/pml/bin/pip install pymeshlab``) and a release build
(``cargo build --release --bin scanmill --example machine_reference``).

For each scan it alternates, N times:

- scanmill: ``scanmill process SCAN --recipe config/recipes/face-scan.toml --out DIR`` as a
  child process (load, relax, fair, decimate to 26,000, seam_fix, normals, metrics, preview,
  write), timed from start to exit;
- MeshLab: load, Taubin smoothing (13 steps of a λ/μ pair), textured quadric edge collapse
  to 26,000 faces (borders kept, as the recipe's ``boundary = "keep"``), per-vertex normals by
  area, save as OBJ; in a child process of this script, timed from the load's start to the
  save's end (the Python start-up and pymeshlab's import are left out, which favours MeshLab).

It prints each side's median, minimum and maximum wall time, scanmill's ratio to MeshLab,
the load average, and the machine-speed reference of the face_scan bench (the median time of
a fixed single-threaded sort, ``examples/machine_reference.rs``), before and after the runs.

  /tmp/pml/bin/python scripts/vs_meshlab.py [--runs 5] [--scan NAME=PATH ...]

The default scans are face400k and coral400k under /tmp/scans (make them with the
``scanner_sized`` example; see scripts/byte_identical.sh and docs/face-scan.md).
"""

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from side_by_side import REFERENCE, ROOT, SCANMILL, meshlab_in_child, reference_ms

RECIPE = os.path.join(ROOT, "config", "recipes", "face-scan.toml")
DEFAULT_SCANS = [
    "face400k=/tmp/scans/face400k/face400k.obj",
    "coral400k=/tmp/scans/coral400k/coral400k.obj",
]
TARGET_FACES = 26000
TAUBIN_STEPS = 13


def meshlab_child(scan, out):
    """The MeshLab pipeline in this process; prints its seconds, load to save."""
    import pymeshlab

    start = time.perf_counter()
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(scan)
    ms.apply_coord_taubin_smoothing(lambda_=0.5, mu=-0.53, stepsmoothnum=TAUBIN_STEPS)
    ms.meshing_decimation_quadric_edge_collapse_with_texture(
        targetfacenum=TARGET_FACES, preserveboundary=True
    )
    ms.compute_normal_per_vertex(weightmode="By Area")
    ms.save_current_mesh(out)
    elapsed = time.perf_counter() - start
    print(f"{elapsed:.4f} {ms.current_mesh().face_number()}")


def run_meshlab(scan, work):
    seconds, faces = meshlab_in_child(__file__, scan, os.path.join(work, "meshlab", "out.obj"))
    return float(seconds), int(faces)


def run_scanmill(scan, work):
    """Seconds from start to exit, and the run's step times (ms) from its report."""
    out = os.path.join(work, "scanmill")
    report = os.path.join(work, "report.json")
    shutil.rmtree(out, ignore_errors=True)
    cpu_before = children_cpu()
    start = time.perf_counter()
    subprocess.run(
        [SCANMILL, "process", scan, "--recipe", RECIPE, "--out", out, "--report", report],
        check=True,
        capture_output=True,
    )
    seconds = time.perf_counter() - start
    with open(report) as f:
        times = step_times(json.load(f))
    times["CPU (user + system)"] = 1e3 * (children_cpu() - cpu_before)
    return seconds, times


def children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def step_times(report):
    """load, each step's wall time, fair's sweeps alone (the rest of its step is the
    texture read-back), and the tail: the total's remainder, which is the set-up before the
    first step (the input's copy and topology, ~65-70 ms on the 400k scans), the metrics,
    the preview and the write."""
    times = {"load": report["load_ms"]}
    for step in report["steps"]:
        times[step["kind"]] = step["wall_ms"]
        if step["kind"] == "fair":
            times["fair sweeps"] = step["figures"]["time_ms"]
    steps = sum(s["wall_ms"] for s in report["steps"])
    times["tail"] = report["total_ms"] - report["load_ms"] - steps
    return times


def spread(values):
    return f"{statistics.median(values):.2f} s ({min(values):.2f}–{max(values):.2f})"


def one_round(i, scan, work, sample):
    """One run of each side on `scan`, into `sample` (lists: ours, theirs, steps, faces)."""
    ours, theirs, steps, faces = sample
    # Alternate which side goes first, so that neither always meets a warm cache.
    if i % 2 == 1:
        seconds, faces[0] = run_meshlab(scan, work)
        theirs.append(seconds)
    seconds, times = run_scanmill(scan, work)
    ours.append(seconds)
    steps.append(times)
    if i % 2 == 0:
        seconds, faces[0] = run_meshlab(scan, work)
        theirs.append(seconds)


def compare(scans, runs, work):
    """Rounds over every scan, so that a change in the machine's speed meets all scans
    alike; prints one row per scan and returns each scan's median step times."""
    samples = {name: ([], [], [], [None]) for name, _ in scans}
    for i in range(runs):
        for name, scan in scans:
            one_round(i, scan, work, samples[name])
    medians = {}
    for name, (ours, theirs, steps, faces) in samples.items():
        ratio = statistics.median(ours) / statistics.median(theirs)
        print(f"| {name} | {spread(ours)} | {spread(theirs)} ({faces[0]} faces) | {ratio:.2f}× |")
        medians[name] = {k: statistics.median(t[k] for t in steps) for k in steps[0]}
    return medians


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--scan", action="append", metavar="NAME=PATH")
    parser.add_argument("--meshlab-child", nargs=2, metavar=("SCAN", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.meshlab_child:
        meshlab_child(*args.meshlab_child)
        return
    for path in (SCANMILL, REFERENCE):
        if not os.path.exists(path):
            sys.exit(f"{path} missing: cargo build --release --bin scanmill --example machine_reference")
    scans = [s.split("=", 1) for s in (args.scan or DEFAULT_SCANS)]
    with tempfile.TemporaryDirectory(prefix="scanmill-vs-meshlab-") as work:
        before = reference_ms()
        print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {args.runs} alternating runs each, "
              f"load average {os.getloadavg()[0]:.2f}")
        print("| scan | scanmill process (face-scan recipe) | MeshLab pipeline | ratio |")
        print("|---|---|---|---|")
        medians = compare(scans, args.runs, work)
        after = reference_ms()
    print("\nscanmill's steps, medians (ms, from the reports):")
    print("| step | " + " | ".join(medians) + " |")
    print("|---|" + "---|" * len(medians))
    for step in next(iter(medians.values())):
        print(f"| {step} | " + " | ".join(f"{m.get(step, 0):.0f}" for m in medians.values()) + " |")
    print(f"machine-speed reference (face_scan bench's sort): {before:.0f} ms before, {after:.0f} ms after; "
          f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
