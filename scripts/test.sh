#!/usr/bin/env bash
# Run the whole test suite: set up .venv from the pinned requirements, then run pytest inside a
# private loopback-only network namespace (see scripts/netns.sh).
#
# Usage: bash scripts/test.sh [PYTEST ARGS...]
#   e.g. bash scripts/test.sh -x -q test/infra/test_infra.py
#        bash scripts/test.sh --run-slow        (also the long runs marked @pytest.mark.slow)
#   GP_TEST_WORKERS=N  pytest-xdist workers (default 3; 0 or 1: one process). Each worker has a ROS
#                      domain of its own (test/conftest.py); a module's tests stay on one worker
#                      (--dist loadscope), so module-scoped nodes start once; the longest modules
#                      go first (test/conftest.py LONG_FIRST). An explicit -n wins.
# Exit code: pytest's; "no tests collected" (pytest's 5) is turned into a failure (1).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

bash scripts/setup_env.sh
venv="${GP_VENV:-.venv}"
case "$venv" in /*) ;; *) venv="$root/$venv" ;; esac

# Default target is the whole test/ tree unless a path (or node id) is given.
# (The value after an option such as -k or -m is not a path, even if a file of that name exists.)
target=(test)
skip_next=0
for a in "$@"; do
    if [ "$skip_next" = 1 ]; then skip_next=0; continue; fi
    case "$a" in
        -k|-m|-p|-o|-c|-W|--deselect|--ignore|--timeout|--rootdir|--basetemp|--log-level) skip_next=1; continue ;;
        -*) continue ;;
    esac
    if [ -e "${a%%::*}" ]; then target=(); break; fi
done

# Bytecode caches on (even where PYTHONDONTWRITEBYTECODE is set, as on the development machine): the
# suite starts a few hundred Python processes (nodes, CLIs, workers), and each would otherwise
# compile geodesic_planner, tools/ and pytest's rewritten test modules again (~0.2 s CPU each).
unset PYTHONDONTWRITEBYTECODE

# Parallel workers unless the caller chose (-n / --numprocesses / -p no:xdist) or asked for one.
workers="${GP_TEST_WORKERS:-3}"
parallel=()
case " $* " in
    *" -n "*|*" -n"[0-9]*|*" --numprocesses"*|*"no:xdist"*) ;;
    *) if [ "$workers" -gt 1 ] 2>/dev/null; then parallel=(-n "$workers" --dist loadscope --no-loadscope-reorder); fi ;;
esac

set +e
bash scripts/netns.sh "$venv/bin/python" -m pytest "${target[@]}" \
    -p no:cacheprovider --timeout="${GP_TEST_TIMEOUT:-300}" -rfEs "${parallel[@]}" "$@"
rc=$?
set -e
if [ "$rc" -eq 5 ]; then
    echo "test.sh: ERROR: pytest collected no tests (exit 5): treat as a failure" >&2
    exit 1
fi
exit "$rc"
