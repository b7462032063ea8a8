"""What the side-by-side scripts against MeshLab share (vs_meshlab.py, vs_meshlab_remesh.py):
the release binaries they run, the machine-speed reference, and running a script's MeshLab
pipeline in a child process (so that its time and memory are its own)."""

import os
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RELEASE = os.path.join(ROOT, "target", "release")
SCANMILL = os.path.join(RELEASE, "scanmill")
REFERENCE = os.path.join(RELEASE, "examples", "machine_reference")


def reference_ms():
    """The machine-speed reference: the median time of a fixed single-threaded sort (ms)."""
    done = subprocess.run([REFERENCE], check=True, capture_output=True, text=True)
    return float(done.stdout.strip())


def meshlab_in_child(script, scan, out):
    """Runs `script --meshlab-child SCAN OUT` in a fresh Python (OUT's folder emptied first)
    and returns the words of its last output line."""
    shutil.rmtree(os.path.dirname(out), ignore_errors=True)
    os.makedirs(os.path.dirname(out))
    done = subprocess.run(
        [sys.executable, os.path.abspath(script), "--meshlab-child", scan, out],
        check=True,
        capture_output=True,
        text=True,
    )
    return done.stdout.strip().splitlines()[-1].split()
