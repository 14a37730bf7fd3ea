#!/usr/bin/env bash
# Renders one job end to end through the real Lambda binaries, locally: `cargo lambda watch`
# serves the Plan and Worker functions (functions/src/bin/) on the Lambda Invoke API, a moto
# server stands in for S3, and a small driver plays the state machine's part: it uploads a scene
# and its job request, invokes `plan`, then every task of every stage in order, and fetches the
# image. It prints each function's cold start (time to the first answer: the process starts,
# builds its S3 client, serves) and the warm task times, and checks that refused events come
# back as Lambda errors typed Hort.BadInput.
#
#   bash infra/run-lambdas-locally.sh [--release] [SCENE_DIR MAIN_FILE] [OUT.png]
#   # default: scenes/cornell cornell.json, target/lambda-local.png
#
# Needs what tests/s3-servers/with-moto.sh and infra/install-cargo-lambda.sh install. Not run by
# CI (it builds and starts servers; a few minutes).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

release=()
if [[ "${1:-}" == "--release" ]]; then
    release=(--release)
    shift
fi
scene_dir="${1:-scenes/cornell}"
main_file="${2:-cornell.json}"
out="${3:-target/lambda-local.png}"
port="${HORT_LAMBDA_PORT:-9000}"

PATH="$(bash infra/install-cargo-lambda.sh):$PATH"
# Build first, so that the first invocation measures a start, not a compilation.
cargo build "${release[@]}" -p hort-functions --bin plan --bin worker >&2

# with-moto.sh starts moto and exports HORT_TEST_S3_ENDPOINT; the inner script runs under it.
export PORT="$port" SCENE_DIR="$scene_dir" MAIN_FILE="$main_file" OUT="$out"
exec bash tests/s3-servers/with-moto.sh bash -c '
set -euo pipefail
release=("$@")
venv="${HORT_TOOLS_DIR:-$HOME/.cache/hort-tools}/moto-venv"
log=target/lambda-watch.log
cargo lambda watch "${release[@]}" --ignore-changes --invoke-address 127.0.0.1 --invoke-port "$PORT" \
    --env-var HORT_BUCKET=hort-local \
    --env-var HORT_S3_ENDPOINT="$HORT_TEST_S3_ENDPOINT" \
    --env-var AWS_ACCESS_KEY_ID=testing --env-var AWS_SECRET_ACCESS_KEY=testing \
    --env-var AWS_REGION=us-east-1 --env-var AWS_LAMBDA_FUNCTION_MEMORY_SIZE=2048 \
    --package hort-functions >"$log" 2>&1 &
watch_pid=$!
trap "kill $watch_pid 2>/dev/null || true; wait $watch_pid 2>/dev/null || true" EXIT
"$venv/bin/python" - <<'"'"'PY'"'"'
import json, os, sys, time, urllib.request, urllib.error
import boto3

endpoint = os.environ["HORT_TEST_S3_ENDPOINT"]
port = os.environ["PORT"]
scene_dir, main_file, out = os.environ["SCENE_DIR"], os.environ["MAIN_FILE"], os.environ["OUT"]
bucket, job = "hort-local", "local-1"
s3 = boto3.client("s3", endpoint_url=endpoint, region_name="us-east-1",
                  aws_access_key_id="testing", aws_secret_access_key="testing")
s3.create_bucket(Bucket=bucket)
for name in sorted(os.listdir(scene_dir)):
    path = os.path.join(scene_dir, name)
    if os.path.isfile(path):
        s3.upload_file(path, bucket, f"jobs/{job}/scene/{name}")
request = {"scene": main_file,
           "render": {"width": 160, "height": 120, "spp": 1, "splits": 3, "spans": 4,
                      "split_mode": "spatial"},
           "max_concurrency": 0, "task_timeout_seconds": None}
s3.put_object(Bucket=bucket, Key=f"jobs/{job}/manifest.json", Body=json.dumps(request).encode())

def invoke(function, event):
    url = f"http://127.0.0.1:{port}/2015-03-31/functions/{function}/invocations"
    data = json.dumps(event).encode()
    start = time.monotonic()
    for _ in range(600):
        try:
            with urllib.request.urlopen(urllib.request.Request(url, data=data), timeout=120) as r:
                body, error = r.read(), r.headers.get("X-Amz-Function-Error")
            break
        except urllib.error.HTTPError as e:
            body, error = e.read(), "HTTP %d" % e.code
            break
        except (urllib.error.URLError, ConnectionError):
            time.sleep(0.05)  # cargo lambda watch still starting
    else:
        sys.exit("no answer from cargo lambda watch")
    return time.monotonic() - start, json.loads(body or b"null"), error

# Cold starts: the first event of each function names another bucket, which the handler
# refuses before any request, so the time is the start alone (cargo lambda watch starting the
# process, the runtime and the S3 client) plus one round trip.
for function, event in [("plan", {"job": job, "bucket": "elsewhere"}),
                        ("worker", {"job": job, "bucket": "elsewhere", "stage": "combine",
                                    "item": {"task": 0}})]:
    seconds, answer, error = invoke(function, event)
    assert answer.get("errorType") == "Hort.BadInput", answer
    print(f"{function}: cold start to first answer {seconds * 1000:.0f} ms")
seconds, plan, error = invoke("plan", {"job": job, "bucket": bucket})
assert not error, (error, plan)
print(f"plan: planning the job (warm) {seconds * 1000:.0f} ms")
times = {}
for field, stage in [("cast_map", "cast-map"), ("cast_reduce", "cast-reduce"),
                     ("expand", "expand"), ("trace_map", "trace-map"),
                     ("trace_reduce", "trace-reduce")]:
    items = json.loads(s3.get_object(Bucket=bucket, Key=plan["items"][field])["Body"].read())
    for item in items:
        event = {"job": job, "bucket": bucket, "stage": stage, "item": item, "attempt": 0}
        seconds, answer, error = invoke("worker", event)
        assert not error, (stage, item, error, answer)
        times.setdefault(stage, []).append((seconds, answer))
seconds, answer, error = invoke("worker", {"job": job, "bucket": bucket, "stage": "combine",
                                           "item": {"task": 0}, "attempt": 0})
assert not error, (error, answer)
times["combine"] = [(seconds, answer)]
warm = sorted(s for stage in times.values() for s, _ in stage)
print(f"worker: tasks (warm) median {warm[len(warm) // 2] * 1000:.0f} ms, "
      f"slowest {warm[-1] * 1000:.0f} ms, over {len(warm)}")
hits = sum(a.get("split_cache_hits", 0) for stage in times.values() for _, a in stage)
print(f"worker: split cache hits over the job: {hits}")
seconds, answer, error = invoke("worker", {"job": job, "bucket": bucket, "stage": "nonsense"})
print(f"worker: a malformed event answers {error}: {answer}")
assert answer and answer.get("errorType") == "Hort.BadInput", answer
s3.download_file(bucket, f"jobs/{job}/out/image.png", out)
print(f"image: {out} ({os.path.getsize(out)} bytes)")
PY
' run-lambdas "${release[@]}" \
    < /dev/null
