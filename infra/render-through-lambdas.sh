#!/usr/bin/env bash
# The end-to-end check of the real function binaries: `cargo lambda watch` serves the `plan` and
# `worker` bootstraps (functions/src/bin/) on the Lambda Invoke API, a moto server is the S3
# bucket, and `hort render --lambda-endpoint` runs the state machine on this machine, invoking
# every Plan and Worker task through that API. The image must be byte-identical to
# `hort render --monolithic`, and the functions' log must show that they ran every stage.
#
#   bash infra/render-through-lambdas.sh [--arm64] [SCENE]  # default: scenes/cornell/cornell.json
#
# --arm64: the functions are the aarch64 builds of `plan` and `worker`, run under qemu-user
# (Debian's qemu-user and the aarch64 cross linker, installed with apt-get when missing), so the
# arm64 code Lambda runs renders the same bytes as x86-64's --monolithic.
#
# Installs cargo-lambda (infra/install-cargo-lambda.sh) and moto (tests/s3-servers/with-moto.sh)
# itself. Run by .ci/run. Everything it writes lands in target/lambda-e2e/.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

target=()
label=x86-64
if [[ "${1:-}" == "--arm64" ]]; then
    shift
    label=arm64
    triple=aarch64-unknown-linux-gnu
    target=(--target "$triple")
    if ! command -v aarch64-linux-gnu-gcc >/dev/null || ! command -v qemu-aarch64 >/dev/null; then
        echo "render-through-lambdas: installing the aarch64 cross linker and qemu-user (apt-get)" >&2
        sudo=(); [[ "$(id -u)" == 0 ]] || sudo=(sudo)
        "${sudo[@]}" apt-get update -qq >&2
        DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq \
            gcc-aarch64-linux-gnu libc6-dev-arm64-cross qemu-user >&2
    fi
    rustup target list --installed | grep -qx "$triple" || rustup target add "$triple" >&2
    export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
    export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu"
fi
scene="${1:-scenes/cornell/cornell.json}"
out="target/lambda-e2e/$label"
mkdir -p "$out"
rm -f "$out"/*.pfm "$out"/watch.log

PATH="$(bash infra/install-cargo-lambda.sh):$PATH"
# Build before the watch starts, so that no invocation waits for a compilation.
cargo build -p hort --bin hort >&2
cargo build "${target[@]}" -p hort-functions --bin plan --bin worker >&2

export SCENE="$scene" OUT="$out" LABEL="$label" TARGET="${target[*]}"
exec bash tests/s3-servers/with-moto.sh bash -c '
set -euo pipefail
venv="${HORT_TOOLS_DIR:-$HOME/.cache/hort-tools}/moto-venv"
bucket=hort-lambda-e2e
"$venv/bin/python" -c "import boto3
boto3.client(\"s3\", endpoint_url=\"$HORT_TEST_S3_ENDPOINT\", region_name=\"us-east-1\",
             aws_access_key_id=\"testing\", aws_secret_access_key=\"testing\").create_bucket(Bucket=\"$bucket\")"
port="$("$venv/bin/python" -c "import socket
s = socket.socket()
s.bind((\"127.0.0.1\", 0))
print(s.getsockname()[1])")"
# shellcheck disable=SC2086 # TARGET is empty or "--target TRIPLE"
cargo lambda watch $TARGET --ignore-changes --invoke-address 127.0.0.1 --invoke-port "$port" \
    --concurrency 2 \
    --env-var HORT_BUCKET="$bucket" \
    --env-var HORT_S3_ENDPOINT="$HORT_TEST_S3_ENDPOINT" \
    --env-var AWS_ACCESS_KEY_ID=testing --env-var AWS_SECRET_ACCESS_KEY=testing \
    --env-var AWS_REGION=us-east-1 --env-var AWS_LAMBDA_FUNCTION_MEMORY_SIZE=2048 \
    --package hort-functions >"$OUT/watch.log" 2>&1 &
watch_pid=$!
trap "kill $watch_pid 2>/dev/null || true; wait $watch_pid 2>/dev/null || true" EXIT
for _ in $(seq 1 200); do
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
    kill -0 "$watch_pid" 2>/dev/null || { cat "$OUT/watch.log" >&2; exit 1; }
    sleep 0.1
done

# 6 spp: the samples of each pixel go through both sampler paths (one group of four in SIMD
# lanes, two one by one), so the arm64 lanes are checked against the x86-64 ones too.
settings=(--width 64 --height 48 --spp 6)
hort=target/debug/hort
"$hort" render "$SCENE" "${settings[@]}" --splits 3 --spans 4 --workers 2 \
    --s3-endpoint "$HORT_TEST_S3_ENDPOINT" --bucket "$bucket" \
    --access-key testing --secret-key testing \
    --lambda-endpoint "http://127.0.0.1:$port" --out "$OUT/lambda.pfm"
"$hort" render "$SCENE" "${settings[@]}" --monolithic --out "$OUT/monolithic.pfm"
cmp "$OUT/lambda.pfm" "$OUT/monolithic.pfm"
echo "render-through-lambdas: the image through cargo lambda watch ($LABEL functions) equals x86-64 --monolithic ($(wc -c <"$OUT/lambda.pfm") bytes)"

# The functions, not this process, did the work: one log line per task of every stage.
for stage in cast-map cast-reduce expand trace-map trace-reduce combine; do
    grep -q "worker: $stage task [0-9]* done" "$OUT/watch.log" \
        || { echo "render-through-lambdas: no $stage task in the functions log" >&2; exit 1; }
done
grep -q "plan: done" "$OUT/watch.log" \
    || { echo "render-through-lambdas: no plan invocation in the functions log" >&2; exit 1; }
echo "render-through-lambdas: every stage ran in the worker and plan functions"

# The same scene fused (one split: the plan chooses one Render task per span, no shuffle).
"$hort" render "$SCENE" "${settings[@]}" --splits 1 --spans 4 --workers 2 \
    --s3-endpoint "$HORT_TEST_S3_ENDPOINT" --bucket "$bucket" \
    --access-key testing --secret-key testing \
    --lambda-endpoint "http://127.0.0.1:$port" --out "$OUT/fused.pfm"
cmp "$OUT/fused.pfm" "$OUT/monolithic.pfm"
grep -q "worker: render task [0-9]* done" "$OUT/watch.log" \
    || { echo "render-through-lambdas: no render task in the functions log" >&2; exit 1; }
echo "render-through-lambdas: the fused job (render tasks in the worker function) equals --monolithic too"

# A function error reaches the user with its type: these functions serve another bucket, so the
# Plan function refuses the event (Hort.BadInput, never retried) and the job fails at once.
"$venv/bin/python" -c "import boto3
boto3.client(\"s3\", endpoint_url=\"$HORT_TEST_S3_ENDPOINT\", region_name=\"us-east-1\",
             aws_access_key_id=\"testing\", aws_secret_access_key=\"testing\").create_bucket(Bucket=\"other-bucket\")"
if "$hort" render "$SCENE" "${settings[@]}" --s3-endpoint "$HORT_TEST_S3_ENDPOINT" \
    --bucket other-bucket --access-key testing --secret-key testing \
    --lambda-endpoint "http://127.0.0.1:$port" --out "$OUT/refused.pfm" 2>"$OUT/refused.err"; then
    echo "render-through-lambdas: a job for a bucket the functions do not serve succeeded" >&2
    exit 1
fi
expected="failed in plan: Hort.BadInput: Plan failed: the event names bucket \"other-bucket\", this function serves \"$bucket\""
grep -qF "$expected" "$OUT/refused.err" \
    || { echo "render-through-lambdas: expected \"$expected\" in:" >&2; cat "$OUT/refused.err" >&2; exit 1; }
echo "render-through-lambdas: a refused event fails the job with the function'"'"'s error type and message"
' render-through-lambdas < /dev/null
