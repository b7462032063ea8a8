#!/usr/bin/env bash
# What running each daemon job in its own worker process costs: the daemon logs, per job,
# the worker's wall time from spawn to reaping minus the processing time the worker itself
# reports (start-up, recipe load, report hand-over). Runs N jobs of one scan through the
# real daemon with the face-scan recipe and prints the median and range.
#
#   scripts/isolation_cost.sh SCAN_DIR MESH_NAME [N=7]
#   e.g. scripts/isolation_cost.sh ../shared/data/textured/james_face_stereo_capture james.obj
#
# Each copy gets one extra comment line so that it is a new job (same content = one job).
set -euo pipefail
cd "$(dirname "$0")/.."
src=$1 mesh=$2 n=${3:-7}
bin=target/release/scanmill
[ -x "$bin" ] || cargo build --release
lab=$(mktemp -d)
trap 'kill "$daemon" 2>/dev/null || true; rm -rf "$lab"' EXIT
mkdir -p "$lab/in" "$lab/out" "$lab/state"
cat > "$lab/scanmill.toml" <<TOML
state_dir = "$lab/state"
min_free_disk_mb = 1
[[watch]]
path = "$lab/in"
output = "$lab/out"
recipe = "$PWD/config/recipes/face-scan.toml"
quiet_period_secs = 0.5
TOML
SCANMILL_LOG=info "$bin" daemon --config "$lab/scanmill.toml" 2> "$lab/log" &
daemon=$!
for i in $(seq 1 "$n"); do
    d="$lab/in/copy$i"
    mkdir -p "$d"
    for f in "$src"/*; do
        [ "$(basename "$f")" = "$mesh" ] || cp "$f" "$d/"
    done
    { cat "$src/$mesh"; echo "# copy $i"; } > "$d/.$mesh.tmp" && mv "$d/.$mesh.tmp" "$d/$mesh"
    # One job at a time, so that each is measured on a machine that is otherwise idle.
    until [ "$(grep -c 'worker finished' "$lab/log" || true)" -ge "$i" ]; do
        if grep -q ' failed' "$lab/log"; then grep ' failed' "$lab/log" >&2; exit 1; fi
        sleep 0.2
    done
done
figures() { grep 'worker finished' "$lab/log" | sed -E "s/.*isolation_ms=([0-9.]+) process_ms=([0-9.]+).*/\\$1/" | sort -n; }
median() { awk '{ v[NR] = $1 } END { printf "%.1f", v[int((NR + 1) / 2)] }'; }
iso=$(figures 1 | median); proc=$(figures 2 | median)
echo "jobs $n: isolation median $iso ms (min $(figures 1 | head -1), max $(figures 1 | tail -1)); processing median $proc ms; share $(awk "BEGIN { printf \"%.2f\", 100 * $iso / $proc }") %"
