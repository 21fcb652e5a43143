"""io/plotting.py: plot_trajectories writes a PNG at >= 150 dpi with units on every labelled axis."""
from __future__ import annotations

import re
import struct
from dataclasses import dataclass

import numpy as np

from geodesic_planner.io import plotting


@dataclass
class Series:
    topic: str
    joint_names: list[str]
    t: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None


def test_plot_trajectories_dpi_units_and_legend_outside(tmp_path, monkeypatch):
    import matplotlib.figure
    saved = []
    orig = matplotlib.figure.Figure.savefig

    def record(self, *args, **kwargs):
        saved.append(self)
        return orig(self, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, 'savefig', record)
    t = np.linspace(0.0, 1.0, 50)
    q = np.stack([np.sin(t), t**2], axis=1)
    rec = Series('/planned_trajectory', ['joint_1', 'joint_2'], t, q, np.gradient(q, t, axis=0), None)
    out = plotting.plot_trajectories(tmp_path / 'traj.png', [('in', rec), ('out', None)], title='demo')
    data = (tmp_path / 'traj.png').read_bytes()
    i = data.index(b'pHYs')
    ppm_x, ppm_y, unit = struct.unpack('>IIB', data[i + 4:i + 13])
    assert out == str(tmp_path / 'traj.png') and unit == 1 and ppm_x * 0.0254 >= 149.5
    (fig,) = saved
    fig.canvas.draw()
    for ax in fig.axes:
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            if label:
                assert re.search(r'\([^()]+\)$', label), label
                assert not any('_' in part for part in label.split('$')[::2]), label
        legend = ax.get_legend()
        if legend is not None:
            assert legend.get_window_extent().x0 >= ax.get_window_extent().x1 - 1
    labelled_y = [ax.get_ylabel() for ax in fig.axes if ax.get_ylabel()]
    assert len(labelled_y) == 3


def _saved_figures(monkeypatch):
    import matplotlib.figure
    saved = []
    orig = matplotlib.figure.Figure.savefig

    def record(self, *args, **kwargs):
        saved.append(self)
        return orig(self, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, 'savefig', record)
    return saved


def test_plot_trajectories_limit_lines_at_the_robot_limits(tmp_path, monkeypatch):
    from geodesic_planner import load_robot

    saved = _saved_figures(monkeypatch)
    robot = load_robot('panda')
    order = [6, 0, 3, 1, 5, 2, 4]                          # the message's joint order is not the robot's
    names = [f'panda_joint{k + 1}' for k in order]
    t = np.linspace(0.0, 2.0, 80)
    q = robot.home[order] + 0.2 * np.sin(t)[:, None]
    rec = Series('/planned', names, t, q, 0.2 * np.cos(t)[:, None] * np.ones(7), -q + robot.home[order])
    plotting.plot_trajectories(tmp_path / 't.png', [('planned', rec)], robot=robot)
    (fig,) = saved
    rows = [ax for ax in fig.axes if ax.get_ylabel().startswith(('position', 'velocity', 'acceleration'))]
    assert len(rows) == 3

    def limits(ax):
        return sorted({float(line.get_ydata()[0]) for line in ax.get_lines() if line.get_gid() == 'limit'})
    # Franka's datasheet: velocity 2.175 (joints 1-4), 2.61 (5-7) rad/s; acceleration 15, 7.5, 10,
    # 12.5, 15, 20, 20 rad/s^2; positions +-2.8973 but joint 2 +-1.7628, joint 4 [-3.0718, -0.0698],
    # joint 6 [-0.0175, 3.7525]
    assert limits(rows[0]) == sorted({-2.8973, 2.8973, -1.7628, 1.7628, -3.0718, -0.0698, -0.0175, 3.7525})
    assert limits(rows[1]) == [-2.61, -2.175, 2.175, 2.61]
    assert limits(rows[2]) == [-20.0, -15.0, -12.5, -10.0, -7.5, 7.5, 10.0, 12.5, 15.0, 20.0]
    # a value shared by several joints is black, one joint's in that joint's colour (its column here)
    import matplotlib.colors as mcolors
    colour = {float(line.get_ydata()[0]): mcolors.to_hex(line.get_color()) for line in rows[2].get_lines()
              if line.get_gid() == 'limit'}
    assert colour[20.0] == '#000000' and colour[12.5] == mcolors.to_hex(f'C{names.index("panda_joint4")}')


def _planar_tool(q):
    """planar_3r's tool position, links of 1 m: the paper's forward kinematics written out."""
    a1, a12, a123 = q[:, 0], q[:, 0] + q[:, 1], q.sum(axis=1)
    return np.stack([np.cos(a1) + np.cos(a12) + np.cos(a123), np.sin(a1) + np.sin(a12) + np.sin(a123)], axis=1)


def test_plot_trajectories_tool_path_is_the_forward_kinematics_of_the_positions(tmp_path, monkeypatch):
    from geodesic_planner import load_robot

    saved = _saved_figures(monkeypatch)
    t = np.linspace(0.0, 1.0, 40)
    q = np.stack([0.2 + 0.5 * t, 0.6 - 0.3 * t**2, -0.3 - 0.2 * t], axis=1)
    shuffled = Series('/a', ['joint3', 'joint1', 'joint2'], t, q[:, [2, 0, 1]], None, None)
    plotting.plot_trajectories(tmp_path / 'p.png', [('planned', shuffled)], robot=load_robot('planar_3r'))
    (fig,) = saved
    drawn = [line for ax in fig.axes for line in ax.get_lines() if line.get_gid() == 'tool path']
    assert len(drawn) == 1                                   # planar: the top view only
    np.testing.assert_allclose(np.column_stack(drawn[0].get_data()), _planar_tool(q), atol=1e-12)
    deviation = [ax for ax in fig.axes if ax.get_title().startswith('tool distance from the straight line')]
    assert len(deviation) == 1

    saved.clear()
    robot = load_robot('ur5e')
    qs = robot.home + np.outer(t, [0.3, -0.2, 0.1, 0.2, 0.3, 0.1])
    rec = Series('/b', list(robot.joint_names), t, qs, None, None)
    plotting.plot_trajectories(tmp_path / 'u.png', [('planned', rec)], robot=robot)
    (fig,) = saved
    views = [(ax, line) for ax in fig.axes for line in ax.get_lines() if line.get_gid() == 'tool path']
    assert [ax.get_xlabel()[-3:] + ax.get_ylabel() for ax, _ in views] == ['(m)tool $y$ (m)', '(m)tool $z$ (m)']
    p = robot.fk(qs)[:, :3, 3]
    for (_ax, line), cols in zip(views, [(0, 1), (0, 2)]):
        np.testing.assert_allclose(np.column_stack(line.get_data()), p[:, cols], atol=1e-12)


def test_outline_of_capsule_box_and_sphere():
    from geodesic_planner.core.collision import Shape
    from geodesic_planner.io.collision_plot import ROUND, outline

    pose = np.eye(4)
    c, s = np.cos(0.4), np.sin(0.4)
    pose[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]          # the capsule's axis tilted in the yz plane
    pose[:3, 3] = [0.5, -0.2, 0.3]
    poly = outline(Shape('capsule', (0.6, 0.05)), pose, (1, 2))
    # seen along x: a stadium around the axis' ends +-0.3 (-s, c) from (-0.2, 0.3), radius 0.05
    a = np.array([-0.2, 0.3]) + 0.3 * np.array([-s, c])
    b = np.array([-0.2, 0.3]) - 0.3 * np.array([-s, c])
    u = (b - a) / 0.6
    w = np.clip((poly - a) @ u, 0.0, 0.6)
    dist = np.linalg.norm(poly - (a + w[:, None] * u), axis=1)
    assert np.all(dist <= 0.05 + 1e-12) and np.all(dist >= 0.05 * np.cos(np.pi / ROUND) ** 2 - 1e-12)
    extent = (poly - a) @ u
    np.testing.assert_allclose([extent.min(), extent.max()], [-0.05, 0.65], atol=1e-12)
    box = outline(Shape('box', (0.2, 0.4, 0.6)), np.eye(4), (0, 2))
    assert sorted(map(tuple, np.round(box, 12))) == [(-0.1, -0.3), (-0.1, 0.3), (0.1, -0.3), (0.1, 0.3)]
    ball = outline(Shape('sphere', (0.1,)), np.eye(4), (0, 1))
    np.testing.assert_allclose(np.linalg.norm(ball, axis=1), 0.1, atol=1e-12)


def test_plot_collision_views_solids_and_min_clearance(tmp_path, monkeypatch):
    from geodesic_planner.core.collision import Shape
    from geodesic_planner.io.collision_plot import ArmView, Closest, outline, plot_collision

    saved = _saved_figures(monkeypatch)
    n = 20
    s = np.linspace(0.0, 1.0, n)
    tool = np.stack([1.0 + s, 1.0 - s, 0.2 * s], axis=1)
    arm = np.stack([np.zeros((n, 3)), 0.5 * tool, tool], axis=1)
    capsule = np.eye(4)
    capsule[:3, 3] = [0.5, 0.5, 0.0]
    views = [ArmView('start', [(Shape('capsule', (1.0, 0.05)), capsule)], 'C2')]
    clearance = 0.3 - np.abs(s - 0.5)
    closest = Closest(0.0712, ('box', 'link_2'), np.array([1.0, 0.0, 0.1]), np.array([1.1, 0.0, 0.1]), 0.45)
    plot_collision(tmp_path / 'c.png', arm, tool, s, [('aside', np.array([2.0, 0.0, 0.0]), 0.2, clearance,
                                                       float('nan'))], 0.01, views=views, closest=closest)
    (fig,) = saved
    assert len(fig.axes) == 3                      # top view, side view (the tool leaves z = 0), distances
    top, side, dist = fig.axes
    patch = [p for p in top.patches if p.get_label() == 'start: checked capsules']
    assert len(patch) == 1
    np.testing.assert_allclose(patch[0].get_xy()[:-1], outline(views[0].solids[0][0], capsule, (0, 1)), atol=1e-12)
    marker = [line for line in dist.get_lines() if str(line.get_label()).startswith('min_clearance 0.0712 m')]
    assert len(marker) == 1 and list(marker[0].get_xdata()) == [0.45] and list(marker[0].get_ydata()) == [0.0712]
    segment = [line for line in side.get_lines() if str(line.get_label()).startswith('min_clearance')]
    np.testing.assert_allclose(np.column_stack(segment[0].get_data()), [[1.0, 0.1], [1.1, 0.1]])
    for ax in (top, side, dist):
        assert ax.get_title()


def test_plot_ptp_legends_inside_and_durations_on_one_time_axis(tmp_path, monkeypatch):
    from geodesic_planner.io.motion_plot import plot_ptp_comparison

    saved = _saved_figures(monkeypatch)
    s = np.linspace(0.0, 1.0, 30)
    q = np.stack([s, 1 - s], axis=1)
    runs = [(f'run{k}: x', s, q, np.linspace(0.0, d, 50), np.sin(np.linspace(0.0, np.pi, 50)))
            for k, d in enumerate((1.5, 1.2))]
    plot_ptp_comparison(tmp_path / 'p.png', runs, ['j_1', 'j_2'])
    (fig,) = saved
    fig.canvas.draw()
    for ax in fig.axes:
        legend = ax.get_legend()
        assert legend is not None
        box, frame = legend.get_window_extent(), ax.get_window_extent()
        assert frame.x0 - 1 <= box.x0 and box.x1 <= frame.x1 + 1 and frame.y0 - 1 <= box.y0 and box.y1 <= frame.y1 + 1
    energy = fig.axes[1]
    assert energy.get_xlabel() == plotting.T_LABEL
    ends = sorted(float(line.get_xdata()[-1]) for line in energy.get_lines() if line.get_label().startswith('run'))
    assert ends == [1.2, 1.5]
    assert {float(line.get_xdata()[0]) for line in energy.get_lines() if line.get_linestyle() == ':'} == {1.2, 1.5}


def test_plot_sequence_top_and_side_views(tmp_path, monkeypatch):
    from geodesic_planner.io.motion_plot import plot_sequence

    saved = _saved_figures(monkeypatch)
    t = np.linspace(0.0, 1.0, 50)
    tool = np.stack([t, t**2, 0.1 * t], axis=1)
    plot_sequence(tmp_path / 's.png', t, tool, np.ones(50), [(0.4, 0.6)], tool[[0, 25, 49]], ['LIN', 'CIRC'])
    (fig,) = saved
    drawn = [line for ax in fig.axes for line in ax.get_lines() if line.get_gid() == 'tool path']
    assert len(drawn) == 2
    np.testing.assert_allclose(np.column_stack(drawn[0].get_data()), tool[:, [0, 1]])
    np.testing.assert_allclose(np.column_stack(drawn[1].get_data()), tool[:, [0, 2]])
