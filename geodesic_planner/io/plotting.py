"""All figures: the paper's Fig. 5/6 (planar 3R) and Fig. 8-10 (spatial RRPP), and joint trajectories.

matplotlib is imported lazily (only when a figure is drawn) and used without pyplot, through
:class:`matplotlib.figure.Figure` and the Agg canvas, so it works headless and keeps no global state.
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..core.kinematics import Chain

#: Line styles per method (geodesic solid, polynomial dashed), as in the paper's legends.
STYLES = {'geodesic': {'ls': '-', 'lw': 1.6}, 'polynomial': {'ls': '--', 'lw': 1.2},
          'cartesian_ik': {'ls': ':', 'lw': 1.4}}
#: Legend names per method.
METHOD_LABELS = {'geodesic': 'geodesic method', 'polynomial': 'polynomial method',
                 'cartesian_ik': 'Cartesian line + IK (Pilz LIN)'}
#: Resolution of every PNG written here, dots per inch (>= 150 for print).
DPI = 150
#: Label of the path parameter axis (dimensionless: SI unit 1).
S_LABEL = r'path parameter $s$ (1)'
#: Label of the time axis.
T_LABEL = r'time $t$ (s)'


def _figure(figsize: tuple[float, float]) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize, dpi=DPI, layout='constrained')
    FigureCanvasAgg(fig)
    return fig


def save_png(fig: Figure, path: str | os.PathLike[str], title: str = '') -> str:
    """Write ``fig`` to ``path`` at :data:`DPI` (legends outside the axes included), with ``title``
    above it when given; returns the path as a string."""
    _suptitle(fig, title)
    fig.savefig(os.fspath(path), dpi=DPI, bbox_inches='tight', pad_inches=0.05)
    return os.fspath(path)


def _save(fig: Figure, out_dir: str, name: str) -> str:
    """Write ``fig`` as ``out_dir/name`` (:func:`save_png`)."""
    return save_png(fig, os.path.join(out_dir, name))


def tool_path_and_speed_axes(ax_xy: Axes, ax_v: Axes, speed_title: str) -> None:
    """Labels of the pair of axes the motion figures share: the tool path in the xy plane (equal
    scales, base frame) and the tool speed against time; both with a grid."""
    ax_xy.set_aspect('equal', adjustable='datalim')
    ax_xy.set_xlabel(r'tool $x$ (m)')
    ax_xy.set_ylabel(r'tool $y$ (m)')
    ax_xy.set_title('tool path (xy plane, base frame)', fontsize=9)
    ax_v.set_xlabel(T_LABEL)
    ax_v.set_ylabel(r'tool speed $|v|$ (m/s)')
    ax_v.set_title(speed_title, fontsize=9)
    ax_xy.grid(True, alpha=0.3)
    ax_v.grid(True, alpha=0.3)


def _legend_outside(ax: Axes, fontsize: float = 8) -> None:
    """Legend to the right of the axes, so it never covers a curve."""
    ax.legend(loc='upper left', bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=fontsize)


def _method(name: str) -> str:
    return METHOD_LABELS.get(name, name.replace('_', ' '))


def _joint_unit(joint_types: Sequence[str] | None, per: str = '') -> str:
    """'(rad/s)' for revolute arms, '(rad/s or m/s)' when some joints are prismatic or unknown."""
    kinds = set(joint_types) if joint_types is not None else {'revolute', 'prismatic'}
    units = [u for k, u in (('revolute', 'rad'), ('prismatic', 'm')) if k in kinds] or ['rad']
    return '(' + ' or '.join(u + per for u in units) + ')'


def is_planar(profiles: dict[str, dict[str, np.ndarray]]) -> bool:
    """True when every tool path stays in one z plane with the tool z axis along the base z axis."""
    for prof in profiles.values():
        if np.ptp(prof['p'][:, 2]) > 1e-9 or np.min(np.abs(prof['R'][:, 2, 2])) < 1.0 - 1e-9:
            return False
    return True


def _tidy(ax: Axes, arrays: list[np.ndarray]) -> None:
    """No offset notation; a flat curve (round-off only) gets a +-5 % band instead of noise."""
    ax.ticklabel_format(axis='y', useOffset=False)
    vals = np.concatenate([np.ravel(a) for a in arrays])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return
    lo, hi = float(vals.min()), float(vals.max())
    mag = max(abs(lo), abs(hi))
    if hi - lo <= 1e-4 * mag + 1e-12:
        centre = 0.5 * (lo + hi)
        pad = max(0.05 * abs(centre), 1e-6)
        ax.set_ylim(centre - pad, centre + pad)


def _style(name: str) -> dict[str, Any]:
    return STYLES.get(name, {'ls': '-.', 'lw': 1.0})


def _suptitle(fig: Figure, title: str) -> None:
    if title:
        fig.suptitle(title, fontsize=10)


def plot_comparison(profiles: dict[str, dict[str, np.ndarray]], out_dir: str, *, title: str = '',
                    planar: bool | None = None, joint_types: Sequence[str] | None = None) -> list[str]:
    """Write the per-s comparison figures (paper Fig. 5/6 or 8-10) and the deviation from the chord.

    Args:
        profiles: method name -> profile from :func:`geodesic_planner.cli.compare.ee_profile`.
        out_dir: existing directory.
        title: optional figure title above the panels (panel titles are the paper's captions).
        planar: planar (Fig. 5/6) or spatial (Fig. 8-10) layout; detected from the data when None.
        joint_types: 'revolute' / 'prismatic' per joint (axis units); None: "rad or m".
    Returns:
        Paths of the PNG files written (:data:`DPI` dots per inch).
    """
    if planar is None:
        planar = is_planar(profiles)
    return [
        _ee_position(profiles, out_dir, title, planar),
        _derivative_norms(profiles, out_dir, title, 'position', planar),
        _ee_orientation(profiles, out_dir, title, planar),
        _derivative_norms(profiles, out_dir, title, 'orientation', planar),
        _joints(profiles, out_dir, title, planar, joint_types),
        _line_deviation(profiles, out_dir, title),
    ]


def _ee_position(profiles: dict[str, Any], out_dir: str, title: str, planar: bool) -> str:
    fig = _figure((6.5, 4.5))
    first = next(iter(profiles.values()))['p']
    if planar:
        ax = fig.add_subplot(1, 1, 1)
        for name, prof in profiles.items():
            ax.plot(prof['p'][:, 0], prof['p'][:, 1], label=_method(name), **_style(name))
        ax.plot(first[[0, -1], 0], first[[0, -1], 1], 'o', color='k', ms=4, label='A, B')
        ax.set_xlabel(r'$p_x$ (m)')
        ax.set_ylabel(r'$p_y$ (m)')
        ax.set_aspect('equal', adjustable='datalim')
        ax.grid(alpha=0.3)
        ax.set_title('Fig. 5(a): the position', fontsize=9)
    else:
        ax = fig.add_subplot(1, 1, 1, projection='3d')
        for name, prof in profiles.items():
            ax.plot(prof['p'][:, 0], prof['p'][:, 1], prof['p'][:, 2], label=_method(name), **_style(name))
        ax.plot(first[[0, -1], 0], first[[0, -1], 1], first[[0, -1], 2], 'k:', lw=0.8, label='chord A-B')
        ax.set_xlabel(r'$p_x$ (m)')
        ax.set_ylabel(r'$p_y$ (m)')
        ax.set_zlabel(r'$p_z$ (m)')
        ax.set_title('Fig. 8: the trajectory in the Cartesian space', fontsize=9)
    _legend_outside(ax)
    _suptitle(fig, title)
    return _save(fig, out_dir, 'ee_position.png')


def _derivative_norms(profiles: dict[str, Any], out_dir: str, title: str, kind: str, planar: bool) -> str:
    fig = _figure((7.5, 6.5))
    if kind == 'position':
        keys = [('dp', r"$|p\,'|$ (m)"), ('ddp', r"$|p\,''|$ (m)"), ('dddp', r"$|p\,'''|$ (m)")]
        norm = lambda a: np.linalg.norm(a, axis=-1)  # noqa: E731
        head = ('Fig. 5(b): the position velocity, acceleration and jerk' if planar
                else 'Tool position: velocity, acceleration and jerk w.r.t. s')
        name = 'ee_position_derivatives.png'
    else:
        keys = [('dR', r"$\|R\,'\|_F$ (1)"), ('ddR', r"$\|R\,''\|_F$ (1)"), ('dddR', r"$\|R\,'''\|_F$ (1)")]
        norm = lambda a: np.linalg.norm(a, axis=(-2, -1))  # noqa: E731
        head = ('Fig. 5(d): the orientation velocity, acceleration and jerk' if planar
                else 'Tool orientation (n, o, a): velocity, acceleration and jerk w.r.t. s')
        name = 'ee_orientation_derivatives.png'
    axes = fig.subplots(3, 1, sharex=True)
    for i, (key, label) in enumerate(keys):
        ax = axes[i]
        series = []
        for meth, prof in profiles.items():
            series.append(norm(prof[key]))
            ax.plot(prof['s'], series[-1], label=_method(meth), **_style(meth))
        _tidy(ax, series)
        ax.set_ylabel(label, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_title(head, fontsize=9)
    _legend_outside(axes[0])
    axes[-1].set_xlabel(S_LABEL)
    _suptitle(fig, title)
    return _save(fig, out_dir, name)


def _ee_orientation(profiles: dict[str, Any], out_dir: str, title: str, planar: bool) -> str:
    if planar:
        fig = _figure((6.5, 4.5))
        ax = fig.add_subplot(1, 1, 1)
        for meth, prof in profiles.items():
            R = prof['R']
            ax.plot(R[:, 0, 0], R[:, 1, 0], label=f'n, {_method(meth)}', **_style(meth))
            ax.plot(R[:, 0, 1], R[:, 1, 1], label=f'o, {_method(meth)}', **_style(meth))
        ax.set_xlabel(r'$n_x$, $o_x$ (1)')
        ax.set_ylabel(r'$n_y$, $o_y$ (1)')
        _legend_outside(ax)
        ax.set_title('Fig. 5(c): the orientation', fontsize=9)
        ax.grid(alpha=0.3)
        _suptitle(fig, title)
        return _save(fig, out_dir, 'ee_orientation.png')
    fig = _figure((12.0, 4.2))
    ax3 = None
    for i, axis_name in enumerate('noa'):
        ax3 = fig.add_subplot(1, 3, i + 1, projection='3d')
        for meth, prof in profiles.items():
            v = prof['R'][:, :, i]
            ax3.plot(v[:, 0], v[:, 1], v[:, 2], label=_method(meth), **_style(meth))
        ax3.set_xlabel(f'${axis_name}_x$ (1)', fontsize=8)
        ax3.set_ylabel(f'${axis_name}_y$ (1)', fontsize=8)
        ax3.set_zlabel(f'${axis_name}_z$ (1)', fontsize=8)
        ax3.tick_params(labelsize=6)
        ax3.set_title(f'Fig. 10: the planned orientation, ${axis_name}$', fontsize=9)
    assert ax3 is not None
    _legend_outside(ax3, fontsize=7)
    _suptitle(fig, title)
    return _save(fig, out_dir, 'ee_orientation.png')


def _joint_legend(ax: Axes, dof: int, methods: Sequence[str], names: Sequence[str] | None = None) -> None:
    """One legend entry per joint (colour) and per method (line style), outside the axes."""
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], color=f'C{j % 10}', lw=1.5) for j in range(dof)]
    labels = [names[j] if names is not None else f'joint {j + 1}' for j in range(dof)]
    for meth in methods:
        handles.append(Line2D([], [], color='k', **_style(meth)))
        labels.append(_method(meth))
    ax.legend(handles, [lab.replace('_', ' ') for lab in labels], loc='upper left',
              bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=7)


def _joints(profiles: dict[str, Any], out_dir: str, title: str, planar: bool,
            joint_types: Sequence[str] | None) -> str:
    fig = _figure((13.0, 3.8))
    u = _joint_unit(joint_types)
    rows = [('q', f'$q$ {u}'), ('dq', f"$q\\,'$ {u}"), ('ddq', f"$q\\,''$ {u}"), ('dddq', f"$q\\,'''$ {u}")]
    names = ('joint positions', 'joint velocities w.r.t. s', 'joint accelerations w.r.t. s',
             'joint jerks w.r.t. s')
    axes = fig.subplots(1, 4)
    for i, (key, label) in enumerate(rows):
        ax = axes[i]
        _tidy(ax, [prof[key] for prof in profiles.values()])
        for meth, prof in profiles.items():
            arr = prof[key]
            for j in range(arr.shape[1]):
                ax.plot(prof['s'], arr[:, j], color=f'C{j % 10}', **_style(meth))
        ax.set_xlabel(S_LABEL, fontsize=8)
        ax.set_ylabel(label, fontsize=8)
        ax.set_title(names[i], fontsize=9)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
    dof = next(iter(profiles.values()))['q'].shape[1]
    _joint_legend(axes[-1], dof, list(profiles))
    fig.suptitle((title + ': ' if title else '')
                 + f'Fig. {"6" if planar else "9"}: the trajectory planning in the joint space', fontsize=10)
    return _save(fig, out_dir, 'joints.png')


def _line_deviation(profiles: dict[str, Any], out_dir: str, title: str) -> str:
    """Distance of the tool to the chord A-B vs s, mm (what a 3-D plot cannot show)."""
    from ..core.transforms import segment_distance
    fig = _figure((7.0, 3.6))
    ax = fig.add_subplot(1, 1, 1)
    first = next(iter(profiles.values()))['p']
    a, b = first[0], first[-1]
    series = []
    for meth, prof in profiles.items():
        series.append(1e3 * segment_distance(prof['p'], a, b))
        ax.plot(prof['s'], series[-1], label=_method(meth), **_style(meth))
    ax.set_xlabel(S_LABEL)
    ax.set_ylabel('distance to chord A-B (mm)')
    ax.set_title('Deviation of the tool path from the straight line A-B', fontsize=9)
    ax.grid(alpha=0.3)
    ax.set_ylim(bottom=0.0, top=max(1.08 * max(float(v.max()) for v in series), 1e-6))
    _legend_outside(ax)
    _suptitle(fig, title)
    return _save(fig, out_dir, 'ee_line_deviation.png')


def plot_timed_comparison(timed: dict[str, dict[str, np.ndarray]], out_dir: str, *,
                          joint_names: Sequence[str] | None = None,
                          joint_types: Sequence[str] | None = None, title: str = '') -> list[str]:
    """Figures vs time of timed trajectories: joints (velocity, acceleration, jerk) and tool.

    Args:
        timed: method name -> profile from :func:`geodesic_planner.cli.compare.timed_profile`
            (``t`` s; ``dq``, ``ddq``, ``dddq`` per s^k; ``dp``, ``dddp`` m/s, m/s^3).
        out_dir: existing directory.
        joint_names: legend names of the joints; default "joint 1", ...
        joint_types: 'revolute' / 'prismatic' per joint (axis units); None: "rad or m".
        title: optional figure title.
    Returns:
        Paths of ``timed_joints.png`` and ``timed_tool.png``.
    """
    methods = list(timed)
    fig = _figure((4.2 * len(methods) + 1.5, 7.5))
    axes = fig.subplots(3, len(methods), sharex='col', sharey='row', squeeze=False)
    rows = [('dq', r'$\dot q$ ' + _joint_unit(joint_types, '/s')),
            ('ddq', r'$\ddot q$ ' + _joint_unit(joint_types, '/s$^2$')),
            ('dddq', r'$\dddot q$ ' + _joint_unit(joint_types, '/s$^3$'))]
    for col, meth in enumerate(methods):
        prof = timed[meth]
        for row, (key, label) in enumerate(rows):
            ax = axes[row, col]
            for j in range(prof[key].shape[1]):
                ax.plot(prof['t'], prof[key][:, j], color=f'C{j % 10}', lw=1.2)
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
            ax.set_ylabel(label, fontsize=8)
        axes[0, col].set_title(f'{_method(meth)}: {prof["t"][-1]:.3f} s', fontsize=9)
        axes[-1, col].set_xlabel(T_LABEL, fontsize=8)
    dof = next(iter(timed.values()))['dq'].shape[1]
    _joint_legend(axes[0, -1], dof, [], joint_names)
    _suptitle(fig, title or 'Joint velocity, acceleration and jerk in time, same joint limits')
    files = [_save(fig, out_dir, 'timed_joints.png')]

    fig = _figure((8.0, 5.5))
    axes2 = fig.subplots(2, 1, sharex=True)
    for meth, prof in timed.items():
        axes2[0].plot(prof['t'], np.linalg.norm(prof['dp'], axis=-1), label=_method(meth), **_style(meth))
        axes2[1].plot(prof['t'], np.linalg.norm(prof['dddp'], axis=-1), label=_method(meth), **_style(meth))
    axes2[0].set_ylabel(r'tool speed $|\dot p|$ (m/s)', fontsize=9)
    axes2[1].set_ylabel(r'tool jerk $|\dddot p|$ (m/s$^3$)', fontsize=9)
    axes2[1].set_xlabel(T_LABEL)
    for ax in axes2:
        ax.grid(alpha=0.3)
    _legend_outside(axes2[0])
    _suptitle(fig, title or 'Tool speed and jerk in time, same joint limits')
    files.append(_save(fig, out_dir, 'timed_tool.png'))
    return files


class JointSeries(Protocol):
    """A sampled joint trajectory (e.g. :class:`geodesic_planner.io.bags.TrajectoryRecord`)."""

    @property
    def topic(self) -> str: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def t(self) -> np.ndarray: ...
    @property
    def positions(self) -> np.ndarray: ...
    @property
    def velocities(self) -> np.ndarray | None: ...
    @property
    def accelerations(self) -> np.ndarray | None: ...


def plot_trajectories(path: str | os.PathLike[str], columns: Sequence[tuple[str, JointSeries | None]], *,
                      title: str = '', robot: Chain | None = None) -> str:
    """One PNG of joint trajectories side by side: rows position, velocity, acceleration vs time.

    Args:
        path: PNG file to write.
        columns: (heading, trajectory or None) per column, e.g. before and after processing;
            t in s, positions (N, dof) in rad or m, velocities /s, accelerations /s² (None: not
            in the message, shown as a note).
        title: figure title.
        robot: the model of the joints (optional). With it, every panel shows the joints' limits
            (position, velocity, acceleration; dashed, ``gid`` ``'limit'``; a limit far off the
            data's scale is named in the panel instead of squeezing the curves), and a last column
            shows the tool path ``robot.fk(positions)`` (``gid`` ``'tool path'``) against the straight
            line from its first to its last point: top and side views (the top view alone, taller,
            for a planar arm) and the distance from the line against time.

    Returns:
        ``path`` as a string.
    """
    ncols = max(len(columns), 1)
    extra = 1 if robot is not None else 0
    fig = _figure((6.0 * ncols + 1.5 + 5.0 * extra, 8.0))
    grid = fig.add_gridspec(3, ncols + extra, width_ratios=[1.0] * ncols + [0.85] * extra)
    axes = np.empty((3, ncols), dtype=object)
    for row in range(3):
        for col in range(ncols):
            axes[row, col] = fig.add_subplot(grid[row, col], sharey=axes[row, 0] if col else None)
    labels = ('position (rad or m)', 'velocity (rad/s or m/s)', r'acceleration (rad/s$^2$ or m/s$^2$)')
    colors = [f'C{k}' for k in range(10)]
    legend_done = False
    for col, (heading, rec) in enumerate(columns):
        axes[0, col].set_title(f'{heading}: {rec.topic}' if rec is not None else f'{heading}: none', fontsize=9)
        if rec is None:
            continue
        style = {'marker': 'o', 'ms': 3, 'lw': 0.8} if rec.t.size <= 200 else {'lw': 1.5}
        for row, values in enumerate((rec.positions, rec.velocities, rec.accelerations)):
            ax = axes[row, col]
            if values is None:
                ax.text(0.5, 0.5, 'not in message', ha='center', va='center', transform=ax.transAxes, color='gray')
                continue
            for j, name in enumerate(rec.joint_names):
                ax.plot(rec.t, values[:, j], color=colors[j % len(colors)], label=name, **style)
        if robot is not None:
            _limit_lines(axes[:, col], rec, robot, colors)
        if not legend_done:
            handles, names = axes[0, col].get_legend_handles_labels()
            axes[0, -1].legend(handles, names, fontsize=7, loc='upper left', bbox_to_anchor=(1.02, 1.0),
                               borderaxespad=0.0)
            legend_done = True
    if robot is not None:
        for row in range(3):
            _fit_limits(axes[row])
        _tool_column(fig, grid, ncols, columns, robot)
    for row, label in enumerate(labels):
        axes[row, 0].set_ylabel(label)
        for col in range(ncols):
            axes[row, col].grid(True, alpha=0.3)
            if col:
                axes[row, col].tick_params(labelleft=False)
    for col in range(ncols):
        axes[-1, col].set_xlabel('time from start (s)')
    fig.suptitle(title, fontsize=10)
    return save_png(fig, path)


def _joint_order(rec: JointSeries, robot: Chain) -> list[int]:
    """The robot's index of each of the record's joints."""
    from ..core.errors import RequestError
    missing = [n for n in rec.joint_names if n not in robot.joint_names]
    if missing:
        raise RequestError(f'plot: joints {missing} are not joints of {robot.name!r} ({robot.joint_names})')
    return [robot.joint_names.index(n) for n in rec.joint_names]


def _limit_lines(axes: np.ndarray, rec: JointSeries, robot: Chain, colors: Sequence[str]) -> None:
    """Dashed lines at the joints' limits in the three rows (one line per distinct value: black when
    several joints share it, else the joint's colour)."""
    idx = _joint_order(rec, robot)
    rows = ((robot.lower, robot.upper), (-robot.max_velocity, robot.max_velocity),
            (-robot.max_acceleration, robot.max_acceleration))
    for ax, (lo, hi) in zip(axes, rows):
        values: dict[float, list[int]] = {}
        for j, k in enumerate(idx):
            for v in (float(lo[k]), float(hi[k])):
                if math.isfinite(v):
                    values.setdefault(v, []).append(j)
        for n, (v, joints) in enumerate(sorted(values.items())):
            ax.axhline(v, color='k' if len(joints) > 1 else colors[joints[0] % len(colors)], ls='--', lw=0.9,
                       alpha=0.8, gid='limit', label='limits (dashed)' if n == 0 else None)


def _fit_limits(row: Sequence[Axes]) -> None:
    """The row's y range: the data's, widened to its limit lines when they lie within one data span of
    it; the limits beyond that are named in the panel."""
    data = [np.asarray(line.get_ydata(), dtype=float) for ax in row for line in ax.get_lines()
            if line.get_gid() != 'limit']
    finite = np.concatenate([d[np.isfinite(d)] for d in data]) if data else np.zeros(0)
    if finite.size == 0:
        return
    lo, hi = float(finite.min()), float(finite.max())
    span = max(hi - lo, 1e-9)
    limits = sorted({float(np.asarray(line.get_ydata())[0]) for ax in row for line in ax.get_lines()
                     if line.get_gid() == 'limit'})
    near = [v for v in limits if lo - span <= v <= hi + span]
    far = [v for v in limits if v not in near]
    lo, hi = min([lo, *near]), max([hi, *near])
    pad = 0.06 * max(hi - lo, 1e-9)
    row[0].set_ylim(lo - pad, hi + pad)
    if far:
        for ax in row:
            ax.text(0.01, 0.98, 'joint limits off the scale: ' + ', '.join(f'{v:.4g}' for v in far),
                    transform=ax.transAxes, ha='left', va='top', fontsize=7, color='0.3')


def _tool_column(fig: Figure, grid: Any, col: int, columns: Sequence[tuple[str, JointSeries | None]],  # noqa: ANN401
                 robot: Chain) -> None:
    """The tool path of each trajectory (fk of its positions) in views of the base frame, against the
    straight line between its ends, and its distance from that line against time."""
    from ..core.transforms import segment_distance
    from ..core.errors import RequestError
    paths = []
    for heading, rec in columns:
        if rec is None:
            continue
        idx = _joint_order(rec, robot)
        if sorted(idx) != list(range(robot.dof)):
            raise RequestError(f'plot: {heading} has joints {rec.joint_names}, not every joint of {robot.name!r}')
        paths.append((heading, rec, robot.fk(rec.positions[:, np.argsort(idx)])[:, :3, 3]))
    if not paths:
        return
    first = paths[0][2]
    a, b = first[0], first[-1]
    planar = all(np.ptp(p[:, 2]) < 1e-9 for _, _, p in paths)
    views = [((0, 1), 'tool path, top view (xy plane, base frame)', grid[0:2, col] if planar else grid[0, col])]
    if not planar:
        views.append(((0, 2), 'tool path, side view (xz plane, base frame)', grid[1, col]))
    for (i, j), name, cell in views:
        ax = fig.add_subplot(cell)
        ax.plot([a[i], b[i]], [a[j], b[j]], color='k', ls=':', lw=1.0, label='straight line start -> goal')
        for k, (heading, _rec, p) in enumerate(paths):
            ax.plot(p[:, i], p[:, j], color=f'C{k}', ls='-' if k == 0 else '--', lw=2.2 - 0.8 * k,
                    gid='tool path', label=f'tool, {heading}')
        for end, word in ((a, 'start'), (b, 'goal')):
            ax.plot(end[i], end[j], 'ko', ms=4)
            ax.annotate(word, (end[i], end[j]), xytext=(5, 5), textcoords='offset points', fontsize=8)
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_xlabel(f'tool ${"xyz"[i]}$ (m)', fontsize=8)
        ax.set_ylabel(f'tool ${"xyz"[j]}$ (m)', fontsize=8)
        ax.set_title(name, fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, loc='best')
    ax = fig.add_subplot(grid[2, col])
    worst = 0.0
    for k, (heading, rec, p) in enumerate(paths):
        dev = segment_distance(p, a, b)
        worst = max(worst, float(dev.max()))
        ax.plot(rec.t, dev, color=f'C{k}', ls='-' if k == 0 else '--', label=heading)
    ax.ticklabel_format(axis='y', style='sci', scilimits=(-2, 3))
    ax.set_xlabel('time from start (s)')
    ax.set_ylabel('distance (m)')
    ax.set_title(f'tool distance from the straight line (largest {worst:.2g} m)', fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc='best')


def plot_via_blend(path: str | os.PathLike[str],
                   runs: Sequence[tuple[str, np.ndarray, np.ndarray, np.ndarray]],
                   via_positions: np.ndarray, blend_radius: float, *, title: str = '') -> str:
    """One PNG of motions through via poses: the tool path in the xy plane with the via poses and
    circles of radius ``blend_radius`` around them (left), the tool speed vs time (right).

    Args:
        path: PNG file to write.
        runs: (label, t (N,) in s, tool positions (N, 3) in m (base frame), tool speed (N,) in m/s)
            per motion, e.g. stopping at the via poses and blended.
        via_positions: the poses the motion passes, start and goal included, (K, 3), m.
        blend_radius: m (0: no circles).
        title: figure title.

    Returns:
        ``path`` as a string.
    """
    from matplotlib.patches import Circle

    fig = _figure((11.0, 4.2))
    ax_xy, ax_v = fig.subplots(1, 2, gridspec_kw={'width_ratios': [1.0, 1.3]})
    via = np.asarray(via_positions, dtype=float)
    for k, (label, t, tool, speed) in enumerate(runs):
        ax_xy.plot(tool[:, 0], tool[:, 1], color=f'C{k}', label=label, **_style('geodesic'))
        ax_v.plot(t, speed, color=f'C{k}', label=label, **_style('geodesic'))
    ax_xy.plot(via[:, 0], via[:, 1], ls=':', lw=0.8, color='gray', label='polyline start-via-goal')
    ax_xy.plot(via[1:-1, 0], via[1:-1, 1], 'kx', ms=7, label='via poses')
    ax_xy.plot(via[[0, -1], 0], via[[0, -1], 1], 'ko', ms=5, mfc='none', label='start, goal')
    if blend_radius > 0.0:
        for k, (x, y) in enumerate(via[1:-1, :2]):
            ax_xy.add_patch(Circle((x, y), blend_radius, fill=False, ls='--', lw=0.8, color='C3',
                                   label=f'blend radius {blend_radius:g} m' if k == 0 else None))
    tool_path_and_speed_axes(ax_xy, ax_v, 'tool speed')
    handles, labels = ax_xy.get_legend_handles_labels()     # one legend for both, to the right
    ax_v.legend(handles, labels, loc='upper left', bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                fontsize=7)
    return save_png(fig, path, title)


__all__ = ['DPI', 'JointSeries', 'is_planar', 'plot_comparison', 'plot_timed_comparison', 'plot_trajectories',
           'plot_via_blend', 'save_png', 'tool_path_and_speed_axes']
