#!/usr/bin/env python3
"""scanmill's isotropic remesh against MeshLab's isotropic explicit remeshing, measured in
the same run (issue #24).

Development only: not run in CI. Needs pymeshlab (``pip install pymeshlab``, e.g. in a venv:
``python3 -m venv /tmp/pml && /tmp/pml/bin/pip install pymeshlab``) and a release build
(``cargo build --release --bin scanmill --example remesh_quality --example machine_reference``).

Both sides remesh at 1 % of the bounding-box diagonal with 3 iterations. For each scan it
alternates, N times:

- scanmill: ``scanmill process SCAN --recipe R --out DIR --report J`` as a child process,
  timed from start to exit (load, the step, PLY write); R has metrics and preview off, PLY
  output and one step, ``kind = "remesh"``, ``method = "isotropic"``, ``edge_fraction = 0.01``,
  ``iterations = 3``. The step's own wall time is read from the report J. Facefuns gets
  ``--texture example.png`` (its OBJ names no MTL).
- MeshLab: in a child process of this script, ``load_new_mesh``, then
  ``meshing_isotropic_explicit_remeshing(iterations=3, targetlen=PercentageValue(1.0))``
  (1 % of the bounding-box diagonal), then ``save_current_mesh`` to PLY, timed from the load's
  start to the save's end (the Python start-up and pymeshlab's import are left out, which
  favours MeshLab); the filter alone is timed too. Every other parameter keeps its default
  (pymeshlab 2025.7): ``adaptive=False``, ``selectedonly=False``, ``featuredeg=30`` (edges
  whose faces turn by more than 30° are kept as features; scanmill's step has no
  ``feature_angle``), ``checksurfdist=True`` with ``maxsurfdist=1 %`` (a collapse or flip that
  moves the surface by more than 1 % of the diagonal is refused), and the split, collapse,
  swap, smooth and reproject passes all on.

Then ``examples/remesh_quality`` measures each side's last output against the scan with
scanmill's own metrics (one code for both sides): share of triangles with smallest angle
≥ 30°, its 1st percentile and minimum, mean and max surface distance (both directions pooled,
% of the diagonal), flipped faces (normal more than 90° from the input's at the closest
point), and the mean edge length in % of the diagonal (to check that both used 1 %).

It prints each side's median, minimum and maximum wall time, MeshLab's time over scanmill's,
the quality table, the load average, and the machine-speed reference of the face_scan bench
(``examples/machine_reference.rs``) before and after the runs.

  /tmp/pml/bin/python scripts/vs_meshlab_remesh.py [--runs 5] [--scan NAME=PATH[,TEXTURE] ...]
      [--keep DIR]

The default scans are facefuns, james, the bunny and igea from ../shared/data beside the
checkout (``--data`` to point elsewhere).
"""

import argparse
import glob
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from side_by_side import REFERENCE, RELEASE, ROOT, SCANMILL, meshlab_in_child, reference_ms

QUALITY = os.path.join(RELEASE, "examples", "remesh_quality")
DEFAULT_DATA = os.path.join(os.path.dirname(ROOT), "shared", "data")
# name, scan under the data folder, texture for `--texture` (an OBJ that names no MTL).
DEFAULT_SCANS = [
    ("facefuns", "textured/facefuns_di3d_face/example.obj", "textured/facefuns_di3d_face/example.png"),
    ("james", "textured/james_face_stereo_capture/james.obj", None),
    ("bunny", "untextured/stanford_bunny/bun_zipper.ply", None),
    ("igea", "untextured/misc_scans/igea_cyberware_tristrips.ply", None),
]
EDGE_PERCENT = 1.0
ITERATIONS = 3
RECIPE = f"""[output]
format = "ply"

[metrics]
enabled = false

[preview]
enabled = false

[[step]]
kind = "remesh"
method = "isotropic"
edge_fraction = {EDGE_PERCENT / 100}
iterations = {ITERATIONS}
"""


def meshlab_child(scan, out):
    """The MeshLab remesh in this process; prints its seconds (load to save, and the filter
    alone) and the output's face count."""
    import pymeshlab

    start = time.perf_counter()
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(scan)
    filter_start = time.perf_counter()
    ms.meshing_isotropic_explicit_remeshing(
        iterations=ITERATIONS, targetlen=pymeshlab.PercentageValue(EDGE_PERCENT)
    )
    filter_seconds = time.perf_counter() - filter_start
    ms.save_current_mesh(out)
    elapsed = time.perf_counter() - start
    print(f"{elapsed:.4f} {filter_seconds:.4f} {ms.current_mesh().face_number()}")


def run_meshlab(scan, work):
    """Seconds load to save, the filter's seconds, and the output's path."""
    out = os.path.join(work, "meshlab", "out.ply")
    seconds, filter_seconds, _faces = meshlab_in_child(__file__, scan, out)
    return float(seconds), float(filter_seconds), out


def run_scanmill(scan, texture, recipe, work):
    """Seconds from start to exit, the remesh step's wall seconds (from the report), and the
    output's path."""
    out = os.path.join(work, "scanmill")
    report = os.path.join(work, "report.json")
    shutil.rmtree(out, ignore_errors=True)
    command = [SCANMILL, "process", scan, "--recipe", recipe, "--out", out, "--report", report]
    if texture:
        command += ["--texture", texture]
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    seconds = time.perf_counter() - start
    with open(report) as f:
        (step,) = [s for s in json.load(f)["steps"] if s["kind"] == "remesh"]
    (mesh,) = glob.glob(os.path.join(out, "*.ply"))
    return seconds, step["wall_ms"] / 1e3, mesh


def quality(scan, result):
    done = subprocess.run([QUALITY, scan, result], check=True, capture_output=True, text=True)
    return json.loads(done.stdout)


def seconds(values):
    """Median (min–max), in ms below 1 s."""
    m = statistics.median(values)
    if m < 1:
        return f"{1e3 * m:.0f} ms ({1e3 * min(values):.0f}–{1e3 * max(values):.0f})"
    return f"{m:.2f} s ({min(values):.2f}–{max(values):.2f})"


def one_round(i, scan, texture, recipe, work, sample):
    # Alternate which side goes first, so that neither always meets a warm cache.
    if i % 2 == 1:
        sample["meshlab"].append(run_meshlab(scan, work))
    sample["scanmill"].append(run_scanmill(scan, texture, recipe, work))
    if i % 2 == 0:
        sample["meshlab"].append(run_meshlab(scan, work))


def compare(scans, runs, recipe, work):
    """Rounds over every scan, so that a change in the machine's speed meets all scans
    alike; returns each scan's samples."""
    samples = {name: {"scanmill": [], "meshlab": []} for name, _, _ in scans}
    for i in range(runs):
        for name, scan, texture in scans:
            one_round(i, scan, texture, recipe, os.path.join(work, name), samples[name])
    return samples


def print_times(samples):
    print("| scan | scanmill process | scanmill step | MeshLab (load to save) | MeshLab filter | "
          "speed-up (process / step vs filter) |")
    print("|---|---|---|---|---|---|")
    for name, s in samples.items():
        ours = [r[0] for r in s["scanmill"]]
        step = [r[1] for r in s["scanmill"]]
        theirs = [r[0] for r in s["meshlab"]]
        filt = [r[1] for r in s["meshlab"]]
        whole = statistics.median(theirs) / statistics.median(ours)
        alone = statistics.median(filt) / statistics.median(step)
        print(f"| {name} | {seconds(ours)} | {seconds(step)} | {seconds(theirs)} | {seconds(filt)} | "
              f"{whole:.1f}× / {alone:.1f}× |")


def print_quality(scans, samples):
    print("| scan | side | faces | mean edge (% diag) | ≥ 30° | p1 / min angle | "
          "mean / max distance (% diag) | flipped |")
    print("|---|---|---|---|---|---|---|---|")
    for name, scan, _ in scans:
        for side in ("scanmill", "meshlab"):
            q = quality(scan, samples[name][side][-1][2])
            a = q["angles"]
            dropped = f" ({q['dropped_faces']} dropped on load)" if q["dropped_faces"] else ""
            print(f"| {name} | {'MeshLab' if side == 'meshlab' else side} | {q['faces']:,}{dropped} | "
                  f"{q['mean_edge_pct']:.3f} | {100 * a['share_min_angle_30']:.2f} % | "
                  f"{a['min_angle_p1']:.1f}° / {a['min_angle']:.1f}° | "
                  f"{q['distance_mean_pct']:.4f} / {q['distance_max_pct']:.3f} | {q['flipped_faces']} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--scan", action="append", metavar="NAME=PATH[,TEXTURE]")
    parser.add_argument("--data", default=DEFAULT_DATA, help="folder of the default scans")
    parser.add_argument("--keep", metavar="DIR", help="write the outputs here and keep them")
    parser.add_argument("--meshlab-child", nargs=2, metavar=("SCAN", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.meshlab_child:
        meshlab_child(*args.meshlab_child)
        return
    for path in (SCANMILL, REFERENCE, QUALITY):
        if not os.path.exists(path):
            sys.exit(f"{path} missing: cargo build --release --bin scanmill --example remesh_quality "
                     "--example machine_reference")
    if args.scan:
        scans = []
        for s in args.scan:
            name, rest = s.split("=", 1)
            path, _, texture = rest.partition(",")
            scans.append((name, path, texture or None))
    else:
        scans = [(name, os.path.join(args.data, path), texture and os.path.join(args.data, texture))
                 for name, path, texture in DEFAULT_SCANS]
    work = args.keep or tempfile.mkdtemp(prefix="scanmill-vs-meshlab-remesh-")
    try:
        recipe = os.path.join(work, "remesh.toml")
        os.makedirs(work, exist_ok=True)
        with open(recipe, "w") as f:
            f.write(RECIPE)
        before = reference_ms()
        load_before = os.getloadavg()[0]
        print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {args.runs} alternating runs each, "
              f"load average {load_before:.2f}, edge length {EDGE_PERCENT} % of the diagonal, "
              f"{ITERATIONS} iterations")
        samples = compare(scans, args.runs, recipe, work)
        after = reference_ms()
        load_after = os.getloadavg()[0]
        print_times(samples)
        print()
        print_quality(scans, samples)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    print(f"\nmachine-speed reference (face_scan bench's sort): {before:.1f} ms before, {after:.1f} ms after; "
          f"load average {load_before:.2f} before, {load_after:.2f} after the timed runs")


if __name__ == "__main__":
    main()
