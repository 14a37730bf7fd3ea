#!/usr/bin/env bash
# Regenerates eval/references/: Mitsuba 3 references and its timed sweep for the bundled scenes
# (eval/README.md). Creates a Python venv with Mitsuba from PyPI under target/ when missing.
# Usage: bash eval/references.sh [extra mitsuba_refs.py flags]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
source "$root/eval/mitsuba-venv.sh"
cd "$root"
exec "$venv/bin/python" eval/mitsuba_refs.py eval/references \
    scenes/bunny/bunny.json scenes/cornell/cornell.json scenes/teapot/teapot.json \
    scenes/globe/globe.json "$@"
