#!/usr/bin/env bash
# Installs what the Embree columns of `hort bench kernel` and `hort bench samples` need: native
# Embree 3 (Debian's `libembree-dev`) and a C compiler, through apt-get (as root, or with sudo).
# Does nothing when both are already there. Usage: bash eval/embree.sh
set -euo pipefail

have_embree() {
    command -v cc > /dev/null &&
        printf '#include <embree3/rtcore.h>\nint main(void){return 0;}\n' |
        cc -x c - -o /dev/null -lembree3 2> /dev/null
}

if have_embree; then
    echo "Embree 3 and a C compiler are installed."
    exit 0
fi
if ! command -v apt-get > /dev/null; then
    echo "No apt-get here: install Embree 3 (headers and libembree3) and a C compiler with this system's packages." >&2
    exit 1
fi
sudo=()
if [ "$(id -u)" != 0 ]; then
    command -v sudo > /dev/null || { echo "Run as root or install sudo: apt-get needs root." >&2; exit 1; }
    sudo=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -q
"${sudo[@]}" apt-get install -y -q libembree-dev gcc libc6-dev
have_embree || { echo "Embree was installed but a test program does not link against -lembree3." >&2; exit 1; }
echo "Embree 3 and a C compiler are installed."
