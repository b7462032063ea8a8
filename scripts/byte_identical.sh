#!/usr/bin/env bash
# Shows that a change leaves the product's output as it was: runs
#   scanmill process SCAN --recipe config/recipes/face-scan.toml --out DIR --report R.json
# with a baseline binary and a new one on every textured scan in ../shared/data/textured and on
# face400k, then compares every output file byte for byte (OBJ, MTL, textures, preview PNG) and
# every figure of the report. Only what differs from run to run by nature is left out of the
# comparison: wall and CPU times, rates, peak memory, and paths.
#
#   scripts/byte_identical.sh BASELINE_BINARY [NEW_BINARY=target/release/scanmill] [FACE400K]
#
# FACE400K defaults to /tmp/scans/face400k/face400k.obj; make it with
#   cargo run --release --example scanner_sized -- \
#     ../shared/data/textured/facefuns_di3d_face/example.obj /tmp/scans/face400k/face400k.obj \
#     400000 0.1 ../shared/data/textured/facefuns_di3d_face/example.png
# The baseline's outputs are kept in $SCANMILL_IDENTICAL_DIR (default /tmp/scanmill-identical),
# keyed by the binary's and the recipe's hash, so that a series of checks runs the baseline
# once. When a change respells the recipe (the new spelling must mean the same, with the same
# recipe hash), $SCANMILL_IDENTICAL_BASE_RECIPE names the recipe file the baseline reads, e.g.
# `git show main:config/recipes/face-scan.toml > /tmp/face-scan-before.toml`.
# Exits 0 when everything is identical, 1 with one line per difference otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
base_bin=$(realpath "$1")
new_bin=$(realpath "${2:-target/release/scanmill}")
face400k=${3:-/tmp/scans/face400k/face400k.obj}
work=${SCANMILL_IDENTICAL_DIR:-/tmp/scanmill-identical}
recipe=config/recipes/face-scan.toml
base_recipe=${SCANMILL_IDENTICAL_BASE_RECIPE:-$recipe}
data=../shared/data/textured

# name|mesh|texture (the texture only where the OBJ names no material library; see
# docs/face-scan.md: facefuns is paired with its PNG, spot has no MTL and runs without one).
scans=(
    "james|$data/james_face_stereo_capture/james.obj|"
    "facefuns|$data/facefuns_di3d_face/example.obj|$data/facefuns_di3d_face/example.png"
    "lee_perry_smith|$data/lee_perry_smith_head/LeePerrySmith_converted.obj|"
    "nefertiti|$data/nefertiti_bust_fraunhofer/Nefertiti_converted.obj|"
    "ict|$data/ict_facekit_neutral/generic_neutral_mesh.obj|"
    "esp32cam|$data/esp32cam_meshroom_raw/texturedMesh.obj|"
    "pizza|$data/pizza_rigsters_photogrammetry/pizza.obj|"
    "usnm|$data/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz|"
    "spot|$data/spot_keenan_crane/spot_triangulated.obj|"
    "face400k|$face400k|"
)

# run BINARY RECIPE DIR: every scan into DIR/NAME/out with its report at DIR/NAME/report.json.
run() {
    local bin=$1 recipe=$2 dir=$3 entry name mesh texture
    for entry in "${scans[@]}"; do
        IFS='|' read -r name mesh texture <<< "$entry"
        [ -f "$mesh" ] || { echo "missing scan: $mesh" >&2; exit 2; }
        rm -rf "${dir:?}/$name"
        mkdir -p "$dir/$name"
        "$bin" process "$mesh" --recipe "$recipe" --out "$dir/$name/out" \
            --report "$dir/$name/report.json" ${texture:+--texture "$texture"} \
            > "$dir/$name/stdout" 2> "$dir/$name/stderr" \
            || echo "exit $?" > "$dir/$name/exit"
    done
}

base_dir=$work/base-$(cat "$base_bin" "$base_recipe" | sha256sum | cut -c1-16)
if [ ! -f "$base_dir/.complete" ]; then
    run "$base_bin" "$base_recipe" "$base_dir"
    touch "$base_dir/.complete"
fi
new_dir=$work/new
run "$new_bin" "$recipe" "$new_dir"

python3 - "$base_dir" "$new_dir" "${scans[@]}" <<'PY'
import filecmp, json, os, re, sys

base, new, entries = sys.argv[1], sys.argv[2], sys.argv[3:]
# Figures that are not output: times, rates, memory, and where files were.
VOLATILE_SUFFIXES = ("_ms", "_seconds", "_per_second", "peak_rss_bytes", "peak_rss_mb")
VOLATILE_KEYS = {"path", "time_ms", "wall_ms", "render_ms", "cpu_seconds", "peak_rss"}

def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items()
                if k not in VOLATILE_KEYS and not k.endswith(VOLATILE_SUFFIXES)}
    if isinstance(x, list):
        return [strip(v) for v in x]
    return x

def diff(a, b, where, out):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{where}.{k}: only in {'new' if k in b else 'baseline'}")
            else:
                diff(a[k], b[k], f"{where}.{k}", out)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            diff(x, y, f"{where}[{i}]", out)
    elif a != b or type(a) is not type(b):
        out.append(f"{where}: {a!r} -> {b!r}")

def messages(run_dir, name, f):
    """A run's stderr or exit status with its own folder and the elapsed time taken out."""
    p = os.path.join(run_dir, name, f)
    text = open(p).read() if os.path.exists(p) else ""
    return re.sub(r"\d+ ms\)", "N ms)", text.replace(run_dir, "RUN"))

failures = []
for entry in entries:
    name = entry.split("|")[0]
    b, n = os.path.join(base, name), os.path.join(new, name)
    for f in ("exit", "stderr"):
        tb, tn = messages(base, name, f), messages(new, name, f)
        if tb != tn:
            failures.append(f"{name}: {f} differs: {tb.strip()!r} -> {tn.strip()!r}")
    files_b = sorted(os.listdir(os.path.join(b, "out"))) if os.path.isdir(os.path.join(b, "out")) else []
    files_n = sorted(os.listdir(os.path.join(n, "out"))) if os.path.isdir(os.path.join(n, "out")) else []
    if files_b != files_n:
        failures.append(f"{name}: output files {files_b} -> {files_n}")
    for f in sorted(set(files_b) & set(files_n)):
        if not filecmp.cmp(os.path.join(b, "out", f), os.path.join(n, "out", f), shallow=False):
            failures.append(f"{name}: {f} differs")
    rb, rn = os.path.join(b, "report.json"), os.path.join(n, "report.json")
    if os.path.exists(rb) != os.path.exists(rn):
        failures.append(f"{name}: report.json only in one run")
    elif os.path.exists(rb):
        out = []
        diff(strip(json.load(open(rb))), strip(json.load(open(rn))), "report", out)
        failures += [f"{name}: {d}" for d in out]
    print(f"{name}: {len(files_n)} files compared, report compared", file=sys.stderr)

for line in failures:
    print(line)
print("identical" if not failures else f"{len(failures)} differences", file=sys.stderr)
sys.exit(1 if failures else 0)
PY
