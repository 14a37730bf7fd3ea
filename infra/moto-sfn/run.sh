#!/usr/bin/env bash
# A second, third-party Step Functions interpreter: infra/statemachine.asl.json on moto's Step
# Functions engine (moto[server] 5.x from PyPI, a port of LocalStack's ASL interpreter), its
# Lambda tasks reaching the real `plan` and `worker` binaries under `cargo lambda watch`, its S3
# (ItemReader, ResultWriter, and the functions' bucket) on the same moto server. A fused and a
# staged job must give `hort render --monolithic`'s bytes; a job the Plan function refuses must
# end FAILED with Hort.BadInput. What moto's engine cannot run is in infra/moto-sfn/README.md.
#
#   bash infra/moto-sfn/run.sh [fused] [staged] [refused]     # default: all three
#
# moto's engine sends every AWS call it makes to http://localhost:$MOTO_PORT
# (moto/stepfunctions/parser/asl/utils/boto_client.py), so MOTO_PORT names lambda_proxy.py,
# which hands Lambda Invoke requests to `cargo lambda watch` and the rest to moto. Installs moto
# (tests/s3-servers/with-moto.sh's venv) and cargo-lambda (infra/install-cargo-lambda.sh) when
# missing. Writes under target/moto-sfn/. Run by .ci/run.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
repo="$(pwd)"
here="$repo/infra/moto-sfn"
target="${CARGO_TARGET_DIR:-$repo/target}"
out="$target/moto-sfn"
mkdir -p "$out"
venv="${HORT_TOOLS_DIR:-$HOME/.cache/hort-tools}/moto-venv"
[[ -x "$venv/bin/moto_server" ]] || bash tests/s3-servers/with-moto.sh true
PATH="$(bash infra/install-cargo-lambda.sh):$PATH"
# Build before the watch starts, so that no invocation waits for a compilation.
cargo build -p hort --bin hort >&2
cargo build -p hort-functions --bin plan --bin worker >&2

free() { "$venv/bin/python" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
moto=$(free) proxy=$(free) lambda=$(free)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT
MOTO_PORT=$proxy "$venv/bin/moto_server" -H 127.0.0.1 -p "$moto" >"$out/moto.log" 2>&1 &
pids+=($!)
"$venv/bin/python" "$here/lambda_proxy.py" "$proxy" "$moto" "$lambda" >"$out/proxy.log" 2>&1 &
pids+=($!)
bucket=hort-moto-sfn
cargo lambda watch --ignore-changes --invoke-address 127.0.0.1 --invoke-port "$lambda" \
    --concurrency 2 \
    --env-var HORT_BUCKET=$bucket --env-var HORT_S3_ENDPOINT="http://127.0.0.1:$moto" \
    --env-var AWS_ACCESS_KEY_ID=testing --env-var AWS_SECRET_ACCESS_KEY=testing \
    --env-var AWS_REGION=us-east-1 --env-var AWS_LAMBDA_FUNCTION_MEMORY_SIZE=2048 \
    --package hort-functions >"$out/watch.log" 2>&1 &
pids+=($!)
for port in $moto $proxy $lambda; do
    for _ in $(seq 1 600); do (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break; sleep 0.1; done
done
status=0
for mode in ${@:-fused staged refused}; do
    EP="http://127.0.0.1:$moto" MODE=$mode BUCKET=$bucket REPO="$repo" OUT="$out" \
        HORT_BIN="$target/debug/hort" \
        "$venv/bin/python" "$here/drive.py" || status=1
done
for stage in render cast-map cast-reduce expand trace-map trace-reduce combine; do
    echo "moto-sfn: worker '$stage' tasks done in the functions' log: $(grep -c "worker: $stage task [0-9]* done" "$out/watch.log" || true)"
done
echo "moto-sfn: Lambda invocations through the proxy: $(grep -c invocations "$out/proxy.log" || true)"
exit $status
