#!/usr/bin/env bash
# Create (if missing) and fill the project's virtualenv from the pinned requirements.
#
# Usage: bash scripts/setup_env.sh
#   GP_VENV=DIR     venv location (default: .venv at the repository root; relative = from the root)
#   GP_PYTHON=EXE   interpreter used to create the venv (default: python3.11, else python3 >= 3.10)
#
# Installs requirements/lock.txt (exact pins, ROS 2 Jazzy wheels included, with the CMake, ament and
# rosidl build wheels), then the package itself with `pip install --no-deps -e .`, then builds the
# interface package geodesic_planner_interfaces (ament_cmake + rosidl, ~15 s) into the venv with
# `pip install --no-build-isolation` (scikit-build-core; see geodesic_planner_interfaces/pyproject.toml):
# its files land where the ROS wheels put theirs, so the venv's python imports it with no environment.
# `pip install -e .` also compiles the C kernels (geodesic_planner/core/_kernels*.c, about 1 s).
# A stamp file inside the venv records the sha256 of lock.txt, setup.py, pyproject.toml, the kernels' source and
# the interface package's sources: when it matches, all of this is skipped (re-runs take well under a second).
# pip's output goes to a log file; on failure its tail is printed and the script exits non-zero.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${GP_VENV:-.venv}"
case "$venv" in /*) ;; *) venv="$root/$venv" ;; esac
lock="$root/requirements/lock.txt"
stamp="$venv/.geodesic_planner_stamp"

say() { printf 'setup_env: %s\n' "$*" >&2; }
die() { printf 'setup_env: ERROR: %s\n' "$*" >&2; exit 1; }

pick_python() {
    if [ -n "${GP_PYTHON:-}" ]; then
        command -v "$GP_PYTHON" >/dev/null 2>&1 || die "GP_PYTHON=$GP_PYTHON not found"
        echo "$GP_PYTHON"; return
    fi
    local c
    for c in python3.11 python3; do
        if command -v "$c" >/dev/null 2>&1 &&
           "$c" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else 1)' 2>/dev/null; then
            echo "$c"; return
        fi
    done
    die "no Python >= 3.10 found (python3.11 preferred: the ROS 2 Jazzy wheels are built for CPython 3.11); set GP_PYTHON"
}

[ -f "$lock" ] || die "missing $lock"
interfaces="$root/geodesic_planner_interfaces"
stamp_inputs() {  # every file whose change needs a new set-up, in a fixed order
    printf '%s\n' "$lock" "$root/setup.py" "$root/pyproject.toml" "$root/geodesic_planner/core/_kernels.c" \
        "$root/geodesic_planner/core/_kernels_timing.c" "$root/geodesic_planner/core/_kernels.h"
    (cd "$interfaces" && find . -type f \( -name '*.msg' -o -name '*.srv' -o -name '*.txt' -o -name '*.xml' \
        -o -name '*.cmake' -o -name '*.toml' \) -not -path './build/*' | LC_ALL=C sort | sed "s|^\.|$interfaces|")
}
want="$(stamp_inputs | while IFS= read -r f; do cat "$f"; done | sha256sum | cut -d" " -f1)"

# Fast path: venv present, stamp matches.
if [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    exit 0
fi

mkdir -p "$venv"
# Serialise concurrent set-ups of the same venv (e.g. demo.sh and test.sh started together).
exec 9>"$venv/.setup-lock"
flock 9
# Another process may have finished the job while we waited.
if [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    exit 0
fi

log="$(mktemp "${TMPDIR:-/tmp}/geodesic_planner_setup.XXXXXX.log")"
run() {  # run a command with its output in $log; on failure show the tail and stop
    if ! "$@" >>"$log" 2>&1; then
        say "command failed: $*"
        grep -v -E '^WARNING: Location .* is ignored' "$log" | tail -n 40 >&2
        say "full log: $log"
        exit 1
    fi
}

if [ ! -x "$venv/bin/python" ]; then
    py="$(pick_python)"
    "$py" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' ||
        say "warning: $py is not Python 3.11; the pinned ROS 2 Jazzy wheels (cp311) may not install"
    say "creating venv $venv with $("$py" -c 'import sys; print(sys.executable, sys.version.split()[0])')"
    if ! "$py" -m venv "$venv" >>"$log" 2>&1; then
        cat "$log" >&2
        die "could not create the venv with $py (on Debian: apt-get install python3-venv)"
    fi
fi

say "installing pinned requirements into $venv (requirements/lock.txt)..."
t0=$SECONDS
run "$venv/bin/python" -m pip install --disable-pip-version-check -q -r "$lock"
run "$venv/bin/python" -m pip install --disable-pip-version-check -q --no-deps -e "$root"
say "building the interface package geodesic_planner_interfaces (rosidl, C and C++ compilers)..."
command -v cc >/dev/null 2>&1 && command -v c++ >/dev/null 2>&1 ||
    die "no C/C++ compiler (cc, c++) for the interface package: on Debian, apt-get install build-essential"
# The ament index and CMake's package search both need the venv prefix at configure time; the pinned
# cmake wheel is on PATH first. A build directory inside the venv makes re-builds incremental.
run env PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv" \
    "$venv/bin/python" -m pip install --disable-pip-version-check -q --no-build-isolation --no-deps \
    --config-settings=build-dir="$venv/.build/geodesic_planner_interfaces" "$interfaces"
# Warn, but do not fail, on inconsistent dependencies (shows pip's own words).
if ! "$venv/bin/python" -m pip check >>"$log" 2>&1; then
    say "warning: pip check reports problems:"
    grep -v -E '^WARNING: Location .* is ignored' "$log" | tail -n 10 >&2
fi
echo "$want" >"$stamp"
rm -f "$log"
say "venv ready in $((SECONDS - t0)) s"
