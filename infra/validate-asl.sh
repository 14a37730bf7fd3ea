#!/usr/bin/env bash
# Validates the HORT state machine (infra/statemachine.asl.json, or the files given) with npm
# `asl-validator`, installed on first use into ${HORT_TOOLS:-$HOME/.cache/hort-tools} (never into
# the repository). Exit status 0 only if every file is valid.
#
# asl-validator checks the schema (Distributed Map ItemReader/ItemProcessor included) and the
# state graph (missing Next targets, unreachable states). It does not check enum values such as
# JitterStrategy or the syntax of ErrorPath/CausePath: the emulator's loader does, and
# `cargo test -p asl-interpreter` loads this same file.
set -euo pipefail

version=4.0.0
tools="${HORT_TOOLS:-$HOME/.cache/hort-tools}"
validator="$tools/node_modules/.bin/asl-validator"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

if [[ ! -x "$validator" ]] || [[ "$("$validator" --version)" != "$version" ]]; then
  command -v npm >/dev/null || { echo "validate-asl: npm not found (needed to install asl-validator)" >&2; exit 2; }
  mkdir -p "$tools"
  echo "validate-asl: installing asl-validator@$version into $tools" >&2
  npm install --prefix "$tools" --no-audit --no-fund --silent "asl-validator@$version" >&2
fi

if [[ $# -eq 0 ]]; then
  set -- "$here/statemachine.asl.json"
fi
args=()
for file in "$@"; do
  args+=(--json-path "$file")
done
exec "$validator" "${args[@]}"
