#!/usr/bin/env bash
# Regenerates eval/references/: Mitsuba 3 references and its timed sweep for the bundled scenes
# (eval/README.md). Creates a Python venv with Mitsuba from PyPI under target/ when missing.
# Usage: bash eval/references.sh [extra mitsuba_refs.py flags]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="${HORT_MITSUBA_VENV:-$root/target/mitsuba-venv}"
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import mitsuba' 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet "mitsuba==3.9.1" "drjit==1.5.0" "numpy>=1.26,<3"
fi
export HORT_MITSUBA_HOME="$venv/home"
mkdir -p "$HORT_MITSUBA_HOME"
cd "$root"
exec "$venv/bin/python" eval/mitsuba_refs.py eval/references \
    scenes/bunny/bunny.json scenes/cornell/cornell.json scenes/teapot/teapot.json \
    scenes/globe/globe.json "$@"
