#!/usr/bin/env bash
# Instructions per primary and per shadow ray of the BVH kernel on x86-64 (valgrind callgrind)
# and aarch64 (qemu-user with local-emulator/bench/insn_count_plugin.c), on identical rays.
# A developer tool, not run by CI.
#
#   local-emulator/bench/instruction-counts.sh [SCENE ...]      (default: bunny cornell)
#
# SCENE is a bundled scene name (scenes/NAME/NAME.json) or a path to a scene file. SIZE=WxH
# sets the image size (default 320x180, one primary ray per pixel). Needs: cargo, the rustup
# target aarch64-unknown-linux-gnu, gcc-aarch64-linux-gnu (linker and aarch64 libc under
# /usr/aarch64-linux-gnu), qemu-user 7.x with plugin support, valgrind, a host C compiler (cc).
#
# Both architectures run the release build of core/examples/kernel_insns.rs in four chained
# modes (setup, primary, shadow-rays, shadow), each adding one step, plus `packets` (setup +
# the primary rays in 16-ray packets), and count the instructions of the whole process: per
# primary ray = (primary - setup) / primary rays, in packets = (packets - setup) / primary
# rays, per shadow ray = (shadow - shadow-rays) / shadow rays. A digest run per architecture
# (uninstrumented; it also checks that packets give the single-ray answers)
# prints FNV digests of every hit (id, t, barycentrics, leaf index) and every shadow ray and
# answer; "same answers" says whether both architectures agree bit for bit.
set -euo pipefail

cd "$(dirname "$0")/../.."
root=$(pwd)
size=${SIZE:-320x180}
target_dir=${CARGO_TARGET_DIR:-target}
case $target_dir in /*) ;; *) target_dir=$root/$target_dir ;; esac
work=$target_dir/kernel-insns
cross=aarch64-unknown-linux-gnu
sysroot=/usr/aarch64-linux-gnu

die() {
    echo "instruction-counts.sh: $*" >&2
    exit 1
}
need() { # command, how to get it
    command -v "$1" >/dev/null 2>&1 || die "missing '$1' ($2)"
}
need cargo "https://rustup.rs"
need rustc "https://rustup.rs"
need valgrind "apt-get install valgrind"
need cc "apt-get install gcc"
need aarch64-linux-gnu-gcc "apt-get install gcc-aarch64-linux-gnu"
need qemu-aarch64 "apt-get install qemu-user"
[[ -d $(rustc --print sysroot)/lib/rustlib/$cross/lib ]] ||
    die "missing Rust target $cross (rustup target add $cross)"
[[ -d $sysroot/lib ]] || die "missing aarch64 libc in $sysroot (apt-get install gcc-aarch64-linux-gnu)"
qemu-aarch64 -h 2>&1 | grep -q -- '^-plugin' ||
    die "qemu-aarch64 was built without TCG plugin support (no -plugin option)"
[[ $size =~ ^[0-9]+x[0-9]+$ ]] || die "SIZE must look like 320x180, not '$size'"

scenes=("$@")
[[ ${#scenes[@]} -gt 0 ]] || scenes=(bunny cornell)
scene_files=()
for s in "${scenes[@]}"; do
    if [[ -f $s ]]; then
        scene_files+=("$(cd "$(dirname "$s")" && pwd)/$(basename "$s")")
    elif [[ -f scenes/$s/$s.json ]]; then
        scene_files+=("$root/scenes/$s/$s.json")
    else
        die "no scene '$s' (neither a file nor scenes/$s/$s.json)"
    fi
done

mkdir -p "$work"
# Both binaries must come from the same sources: if core/ changes during the two builds
# (someone editing the kernel), build again.
sources_hash() { find core Cargo.toml Cargo.lock -type f -not -path 'core/target/*' -print0 |
    sort -z | xargs -0 sha1sum | sha1sum; }
for attempt in 1 2 3 4; do
    [[ $attempt -lt 4 ]] || die "core/ kept changing during the builds; try again later"
    before=$(sources_hash)
    echo "building (release) ..." >&2
    cargo build --release --quiet -p hort-core --features kernel-insns --example kernel_insns ||
        die "x86-64 build failed"
    CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=${CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER:-aarch64-linux-gnu-gcc} \
        cargo build --release --quiet --target $cross -p hort-core --features kernel-insns \
        --example kernel_insns || die "aarch64 build failed"
    [[ $(sources_hash) == "$before" ]] && break
    echo "core/ changed during the builds; building again" >&2
done
cc -shared -fPIC -O2 -fvisibility=hidden -o "$work/insn_count_plugin.so" \
    local-emulator/bench/insn_count_plugin.c || die "cannot compile the qemu plugin"
x86=$target_dir/release/examples/kernel_insns
arm=$target_dir/$cross/release/examples/kernel_insns
plugin=$work/insn_count_plugin.so

# field NAME LINE: the value of NAME=... in LINE.
field() { sed -n "s/.*\b$1=\([^ ]*\).*/\1/p" <<<"$2"; }

# x86_count / arm_count SCENE MODE: instructions of the whole process running one mode.
x86_count() {
    local log=$work/callgrind.$2.log
    valgrind --tool=callgrind --cache-sim=no --callgrind-out-file="$work/callgrind.$2.out" \
        "$x86" "$1" "$2" "$size" >"$work/callgrind.$2.stdout" 2>"$log" ||
        die "valgrind failed, see $log"
    local n
    n=$(sed -n 's/^summary: *//p' "$work/callgrind.$2.out")
    [[ $n =~ ^[0-9]+$ ]] || die "no instruction total in $work/callgrind.$2.out"
    echo "$n"
}
arm_count() {
    local count=$work/qemu.$2.count log=$work/qemu.$2.log
    rm -f "$count"
    qemu-aarch64 -L $sysroot -plugin "$plugin,out=$count" "$arm" "$1" "$2" "$size" \
        >"$work/qemu.$2.stdout" 2>"$log" || die "qemu-aarch64 failed, see $log"
    local n
    n=$(cat "$count" 2>/dev/null) || die "the qemu plugin wrote no count (see $log)"
    [[ $n =~ ^[0-9]+$ ]] || die "bad count '$n' in $count"
    echo "$n"
}
per_ray() { awk -v a="$1" -v b="$2" -v n="$3" 'BEGIN { if (n > 0) printf "%.1f", (b - a) / n; else printf "-" }'; }
ratio() { awk -v x="$1" -v y="$2" 'BEGIN { if (x > 0 && y != "-") printf "%.2f", y / x; else printf "-" }'; }

dirty=$(GIT_OPTIONAL_LOCKS=0 git status --porcelain -- core 2>/dev/null | head -1)
echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo '?')${dirty:+ + uncommitted changes in core/} (sources sha1 ${before:0:12}), $(rustc --version), $(qemu-aarch64 --version | head -1), $(valgrind --version)"
echo
echo "Instructions per ray, ${size} image, one primary ray per pixel, shadow rays towards the first light (x86-64: x86-64-v2 build as .cargo/config.toml sets it, valgrind callgrind Ir; aarch64: NEON build, qemu-user plugin)."
echo
echo "| scene | triangles | primary rays | x86-64 / primary ray | aarch64 / primary ray | aarch64 / x86-64 | x86-64 / primary ray, x16 packets | aarch64 / primary ray, x16 packets | shadow rays | x86-64 / shadow ray | aarch64 / shadow ray | aarch64 / x86-64 | same answers |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
status=0
for i in "${!scene_files[@]}"; do
    f=${scene_files[$i]}
    name=${scenes[$i]}
    echo "$name ..." >&2
    declare -A xc=() ac=()
    for m in setup primary packets shadow-rays shadow; do
        xc[$m]=$(x86_count "$f" $m)
        ac[$m]=$(arm_count "$f" $m)
    done
    line=$("$x86" "$f" shadow "$size")
    triangles=$(field triangles "$line")
    np=$(field primary_rays "$line")
    ns=$(field shadow_rays "$line")
    xd=$("$x86" "$f" digest "$size" | tail -1)
    ad=$(qemu-aarch64 -L $sysroot "$arm" "$f" digest "$size" | tail -1)
    if [[ $xd == "$ad" ]]; then
        same="yes ($(field primary_digest "$xd") / $(field shadow_digest "$xd"))"
    else
        same="**NO** (x86-64 $xd; aarch64 $ad)"
        status=1
    fi
    xp=$(per_ray "${xc[setup]}" "${xc[primary]}" "$np")
    ap=$(per_ray "${ac[setup]}" "${ac[primary]}" "$np")
    xq=$(per_ray "${xc[setup]}" "${xc[packets]}" "$np")
    aq=$(per_ray "${ac[setup]}" "${ac[packets]}" "$np")
    xs=$(per_ray "${xc[shadow-rays]}" "${xc[shadow]}" "$ns")
    as=$(per_ray "${ac[shadow-rays]}" "${ac[shadow]}" "$ns")
    echo "| $name | $triangles | $np | $xp | $ap | $(ratio "$xp" "$ap") | $xq | $aq | $ns | $xs | $as | $(ratio "$xs" "$as") | $same |"
    {
        echo "$name raw totals (setup primary packets shadow-rays shadow):"
        echo "  x86-64  ${xc[setup]} ${xc[primary]} ${xc[packets]} ${xc[shadow-rays]} ${xc[shadow]}"
        echo "  aarch64 ${ac[setup]} ${ac[primary]} ${ac[packets]} ${ac[shadow-rays]} ${ac[shadow]}"
    } >&2
    unset xc ac
done
exit $status
