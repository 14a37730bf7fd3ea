#!/usr/bin/env bash
# Runs a command against a fresh moto server (S3, SQS, Step Functions) on 127.0.0.1.
#
#   bash tests/s3-servers/with-moto.sh cargo test -p hort-tests --test it s3_conformance::
#
# Installs moto[server] 5.x from PyPI into ${HORT_TOOLS_DIR:-$HOME/.cache/hort-tools}/moto-venv
# the first time, starts `moto_server` on a free port, waits until it answers, exports
#   HORT_TEST_S3_ENDPOINT  http://127.0.0.1:PORT
#   HORT_TEST_S3_BUCKET    hort-test (not created here: tests call S3Store::create_bucket_if_missing)
#   HORT_TEST_S3_ACCESS_KEY / HORT_TEST_S3_SECRET_KEY  (moto accepts any credentials)
#   HORT_TEST_AWS_ENDPOINT the same URL: the one moto server also speaks SQS and Step Functions
#                          (tests/tests/it/aws_moto.rs; moto records executions, it does not run
#                          them)
# runs the command, stops the server on exit, and exits with the command's status.
# The server log goes to $TOOLS/moto-server.log.
set -euo pipefail

if [ "$#" -eq 0 ]; then
    echo "usage: $0 COMMAND [ARGS...]" >&2
    exit 2
fi

tools="${HORT_TOOLS_DIR:-$HOME/.cache/hort-tools}"
venv="$tools/moto-venv"
moto_spec='moto[server]>=5,<6'

if [ ! -x "$venv/bin/moto_server" ]; then
    echo "with-moto: installing $moto_spec into $venv" >&2
    mkdir -p "$tools"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "$moto_spec"
fi

# A free port: bind port 0, read it back, release it (a tiny race, acceptable for tests).
port="$("$venv/bin/python" -c 'import socket
s = socket.socket()
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1])')"
endpoint="http://127.0.0.1:$port"
log="$tools/moto-server.log"

# moto_server, its conditional PUTs made atomic as on S3 (see moto_atomic.py).
"$venv/bin/python" "$(dirname "${BASH_SOURCE[0]}")/moto_atomic.py" -H 127.0.0.1 -p "$port" >"$log" 2>&1 &
server_pid=$!
stop_server() {
    kill "$server_pid" 2>/dev/null || true
    wait "$server_pid" 2>/dev/null || true
}
trap stop_server EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# moto answers GET / with an (empty) bucket list once it is up.
for _ in $(seq 1 100); do
    if ! kill -0 "$server_pid" 2>/dev/null; then
        echo "with-moto: moto_server exited; its log ($log):" >&2
        cat "$log" >&2
        exit 1
    fi
    if "$venv/bin/python" -c "import urllib.request, sys
urllib.request.urlopen('$endpoint/', timeout=1)" 2>/dev/null; then
        break
    fi
    sleep 0.1
done
if ! "$venv/bin/python" -c "import urllib.request
urllib.request.urlopen('$endpoint/', timeout=1)" 2>/dev/null; then
    echo "with-moto: moto_server did not answer at $endpoint within 10 s; its log ($log):" >&2
    cat "$log" >&2
    exit 1
fi

export HORT_TEST_S3_ENDPOINT="$endpoint"
export HORT_TEST_S3_BUCKET="${HORT_TEST_S3_BUCKET:-hort-test}"
export HORT_TEST_S3_ACCESS_KEY="${HORT_TEST_S3_ACCESS_KEY:-testing}"
export HORT_TEST_S3_SECRET_KEY="${HORT_TEST_S3_SECRET_KEY:-testing}"
export HORT_TEST_AWS_ENDPOINT="$endpoint"
echo "with-moto: moto $("$venv/bin/python" -c 'import moto; print(moto.__version__)') at $endpoint (bucket $HORT_TEST_S3_BUCKET)" >&2

status=0
"$@" || status=$?
exit "$status"
