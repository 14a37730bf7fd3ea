#!/usr/bin/env bash
# Per-sample time on a generated mesh of about a million triangles against Mitsuba 3's
# multijitter sampler, both timed in this run on one thread: `hort bench samples` on the
# mesh, with Mitsuba's time from a sweep of its own made minutes before (eval/README.md).
# The bundled scenes are small; this is the issue's "mesh of ~1M triangles" target.
# Usage: bash eval/mesh-bench.sh [TRIANGLES] (default 1000000); work files in target/mesh-bench.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
triangles="${1:-1000000}"
work="$root/target/mesh-bench"
mkdir -p "$work"
cd "$root"
cargo build --release -p hort
hort=target/release/hort
"$hort" scene generate --triangles "$triangles" --seed 7 --out "$work/mesh.obj" --force
# The generated manifest frames the scene but names no light, which Mitsuba's side needs: one
# point light above and in front, as the default light would sit (the ground is 100 x 60).
python3 - "$work/mesh.json" <<'PY'
import json, sys
path = sys.argv[1]
manifest = json.load(open(path))
manifest.update(lights=[{"kind": "point", "position": [58.0, 115.0, 95.0], "intensity": 80000.0}],
                ambient=0.0, background=[0.0, 0.0, 0.0])
json.dump(manifest, open(path, "w"), indent=1)
PY
source "$root/eval/mitsuba-venv.sh"
# Only the 64-spp timing is used; the 16-spp reference is what the script needs to run.
"$venv/bin/python" eval/mitsuba_refs.py "$work/refs" "$work/mesh.json" \
    --ref-spp 16 --sweep-spp 64 --runs 3 --ref-threads 1
pin=()
if command -v taskset > /dev/null; then pin=(taskset -c "$(($(nproc) - 1))"); fi
"${pin[@]}" "$hort" bench samples "$work/mesh.json" --references "$work/refs" --repeats 3
