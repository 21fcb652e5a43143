"""``geodesic-plan batch REQUESTS -o DIR``: plan many requests at once, on Ray.

Each line of a JSON Lines file, or each row of a Parquet file, is one request in the YAML
requests' schema (:mod:`~geodesic_planner.io.batch_plan`: plus ``id``, ``scene``, ``motion``,
the scaling factors and a time limit); the results go to Parquet shards in ``DIR``
(:mod:`~geodesic_planner.io.batch_output`), one row per request. ``--workers N`` workers on a
local Ray instance (default: this machine's cores), or ``--address`` an existing Ray cluster.
A progress line with the rate and the time left goes to stderr (redrawn in place on a terminal,
a plain line every :data:`PLAIN_EVERY` s otherwise). Ctrl-C stops the job; ``--resume`` goes on
from the shards written. ``--bag`` also writes the trajectories as a rosbag2 MCAP for replay.

Exit codes: 0 the job is done (rows may report failed plans), 1 an error (``ERROR: ...``),
2 bad arguments, 130 interrupted.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from typing import TextIO

from ..core.errors import GeodesicPlannerError
from ..io.batch_job import MAX_SHARD_SIZE, MAX_WORKERS, JobSpec, run_job
from ..io.batch_plan import DEFAULT_SAMPLE_PERIOD, MAX_TIME_LIMIT

#: Seconds between progress lines when stderr is not a terminal.
PLAIN_EVERY = 10.0
#: Seconds between redraws on a terminal.
TTY_EVERY = 0.2
#: Shortest sample period, s (a trajectory's points are bounded by MAX_POINTS too).
MIN_SAMPLE_PERIOD = 1e-4


class Progress:
    """The progress line: done/total, percentage, rate (requests planned by this run per second)
    and the time left; a bar redrawn in place on a terminal, plain lines otherwise."""

    def __init__(self, stream: TextIO, *, tty: bool | None = None, quiet: bool = False) -> None:
        self.stream = stream
        self.tty = stream.isatty() if tty is None else tty
        self.quiet = quiet
        self.last = -math.inf
        self.state = (0, 0, 0)
        self.first: tuple[float, int] | None = None

    def __call__(self, done: int, total: int, planned: int) -> None:
        self.state = (done, total, planned)
        now = time.monotonic()
        if self.first is None and planned:
            self.first = (now, planned)     # the rate counts from the first row in (Ray's start-up apart)
        if now - self.last >= (TTY_EVERY if self.tty else PLAIN_EVERY):
            self.last = now
            self.show()

    def line(self) -> str:
        done, total, planned = self.state
        t_first, n_first = self.first if self.first is not None else (time.monotonic(), planned)
        elapsed = time.monotonic() - t_first
        rate = (planned - n_first) / elapsed if elapsed > 0 else 0.0
        left = total - done
        eta = _duration(left / rate) if rate > 0 else '?'
        pct = 100.0 * done / total if total else 100.0
        text = f'{done}/{total} ({pct:.0f} %), {rate:.1f} requests/s, ETA {eta}'
        if self.tty:
            filled = int(30 * done / total) if total else 30
            return f'[{"#" * filled}{"." * (30 - filled)}] {text}'
        return f'batch: {text}'

    def show(self, final: bool = False) -> None:
        if self.quiet:
            return
        if self.tty:
            self.stream.write('\r' + self.line() + ('\n' if final else ''))
        else:
            self.stream.write(self.line() + '\n')
        self.stream.flush()


def _duration(left: float) -> str:
    seconds = round(left)
    if seconds >= 3600:
        return f'{seconds // 3600}h{seconds % 3600 // 60:02d}m'
    if seconds >= 60:
        return f'{seconds // 60}m{seconds % 60:02d}s'
    return f'{seconds}s'


class _ArgError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        raise _ArgError(message)


def _bounded(kind: type, low: float, high: float, unit: str = '') -> Callable[[str], float | int]:
    def parse(text: str) -> float | int:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'expected {"an integer" if kind is int else "a number"}, '
                                             f'got {text!r}') from None
        if not (math.isfinite(value) and low <= value <= high):
            raise argparse.ArgumentTypeError(f'must be {low:g} to {high:g}{unit}, got {text!r}')
        return value
    return parse


def _parser() -> _Parser:
    p = _Parser(prog='geodesic-plan batch', description='Plan many requests (JSON Lines or Parquet) on Ray; '
                                                        'results as Parquet shards, one row per request.')
    p.add_argument('requests', help='JSON Lines (.jsonl) or Parquet (.parquet) file of requests')
    p.add_argument('-o', '--output', required=True, help='directory of the result shards (created)')
    p.add_argument('--robot', default='', help='robot of the requests that name none (preset or URDF path)')
    p.add_argument('--scene', action='append', default=[], metavar='[NAME=]FILE',
                   help='collision scene YAML; NAME=FILE names one for the requests\' "scene" key, FILE alone '
                        'is the default scene (repeatable)')
    p.add_argument('--workers', type=_bounded(int, 1, MAX_WORKERS), default=None,
                   help=f'Ray workers, 1 to {MAX_WORKERS} (default: this machine\'s cores, or the cluster\'s CPUs)')
    p.add_argument('--address', metavar='HOST:PORT', help='an existing Ray cluster\'s head (as ray start --head '
                                                         'prints it), instead of a local instance')
    p.add_argument('--shard-size', type=_bounded(int, 1, MAX_SHARD_SIZE), default=1000,
                   help=f'rows per Parquet shard, 1 to {MAX_SHARD_SIZE} (default 1000)')
    p.add_argument('--sample-period', type=_bounded(float, MIN_SAMPLE_PERIOD, 1.0, ' s'),
                   default=DEFAULT_SAMPLE_PERIOD, help=f'time between a trajectory\'s points, s '
                                                       f'(default {DEFAULT_SAMPLE_PERIOD:g})')
    p.add_argument('--time-limit', type=_bounded(float, 1e-3, MAX_TIME_LIMIT, ' s'), default=60.0,
                   help=f'a request\'s time limit, s (default 60, at most {MAX_TIME_LIMIT:g})')
    p.add_argument('--ptp-around', action='store_true',
                   help='in a scene, a sequence\'s blocked PTP items plan around the obstacles (OMPL) instead of '
                        'being refused; those rows are then not reproducible bit for bit')
    p.add_argument('--ptp-planning-timeout', type=_bounded(float, 1e-3, 60.0, ' s'), default=1.0,
                   help='with --ptp-around: the search\'s budget per PTP item, s (default 1, at most 60)')
    p.add_argument('--format', choices=('jsonl', 'parquet'), default='', help='input format (default: from the name)')
    p.add_argument('--resume', action='store_true', help='go on with the job whose shards -o holds')
    p.add_argument('--strict', action='store_true', help='refuse an input with a malformed line or row, before '
                                                         'planning (default: report and skip it)')
    p.add_argument('--bag', help='also write the trajectories to this new rosbag2 (MCAP) directory for replay')
    p.add_argument('-q', '--quiet', action='store_true', help='no progress line')
    return p


def _scenes(values: Sequence[str]) -> dict[str, str]:
    scenes: dict[str, str] = {}
    for value in values:
        name, sep, path = value.partition('=')
        if not sep:
            name, path = '', value
        if not path or name in scenes:
            raise _ArgError(f'--scene {value!r}: ' + ('no file' if not path else f'scene {name!r} given twice'))
        scenes[name] = path
    return scenes


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``geodesic-plan batch``; returns the exit code."""
    try:
        args = _parser().parse_args(argv)
        scenes = _scenes(args.scene)
    except _ArgError as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 2
    spec = JobSpec(args.requests, args.output, args.robot, scenes, args.format, args.shard_size,
                   args.sample_period, args.time_limit, args.ptp_around, args.ptp_planning_timeout)
    progress = Progress(sys.stderr, quiet=args.quiet)

    def skipped(where: str, problem: str) -> None:
        if progress.tty and not args.quiet:
            sys.stderr.write('\n')
        print(f'WARNING: {where}: {problem}: skipped', file=sys.stderr)

    try:
        if args.bag:
            from ..io.batch_bag import check_bag_path
            check_bag_path(args.bag)
        report = run_job(spec, workers=args.workers, address=args.address, resume=args.resume,
                         strict=args.strict, on_progress=progress, on_skip=skipped)
        progress.show(final=True)
        if args.bag:
            from ..io.batch_bag import write_bag
            written = write_bag(args.output, args.bag)
            print(f'{written} trajectories -> {args.bag}', file=sys.stderr)
    except KeyboardInterrupt:
        print(f'\ninterrupted: the shards written are kept in {args.output}; run again with --resume',
              file=sys.stderr)
        return 130
    except (GeodesicPlannerError, OSError) as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    rate = report.planned / report.seconds if report.seconds > 0 else math.nan
    print(f'{report.planned} planned ({report.failed} failed) in {report.seconds:.1f} s on {report.workers} '
          f'worker(s), {rate:.1f} requests/s; {report.resumed} done before, {len(report.skipped)} malformed '
          f'skipped; {report.shards} shards -> {os.path.abspath(args.output)}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
