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


# ------------------------------------------------------------------ namespaced nodes (issue 37)
NS_IN, NS_OUT = '/robot1' + IN, '/robot1' + OUT


def _namespaced_bag(path, ts, custom_data):
    """What the processor in namespace robot1 records: the planner's trajectory (input, t) and its
    own (output, twice as long); custom data as ros/recording.py writes it."""
    rng = np.random.default_rng(4)
    t, q, dq, ddq = example(rng, 5)
    with BagRecorder(path, topics={NS_IN: JOINT_TRAJECTORY, NS_OUT: JOINT_TRAJECTORY},
                     custom_data=custom_data) as rec:
        rec.write(NS_IN, 100, to_cdr(trajectory(t, q, dq, ddq), JOINT_TRAJECTORY, ts))
        rec.write(NS_OUT, 200, to_cdr(trajectory(t * 2, q, dq / 2, ddq / 4), JOINT_TRAJECTORY, ts))
    return path, t


PROCESSOR_CUSTOM_DATA = {'recorded_by': 'trajectory_processor', 'input_topic': NS_IN, 'output_topic': NS_OUT,
                         'sample_period': '0.01', 'velocity_scaling': '1.0'}


def test_plot_uses_the_topics_saved_in_the_bag(tmp_path, ts, capsys):
    bag, t = _namespaced_bag(tmp_path / 'b', ts, PROCESSOR_CUSTOM_DATA)
    assert bag_cli.main(['plot', str(bag), '-o', str(tmp_path / 'png')]) == 0
    assert capsys.readouterr().out.split() == [str(tmp_path / 'png' / 'trajectory_00.png')]  # one pair
    assert (tmp_path / 'png' / 'trajectory_00.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    chosen, pairs = bag_cli.plot_pairs(bag)
    assert (chosen.input, chosen.output, chosen.input_from, chosen.output_from) == (NS_IN, NS_OUT, 'bag', 'bag')
    ((before, after),) = pairs  # one picture: the planner's trajectory before, the processor's after
    assert (before.topic, before.stamp_ns) == (NS_IN, 100)
    assert (after.topic, after.stamp_ns) == (NS_OUT, 200)
    np.testing.assert_allclose(before.t, t, atol=1e-9)
    np.testing.assert_allclose(after.t, 2 * t, atol=1e-9)


def test_plot_of_a_bag_that_does_not_say_finds_the_namespaced_topics(tmp_path, ts):
    bag, _ = _namespaced_bag(tmp_path / 'b', ts, None)
    chosen, pairs = bag_cli.plot_pairs(bag)
    assert (chosen.input, chosen.output, chosen.input_from) == (NS_IN, NS_OUT, 'topic name')
    assert [(a.topic, b.topic) for a, b in pairs] == [(NS_IN, NS_OUT)]
    # the options win over the bag: the input alone, nothing after processing
    chosen, pairs = bag_cli.plot_pairs(bag, input_topic=NS_OUT, output_topic='/none')
    assert (chosen.input, chosen.output, chosen.input_from) == (NS_OUT, '/none', 'option')
    assert [(a.topic, b) for a, b in pairs] == [(NS_OUT, None), (NS_IN, None)]


@pytest.mark.parametrize('custom, topics, expected', [
    ({}, {IN, OUT}, (IN, OUT, 'default', 'default')),
    ({}, {NS_IN, NS_OUT}, (NS_IN, NS_OUT, 'topic name', 'topic name')),
    ({}, {NS_IN, '/robot2' + IN}, (IN, OUT, 'default', 'default')),  # two namespaces: not guessed
    ({'input_topic': '/a', 'output_topic': '/b'}, {IN, OUT}, ('/a', '/b', 'bag', 'bag')),
    ({'input_topic': '/a'}, {NS_OUT}, ('/a', NS_OUT, 'bag', 'topic name')),
])
def test_trajectory_topics(custom, topics, expected):
    got = bag_cli.trajectory_topics(custom, topics)
    assert (got.input, got.output, got.input_from, got.output_from) == expected
