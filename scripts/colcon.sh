#!/usr/bin/env bash
# colcon with this repository's two packages and the venv's PyPI ROS 2 wheels.
#
# Usage: bash scripts/colcon.sh [--interfaces-from-venv] WORKSPACE VERB [COLCON VERB ARGS...]
#   WORKSPACE  directory for build/, install/ and log/ (created; keep it outside the repository)
#   VERB       build, test, test-result, list, ... (any colcon verb)
#   --interfaces-from-venv  only geodesic_planner, against the interface package that
#              setup_env.sh built into the venv (found in its ament index, like a package of an
#              underlay): no rosidl build (26 of the 30 s of a cold build of both, 35 of 42 s CPU)
# Examples:
#   bash scripts/colcon.sh /tmp/gp_ws build
#   bash scripts/colcon.sh /tmp/gp_ws test --pytest-args test/infra/test_ament_lint.py
#   bash scripts/colcon.sh /tmp/gp_ws test-result --verbose
#
# What it adds to a plain colcon call (the checked facts: ../shared/interface-package.md):
#   * the venv (scripts/setup_env.sh) with its bin/ first on PATH: colcon, the cmake wheel, and the
#     python3 that CMake's FindPython3 must pick (the rosidl generators import the venv's modules);
#   * AMENT_PREFIX_PATH=<venv>: rosidl finds its typesupports in the ament index at configure time;
#   * CMAKE_PREFIX_PATH=<venv>: find_package() of the wheels' CMake configs;
#   * --base-paths <root> <root>/geodesic_planner_interfaces: colcon does not descend into a
#     package directory, and the repository root is the geodesic_planner package;
#   * --build-base/--install-base/--log-base (--test-result-base) under WORKSPACE.
# The wheels' exported Python include directories are fixed by the interface package's own CMake
# (geodesic_planner_interfaces/cmake/python_include_dirs.cmake); no installed file is patched.
# With a ROS 2 Jazzy installation sourced instead, plain `colcon build` in a workspace works too.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

die() { printf 'colcon.sh: ERROR: %s\n' "$*" >&2; exit 2; }
bases=("$root" "$root/geodesic_planner_interfaces")
if [ "${1:-}" = --interfaces-from-venv ]; then bases=("$root"); shift; fi
[ $# -ge 2 ] || die "usage: bash scripts/colcon.sh [--interfaces-from-venv] WORKSPACE VERB [ARGS...]"
ws="$1"; verb="$2"; shift 2
ws="$(realpath -m "$ws")"
case "$ws/" in "$root"/*) die "WORKSPACE $ws is inside the repository: choose a directory outside it" ;; esac
mkdir -p "$ws"

bash "$root/scripts/setup_env.sh"
venv="${GP_VENV:-.venv}"
case "$venv" in /*) ;; *) venv="$root/$venv" ;; esac

case "$verb" in
    build|test) extra=(--base-paths "${bases[@]}" --build-base "$ws/build" --install-base "$ws/install") ;;
    test-result) extra=(--test-result-base "$ws/build") ;;
    list|graph|info) extra=(--base-paths "${bases[@]}") ;;
    *) extra=() ;;
esac

cd "$root"
exec env PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv" \
    "$venv/bin/colcon" --log-base "$ws/log" "$verb" "${extra[@]}" "$@"
