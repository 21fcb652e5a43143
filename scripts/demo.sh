#!/usr/bin/env bash
# The main job: plan the paper's example through both ROS nodes, record, summarise, plot.
#
# Usage: bash scripts/demo.sh [--output DIR] [--robot NAME] [--timeout S]
#   DIR defaults to out/demo, relative to the current directory.
# Sets up .venv (scripts/setup_env.sh), then runs `python -m tools.demo` inside the
# loopback-only network namespace (scripts/netns.sh; GEODESIC_PLANNER_NETNS=off to opt out).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

bash "$root/scripts/setup_env.sh"
venv="${GP_VENV:-.venv}"
case "$venv" in /*) ;; *) venv="$root/$venv" ;; esac

export PYTHONPATH="$root${PYTHONPATH:+:$PYTHONPATH}"
exec bash "$root/scripts/netns.sh" "$venv/bin/python" -m tools.demo "$@"
