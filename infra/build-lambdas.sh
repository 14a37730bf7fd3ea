#!/usr/bin/env bash
# Builds the Lambda bootstraps (functions/src/bin/) with cargo lambda and prints the size of
# each bootstrap and of its zip (what Lambda receives):
#
#   bash infra/build-lambdas.sh            # debug, arm64: proves they compile and link (CI)
#   bash infra/build-lambdas.sh --release  # release, arm64: what `sam build` deploys
#
# Then, for arm64 (the template's architecture), `sam build` of infra/template.yaml over the same
# build: the SAM CLI's rust-cargolambda method runs `cargo lambda build [--release] --arm64 --bin
# B` for each function in the same target folder, finds it fresh, and copies the bootstraps into
# target/sam-build/<profile>/ (SAM_BUILD_MODE=debug drops --release); the script checks they are
# the bytes built here. One build serves both. The SAM CLI comes from infra/install-sam-cli.sh;
# HORT_SKIP_SAM_BUILD=1 skips this step.
#
# Output: target/lambda/<arch>-<profile>/<bin>/bootstrap (one folder per architecture and
# profile: cargo lambda's default target/lambda/ is shared by all builds). target/ is
# $CARGO_TARGET_DIR when set.
# HORT_LAMBDA_ARCH=x86-64 builds for x86-64 instead; arm64 falls back to x86-64, saying so, when
# rustup cannot add the aarch64-unknown-linux-gnu target. HORT_LAMBDA_BINS overrides the binaries
# (default "worker plan starter api"). cargo-lambda comes from infra/install-cargo-lambda.sh.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

profile=debug
release=()
if [[ "${1:-}" == "--release" ]]; then
    profile=release
    release=(--release)
else
    # A debug build proves that the bootstraps compile and link; without debug info it links
    # faster and takes a quarter of the disk (this is a separate target folder anyway).
    export CARGO_PROFILE_DEV_DEBUG=0
fi
arch="${HORT_LAMBDA_ARCH:-arm64}"
if [[ "$arch" == arm64 ]] && ! rustup target list --installed 2>/dev/null | grep -qx aarch64-unknown-linux-gnu; then
    if ! rustup target add aarch64-unknown-linux-gnu >&2; then
        echo "build-lambdas: cannot add the aarch64 Rust target; building for x86-64 instead" >&2
        arch=x86-64
    fi
fi
bins=()
for bin in ${HORT_LAMBDA_BINS:-worker plan starter api}; do
    bins+=(--bin "$bin")
done
target="${CARGO_TARGET_DIR:-target}"
out="$target/lambda/$arch-$profile"

PATH="$(bash infra/install-cargo-lambda.sh):$PATH"
# `-p hort-functions`: the functions' own dependency features (from the workspace root, cargo
# would unify them with every member's), exactly what `sam build` resolves from functions/.
echo "build-lambdas: cargo lambda build ${release[*]} --$arch -p hort-functions ${bins[*]} --lambda-dir $out" >&2
start=$(date +%s)
cargo lambda build "${release[@]}" "--$arch" -p hort-functions "${bins[@]}" --lambda-dir "$out"
echo "build-lambdas: built in $(( $(date +%s) - start )) s"

# Sizes: the bootstrap, and the zip Lambda receives (deflate, as `sam build` and cargo lambda
# package it).
python3 - "$out" ${HORT_LAMBDA_BINS:-worker plan starter api} <<'PY'
import io, os, sys, zipfile
out, bins = sys.argv[1], sys.argv[2:]
for b in bins:
    path = os.path.join(out, b, "bootstrap")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(path, "bootstrap")
    size = os.path.getsize(path)
    print(f"build-lambdas: {path}: {size / 2**20:.1f} MiB, zipped {len(buf.getvalue()) / 2**20:.1f} MiB")
PY

if [[ "${HORT_SKIP_SAM_BUILD:-}" == 1 ]]; then
    echo "build-lambdas: no sam build (HORT_SKIP_SAM_BUILD=1)" >&2
    exit 0
fi
if [[ "$arch" != arm64 ]]; then
    echo "build-lambdas: no sam build (it builds for the template's arm64 only)" >&2
    exit 0
fi
sam="$(bash infra/install-sam-cli.sh)"
sam_out="$target/sam-build/$profile"
if [[ "$profile" == debug ]]; then
    export SAM_BUILD_MODE=debug
fi
echo "build-lambdas: sam build --template-file infra/template.yaml --build-dir $sam_out" >&2
start=$(date +%s)
"$sam" build --template-file infra/template.yaml --build-dir "$sam_out"
echo "build-lambdas: sam build in $(( $(date +%s) - start )) s"
for pair in WorkerFunction:worker PlanFunction:plan StarterFunction:starter ApiFunction:api; do
    resource="${pair%%:*}" bin="${pair#*:}"
    if [[ ! " ${HORT_LAMBDA_BINS:-worker plan starter api} " == *" $bin "* ]]; then
        continue
    fi
    cmp "$sam_out/$resource/bootstrap" "$out/$bin/bootstrap" \
        || { echo "build-lambdas: sam build's $resource differs from $out/$bin" >&2; exit 1; }
done
echo "build-lambdas: sam build's bootstraps are the bytes built above"
