#!/usr/bin/env bash
# Installs cargo-lambda (with the zig linker it cross-links with) from PyPI into a venv under
# target/tools/cargo-lambda-venv ($CARGO_TARGET_DIR/tools/... when CARGO_TARGET_DIR is set),
# once, and prints the folder to put on PATH:
#
#   export PATH="$(bash infra/install-cargo-lambda.sh):$PATH"
#   cargo lambda build --bin worker --bin plan --bin starter
#
# Needs python3 (with venv). Nothing lands outside the target folder. HORT_CARGO_LAMBDA_VENV overrides the
# venv folder.
set -euo pipefail

version='1.9.2'
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="${HORT_CARGO_LAMBDA_VENV:-${CARGO_TARGET_DIR:-$here/../target}/tools/cargo-lambda-venv}"

installed() {
    [[ -x "$venv/bin/cargo-lambda" ]] \
        && "$venv/bin/cargo-lambda" lambda --version 2>/dev/null | grep -q " $version"
}

if ! installed; then
    command -v python3 >/dev/null \
        || { echo "install-cargo-lambda: python3 not found" >&2; exit 2; }
    echo "install-cargo-lambda: installing cargo-lambda $version into $venv" >&2
    mkdir -p "$(dirname "$venv")"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "cargo-lambda==$version" >&2
    installed || { echo "install-cargo-lambda: cargo-lambda $version did not install" >&2; exit 1; }
fi
# cargo finds its subcommand cargo-lambda on PATH; cargo-lambda links with zig from the ziglang
# wheel that cargo-lambda's package depends on, through the venv's python-zig launcher.
cd "$venv/bin" && pwd
