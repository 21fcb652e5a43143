"""``geodesic-bag``: inspect, plot and repair trajectory bags (rosbags only, no rclpy).

Usage::

    geodesic-bag info BAG
    geodesic-bag plot BAG --output DIR [--input-topic T] [--output-topic T]
    geodesic-bag repair BAG

``info`` prints the topics (type, count, duration) and one line per recorded JointTrajectory
(points, duration, peak |v|, peak |a|, and why it is invalid when it is). ``plot`` writes one PNG
per processed trajectory: joint positions, velocities and accelerations against time, the planner's
trajectory (input topic, markers) over the processor's (output topic, lines); trajectories on
other JointTrajectory topics, or inputs without an output, get a PNG of their own. The input and
output topics are the options when given, else those the recording node saved in the bag's
``custom_data`` (``input_topic``, ``output_topic``: namespaced nodes record
``/robot1/geodesic_planner/joint_trajectory``...), else the default names, or the one topic of the
bag ending in a default name (see :func:`trajectory_topics`). ``repair`` rebuilds a bag whose
recording was killed (see :func:`geodesic_planner.io.bags.repair`); when the storage file was
damaged beyond the interruption, it writes what could be read, names what was lost on one
``ERROR:`` line and exits with 1. Errors print one line ``ERROR: ...`` and exit with 1.

A record that does not decode never fails the whole bag: ``info`` counts and lists such records
(``undecodable records: N``), ``plot`` skips them and says so on stderr (``skipped N undecodable
record(s)``), ``repair`` copies what it can read. The exit code stays 0 when the rest was read.
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from datetime import datetime, UTC
from pathlib import Path
from typing import TYPE_CHECKING

from ..core.errors import BagError, GeodesicPlannerError
from ..io.bags import (
    BagInfo,
    TrajectoryRecord,
    UndecodableRecord,
    bag_info,
    read_custom_data,
    read_trajectories,
    repair,
)
from ..io.plotting import plot_trajectories

if TYPE_CHECKING:
    from collections.abc import Collection, Mapping, Sequence

DEFAULT_INPUT_TOPIC = '/geodesic_planner/joint_trajectory'
DEFAULT_OUTPUT_TOPIC = '/trajectory_processor/joint_trajectory'

__all__ = ['DEFAULT_INPUT_TOPIC', 'DEFAULT_OUTPUT_TOPIC', 'TrajectoryTopics', 'format_info', 'format_undecodable',
           'main', 'pair_trajectories', 'plot_bag', 'plot_pairs', 'trajectory_topics']


def _utc(stamp_ns: int | None) -> str:
    if stamp_ns is None:
        return '-'
    return datetime.fromtimestamp(stamp_ns * 1e-9, UTC).isoformat(timespec='milliseconds')


def _num(x: float) -> str:
    return '-' if math.isnan(x) else f'{x:.4g}'


#: Undecodable records listed one per line (the rest is counted).
MAX_LISTED = 10


def format_undecodable(skipped: list[UndecodableRecord]) -> list[str]:
    """Lines naming the first MAX_LISTED undecodable records, then how many more."""
    lines = [f'  {r}' for r in skipped[:MAX_LISTED]]
    if len(skipped) > MAX_LISTED:
        lines.append(f'  ... and {len(skipped) - MAX_LISTED} more')
    return lines


def format_info(info: BagInfo) -> str:
    """The text ``geodesic-bag info`` prints."""
    lines = [
        f'bag: {info.path} ({info.storage}), {info.message_count} messages, '
        f'{info.duration:.3f} s, start {_utc(info.start_ns)}',
    ]
    if info.custom_data:
        lines.append('custom data: ' + ', '.join(f'{k}={v}' for k, v in sorted(info.custom_data.items())))
    lines.append('topics:')
    width = max((len(t.name) for t in info.topics), default=0)
    twidth = max((len(t.msgtype) for t in info.topics), default=0)
    for t in info.topics:
        lines.append(f'  {t.name:<{width}}  {t.msgtype:<{twidth}}  {t.count:6d} msgs  {t.duration:8.3f} s')
    lines.append(f'trajectories: {len(info.trajectories)}')
    for s in info.trajectories:
        rel = (s.stamp_ns - info.start_ns) * 1e-9 if info.start_ns is not None else 0.0
        line = (f'  {s.topic} #{s.index} at +{rel:.3f} s: {s.points} points, {s.dof} joints, '
                f'{s.duration:.3f} s, peak |v| {_num(s.peak_velocity)}, peak |a| {_num(s.peak_acceleration)}')
        if s.problems:
            line += f'  INVALID: {"; ".join(s.problems[:3])}' + (' ...' if len(s.problems) > 3 else '')
        lines.append(line)
    if info.undecodable:
        lines.append(f'undecodable records: {len(info.undecodable)} (skipped)')
        lines += format_undecodable(info.undecodable)
    return '\n'.join(lines)


def pair_trajectories(
    inputs: list[TrajectoryRecord], outputs: list[TrajectoryRecord],
) -> list[tuple[TrajectoryRecord | None, TrajectoryRecord | None]]:
    """Match each output with the latest input recorded before it (the one it was made from).

    Returns:
        (input, output) pairs in time order; an input without an output (e.g. rejected as
        invalid) appears as (input, None), an output without an input as (None, output).
    """
    pairs: list[tuple[TrajectoryRecord | None, TrajectoryRecord | None]] = []
    used: set[int] = set()
    for out in outputs:
        before = [i for i, r in enumerate(inputs) if r.stamp_ns <= out.stamp_ns and i not in used]
        if before:
            used.add(before[-1])
            pairs.append((inputs[before[-1]], out))
        else:
            pairs.append((None, out))
    pairs += [(r, None) for i, r in enumerate(inputs) if i not in used]
    pairs.sort(key=lambda p: (p[0] or p[1]).stamp_ns)  # type: ignore[union-attr]
    return pairs


@dataclass(frozen=True)
class TrajectoryTopics:
    """The topics plotted as before (input) and after (output) processing, and where each came from.

    Attributes:
        input: the planner's trajectory topic (the processor's input).
        output: the processor's trajectory topic.
        input_from: 'option', 'bag' (the bag's custom_data), 'default' or 'topic name'.
        output_from: likewise.
    """

    input: str
    output: str
    input_from: str
    output_from: str


def _choose(given: str | None, saved: str | None, default: str, topics: Collection[str]) -> tuple[str, str]:
    if given is not None:
        return given, 'option'
    if saved:
        return saved, 'bag'
    if default in topics:
        return default, 'default'
    namespaced = [t for t in topics if t.endswith(default)]  # /robot1 + /geodesic_planner/...
    if len(namespaced) == 1:
        return namespaced[0], 'topic name'
    return default, 'default'


def trajectory_topics(
    custom_data: Mapping[str, str],
    topics: Collection[str],
    *,
    input_topic: str | None = None,
    output_topic: str | None = None,
) -> TrajectoryTopics:
    """Which recorded topics hold the trajectories before and after processing.

    Each is the option when given; else what the recording node saved in the bag's custom data
    (``input_topic``, ``output_topic``: the node's resolved names, namespace included); else, for
    a bag that does not say, the default name when the bag has that topic, or the one topic of
    the bag whose name ends with it (a namespaced node); else the default.

    Args:
        custom_data: the bag's ``custom_data``.
        topics: the bag's JointTrajectory topics.
        input_topic, output_topic: given by the user (None: choose).
    """
    inp, inp_from = _choose(input_topic, custom_data.get('input_topic'), DEFAULT_INPUT_TOPIC, topics)
    out, out_from = _choose(output_topic, custom_data.get('output_topic'), DEFAULT_OUTPUT_TOPIC, topics)
    return TrajectoryTopics(inp, out, inp_from, out_from)


def plot_pairs(
    bag: str | Path,
    *,
    input_topic: str | None = None,
    output_topic: str | None = None,
    skipped: list[UndecodableRecord] | None = None,
) -> tuple[TrajectoryTopics, list[tuple[TrajectoryRecord | None, TrajectoryRecord | None]]]:
    """What :func:`plot_bag` draws: the topics chosen and the (before, after) pair of each picture.

    Args:
        input_topic, output_topic: the topics before and after processing (None: as
            :func:`trajectory_topics` chooses).
        skipped: undecodable records (not plotted) are appended here.

    Raises:
        BagError: unreadable bag or no decodable JointTrajectory in it.
    """
    undecodable: list[UndecodableRecord] = []
    records = read_trajectories(bag, skipped=undecodable)
    if skipped is not None:
        skipped.extend(undecodable)
    if not records:
        more = f' ({len(undecodable)} undecodable record(s) skipped)' if undecodable else ''
        msg = f'no trajectory_msgs/msg/JointTrajectory messages in {bag}{more}'
        raise BagError(msg)
    try:
        custom = read_custom_data(bag)
    except BagError:  # the messages were read: plot them with the names alone
        custom = {}
    chosen = trajectory_topics(custom, {r.topic for r in records},
                               input_topic=input_topic, output_topic=output_topic)
    inputs = [r for r in records if r.topic == chosen.input]
    outputs = [r for r in records if r.topic == chosen.output]
    pairs = pair_trajectories(inputs, outputs)
    pairs += [(r, None) for r in records if r.topic not in (chosen.input, chosen.output)]
    return chosen, pairs


def plot_bag(
    bag: str | Path,
    output_dir: str | Path,
    *,
    input_topic: str | None = None,
    output_topic: str | None = None,
    skipped: list[UndecodableRecord] | None = None,
) -> list[Path]:
    """Write PNGs of every trajectory in a bag (input and its processed output together).

    Args:
        input_topic, output_topic: the topics before and after processing (None: as
            :func:`trajectory_topics` chooses).
        skipped: undecodable records (not plotted) are appended here.

    Returns:
        The files written, ``trajectory_00.png``, ``trajectory_01.png``, ...

    Raises:
        BagError: unreadable bag or no decodable JointTrajectory in it.
    """
    _, pairs = plot_pairs(bag, input_topic=input_topic, output_topic=output_topic, skipped=skipped)
    out_dir = Path(output_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f'cannot create output directory {out_dir}: {err}'
        raise BagError(msg) from err
    written = []
    for k, (before, after) in enumerate(pairs):
        parts = []
        if before is not None:
            parts.append(f'{before.topic}: {before.t.size} points, {before.duration:.3f} s')
        if after is not None:
            parts.append(f'{after.topic}: {after.t.size} points, {after.duration:.3f} s')
        problems = (before.problems if before is not None else ()) + (after.problems if after is not None else ())
        title = f'trajectory {k}: ' + ' -> '.join(parts) + (f'\nINVALID: {problems[0]}' if problems else '')
        path = out_dir / f'trajectory_{k:02d}.png'
        plot_trajectories(path, [('before processing', before), ('after processing', after)], title=title)
        written.append(path)
    return written


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='geodesic-bag', description=__doc__.split('\n\n')[0])
    sub = parser.add_subparsers(dest='command', required=True)
    p_info = sub.add_parser('info', help='topics, counts, durations and a summary of each trajectory')
    p_info.add_argument('bag', help='rosbag2 directory')
    p_plot = sub.add_parser('plot', help='PNG of joint position/velocity/acceleration vs time')
    p_plot.add_argument('bag', help='rosbag2 directory')
    p_plot.add_argument('--output', '-o', required=True, help='directory for the PNG files')
    p_plot.add_argument('--input-topic', help='trajectory before processing (default: the input topic saved in '
                        f'the bag, else {DEFAULT_INPUT_TOPIC})')
    p_plot.add_argument('--output-topic', help='trajectory after processing (default: the output topic saved in '
                        f'the bag, else {DEFAULT_OUTPUT_TOPIC})')
    p_rep = sub.add_parser('repair', help='make an interrupted recording readable (rebuild index and metadata)')
    p_rep.add_argument('bag', help='rosbag2 directory')
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``geodesic-bag``; returns the exit code (0 ok, 1 error, 2 usage)."""
    args = _parser().parse_args(argv)
    try:
        if args.command == 'info':
            print(format_info(bag_info(args.bag)))
        elif args.command == 'plot':
            skipped: list[UndecodableRecord] = []
            files = plot_bag(args.bag, args.output, input_topic=args.input_topic,
                             output_topic=args.output_topic, skipped=skipped)
            for f in files:
                print(f)
            if skipped:
                print(f'skipped {len(skipped)} undecodable record(s):', file=sys.stderr)
                print('\n'.join(format_undecodable(skipped)), file=sys.stderr)
        else:
            report = repair(args.bag)
            state = 'repaired' if report.repaired else 'unchanged'
            counts = ', '.join(f'{t}: {n}' for t, n in report.messages.items())
            print(f'{state}: {report.path} ({report.storage}): {report.note}; {counts}')
            if report.damaged_file is not None:
                print(f'original storage file kept as {report.damaged_file}')
            if report.repaired and report.custom_data:
                print('custom data kept: ' + ', '.join(f'{k}={v}' for k, v in sorted(report.custom_data.items())))
            if report.damage:
                _error(f'{report.path} was damaged (what could be read was written): {"; ".join(report.damage)}')
                return 1
    except (GeodesicPlannerError, OSError) as err:
        _error(str(err))
        return 1
    return 0


def _error(text: str) -> None:
    print(f'ERROR: {" ".join(text.split())}', file=sys.stderr)  # one line, also for YAML errors


if __name__ == '__main__':
    raise SystemExit(main())
