#!/usr/bin/env bash
# Runs one fuzz target under AFL++ (cargo-afl, stable toolchain) for SECONDS.
#
#   bash fuzz/run.sh TARGET SECONDS [--keep]
#
# TARGET is one of: obj manifest split_object shuffle_block asl http (src/lib.rs, TARGETS).
# The run starts from the kept corpus fuzz/corpus/TARGET (and fuzz/dict/TARGET.dict if there is
# one) and writes to ${FUZZ_OUT:-/tmp/hort-fuzz}/TARGET. It prints the executions, the paths
# found and the crashes and hangs, and exits 1 if there was any crash or hang (the inputs are in
# the output folder's crashes/ and hangs/). With --keep, the queue is minimized with afl-cmin and
# the result replaces fuzz/corpus/TARGET.
#
# Installs cargo-afl (which builds AFL++ itself, about a minute and a half) if it is missing.
# Run it under `nice -n 19` on a shared machine.
set -euo pipefail
cd "$(dirname "$0")/.."

target=${1:?usage: fuzz/run.sh TARGET SECONDS [--keep]}
seconds=${2:?usage: fuzz/run.sh TARGET SECONDS [--keep]}
keep=${3:-}
[ -d "fuzz/corpus/$target" ] || { echo "fuzz/run.sh: no target $target (no fuzz/corpus/$target)" >&2; exit 2; }
# FUZZ_IN: start from another folder (e.g. the queue of an earlier run) instead of the corpus.
inputs=${FUZZ_IN:-fuzz/corpus/$target}

command -v cargo-afl >/dev/null || cargo install cargo-afl --locked --version 0.18.2
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-target}/afl
# Only the http target needs the API router (hort-functions without its AWS SDK): the others
# build without it.
features=(--no-default-features --features afl)
[ "$target" = http ] && features=(--features afl)
# FUZZ_NO_BUILD=1: use the binary as built (while another build holds the target folder).
[ -n "${FUZZ_NO_BUILD:-}" ] || cargo afl build --release "${features[@]}" -p hort-fuzz --bin "$target"
binary=$CARGO_TARGET_DIR/release/$target

out=${FUZZ_OUT:-/tmp/hort-fuzz}/$target
rm -rf "$out"
mkdir -p "$out"
dict=()
[ -f "fuzz/dict/$target.dict" ] && dict=(-x "fuzz/dict/$target.dict")

# No CPU binding (the machine is shared), no UI, a crash-reporting core pattern is not needed.
export AFL_NO_AFFINITY=1 AFL_NO_UI=1 AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1
# No -m: the binaries abort on any allocation over 256 MiB themselves (src/capped_alloc.rs).
# -t: 2 s per input (the OBJ and manifest targets write and read files).
cargo afl fuzz -V "$seconds" -t 2000 -i "$inputs" -o "$out" "${dict[@]}" \
  -- "$binary" > "$out/afl.log" 2>&1 || true
# (cargo-afl's exit status after a -V run is not reliable: judge by the statistics file.)
stats=$out/default/fuzzer_stats
[ -f "$stats" ] || { tail -20 "$out/afl.log" >&2; exit 1; }
field() { awk -F' *: *' -v k="$1" '$1 == k { print $2 }' "$stats"; }
echo "fuzz $target: $(field run_time) s, $(field execs_done) executions ($(field execs_per_sec)/s)," \
  "corpus $(field corpus_count), crashes $(field saved_crashes), hangs $(field saved_hangs)"

if [ "$keep" = "--keep" ]; then
  min=$out/cmin
  cargo afl cmin -t 2000 -i "$out/default/queue" -o "$min" -- "$binary" >/dev/null
  rm -rf "fuzz/corpus/$target"
  mkdir -p "fuzz/corpus/$target"
  for f in "$min"/*; do
    cp "$f" "fuzz/corpus/$target/$(sha1sum "$f" | cut -c1-16)"
  done
  echo "fuzz $target: kept $(ls "fuzz/corpus/$target" | wc -l) inputs," \
    "$(du -sk "fuzz/corpus/$target" | cut -f1) kB"
fi

if [ "$(field saved_crashes)" != 0 ] || [ "$(field saved_hangs)" != 0 ]; then
  echo "fuzz $target: findings in $out/default/crashes and $out/default/hangs" >&2
  exit 1
fi
