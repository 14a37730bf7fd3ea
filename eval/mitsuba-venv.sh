# Sourced by the eval scripts: sets `venv` to a Python venv with Mitsuba 3 from PyPI (under
# target/, made when missing; HORT_MITSUBA_VENV overrides) and exports HORT_MITSUBA_HOME.
# Needs `root` (the repository) set.
venv="${HORT_MITSUBA_VENV:-$root/target/mitsuba-venv}"
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import mitsuba' 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet "mitsuba==3.9.1" "drjit==1.5.0" "numpy>=1.26,<3"
fi
export HORT_MITSUBA_HOME="$venv/home"
mkdir -p "$HORT_MITSUBA_HOME"
