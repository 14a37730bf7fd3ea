#!/usr/bin/env bash
# The dashboard in a real browser: starts `hort serve` on a free loopback port and headless
# Chromium (Debian's `chromium`, installed with apt-get if missing), then dashboard.py drives
# the page through the DevTools protocol (websocket-client from PyPI, in a venv under the
# target folder): a bundled scene submitted from the form, its image awaited, the DOM checked,
# a screenshot written to $TARGET/browser/dashboard.png.
set -euo pipefail
cd "$(dirname "$0")/../../.."
target="${CARGO_TARGET_DIR:-$PWD/target}"
out="$target/browser"
mkdir -p "$out"

if ! command -v chromium >/dev/null; then
  apt-get update -qq && apt-get install -y -qq chromium >/dev/null
fi
venv="$target/browser-venv"
if ! "$venv/bin/python" -c "import websocket" 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q "websocket-client==1.9.*"
fi
cargo build -q -p hort --bin hort
hort="$target/debug/hort"

work="$(mktemp -d)"
serve_pid="" chrome_pid=""
cleanup() {
  local status=$?
  for pid in $chrome_pid $serve_pid; do
    kill "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
  rm -rf "$work"
  exit "$status"
}
trap cleanup EXIT

"$hort" serve --port 0 --workers 2 --data-dir "$work/data" 2>"$out/serve.log" &
serve_pid=$!
for _ in $(seq 100); do
  grep -q "listening on" "$out/serve.log" && break
  sleep 0.1
done
url="$(grep -o 'listening on http://[0-9.:]*' "$out/serve.log" | head -1 | sed 's/listening on //')/"
[ "$url" != "/" ] || { cat "$out/serve.log" >&2; echo "browser: hort serve did not start" >&2; exit 1; }
echo "browser: hort serve at $url"

chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
  --disable-background-networking --disable-component-update --disable-sync \
  --disable-background-timer-throttling --disable-renderer-backgrounding \
  --disable-backgrounding-occluded-windows \
  --user-data-dir="$work/chrome" --remote-debugging-address=127.0.0.1 \
  --remote-debugging-port=0 about:blank 2>"$out/chromium.log" &
chrome_pid=$!
for _ in $(seq 200); do
  [ -s "$work/chrome/DevToolsActivePort" ] && break
  sleep 0.1
done
[ -s "$work/chrome/DevToolsActivePort" ] \
  || { cat "$out/chromium.log" >&2; echo "browser: chromium did not start" >&2; exit 1; }
port="$(head -1 "$work/chrome/DevToolsActivePort")"

"$venv/bin/python" local-emulator/tests/browser/dashboard.py "$port" "$url" "$out/dashboard.png"
