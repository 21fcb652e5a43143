"""The geodesic-bag CLI: info, plot, repair; one-line errors."""
from __future__ import annotations

import re
from types import SimpleNamespace as Msg

import numpy as np
import pytest

from bag_util import IN, JS, OUT, example, joint_state, trajectory
from geodesic_planner.cli import bag as bag_cli
from geodesic_planner.io.bags import JOINT_STATE, JOINT_TRAJECTORY, BagRecorder, make_typestore, to_cdr


@pytest.fixture
def ts():
    return make_typestore()


def test_cli_info_plot_repair(tmp_path, ts, capsys):
    rng = np.random.default_rng(2)
    t, q, dq, ddq = example(rng, 5)
    with BagRecorder(tmp_path / 'b', topics={IN: JOINT_TRAJECTORY, OUT: JOINT_TRAJECTORY}) as rec:
        rec.write(IN, 100, to_cdr(trajectory(t, q, dq, ddq), JOINT_TRAJECTORY, ts))
        rec.write(OUT, 200, to_cdr(trajectory(t * 2, q, dq / 2, ddq / 4), JOINT_TRAJECTORY, ts))
        rec.write(IN, 300, to_cdr(trajectory(t, q[:, :2], names=('a', 'a')), JOINT_TRAJECTORY, ts))
    assert bag_cli.main(['info', str(tmp_path / 'b')]) == 0
    out = capsys.readouterr().out
    assert re.search(rf'{IN}\s+trajectory_msgs/msg/JointTrajectory\s+2 msgs', out)
    assert 'INVALID: duplicate joint names' in out
    assert bag_cli.main(['plot', str(tmp_path / 'b'), '--output', str(tmp_path / 'png')]) == 0
    files = sorted((tmp_path / 'png').glob('*.png'))
    assert [f.name for f in files] == ['trajectory_00.png', 'trajectory_01.png']  # (in, out) + lone invalid in
    assert all(f.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' for f in files)
    assert bag_cli.main(['repair', str(tmp_path / 'b')]) == 0
    assert 'unchanged' in capsys.readouterr().out


@pytest.mark.parametrize('args, message', [
    (['info', '/nonexistent/bag'], 'ERROR: no such bag: /nonexistent/bag'),
    (['plot', '/nonexistent/bag', '-o', '/tmp/x'], 'ERROR: no such bag'),
    (['repair', '/nonexistent/bag'], 'ERROR: no such bag directory'),
])
def test_cli_errors_one_line(args, message, capsys):
    assert bag_cli.main(args) == 1
    err = capsys.readouterr().err
    assert err.startswith(message)
    assert err.count('\n') == 1 and 'Traceback' not in err


def test_cli_plot_without_trajectories(tmp_path, ts, capsys):
    with BagRecorder(tmp_path / 'b', topics={JS: JOINT_STATE}) as rec:
        rec.write(JS, 1, to_cdr(joint_state(0), JOINT_STATE, ts))
    assert bag_cli.main(['plot', str(tmp_path / 'b'), '-o', str(tmp_path / 'png')]) == 1
    assert 'ERROR: no trajectory_msgs/msg/JointTrajectory messages' in capsys.readouterr().err


def test_pair_trajectories_matches_latest_earlier_input():
    def rec(topic, stamp):
        return Msg(topic=topic, stamp_ns=stamp)
    ins = [rec(IN, 10), rec(IN, 20), rec(IN, 30)]  # the one at 20 was rejected (no output)
    outs = [rec(OUT, 15), rec(OUT, 35)]
    pairs = bag_cli.pair_trajectories(ins, outs)
    assert [(a.stamp_ns if a else None, b.stamp_ns if b else None) for a, b in pairs] == [
        (10, 15), (20, None), (30, 35)]
