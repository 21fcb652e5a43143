#!/usr/bin/env bash
# Run chosen tests N times with K CPU-bound processes alongside; print the failures per test.
#
# Usage: bash scripts/stress.sh [-n N] [-k K] [--keep DIR] [--] [PYTEST ARGS / TEST PATHS...]
#   e.g. bash scripts/stress.sh -n 5 -k 2 test/ros
#        bash scripts/stress.sh -n 10 -k 1 -- -k malformed test/ros/test_reliability.py
# Every run is `bash scripts/test.sh ...` (same venv, same network namespace), one at a time.
# Exit code: 0 when no test failed in any run, else 1. See docs/testing.md.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

bash scripts/setup_env.sh
venv="${GP_VENV:-.venv}"
case "$venv" in /*) ;; *) venv="$root/$venv" ;; esac
exec "$venv/bin/python" scripts/stress.py "$@"
