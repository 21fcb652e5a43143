"""All figures: the paper's Fig. 5/6 (planar 3R) and Fig. 8-10 (spatial RRPP), and joint trajectories.

matplotlib is imported lazily (only when a figure is drawn) and used without pyplot, through
:class:`matplotlib.figure.Figure` and the Agg canvas, so it works headless and keeps no global state.
"""
from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Line styles per method (geodesic solid, polynomial dashed), as in the paper's legends.
STYLES = {'geodesic': {'ls': '-', 'lw': 1.6}, 'polynomial': {'ls': '--', 'lw': 1.2},
          'cartesian_ik': {'ls': ':', 'lw': 1.2}}
DPI = 80


def _figure(figsize: tuple[float, float]) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize, dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, out_dir: str, name: str) -> str:
    path = os.path.join(out_dir, name)
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=DPI, pil_kwargs={'optimize': True})
    except TypeError:  # very old matplotlib without pil_kwargs
        fig.savefig(path, dpi=DPI)
    return path


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


def plot_comparison(profiles: dict[str, dict[str, np.ndarray]], out_dir: str, *, title: str = '',
                    planar: bool | None = None) -> list[str]:
    """Write the comparison figures as PNG files.

    Args:
        profiles: method name -> profile from :func:`geodesic_planner.cli.compare.ee_profile`.
        out_dir: existing directory.
        title: figure title prefix.
        planar: planar (Fig. 5/6) or spatial (Fig. 8-10) layout; detected from the data when None.
    Returns:
        Paths of the PNG files written.
    """
    if planar is None:
        planar = is_planar(profiles)
    files = [
        _ee_position(profiles, out_dir, title, planar),
        _derivative_norms(profiles, out_dir, title, 'position'),
        _ee_orientation(profiles, out_dir, title, planar),
        _derivative_norms(profiles, out_dir, title, 'orientation'),
        _joints(profiles, out_dir, title),
    ]
    return files


def _ee_position(profiles: dict[str, Any], out_dir: str, title: str, planar: bool) -> str:
    fig = _figure((5.5, 4.5))
    if planar:
        ax = fig.add_subplot(1, 1, 1)
        for name, prof in profiles.items():
            ax.plot(prof['p'][:, 0], prof['p'][:, 1], label=f'{name} method', **_style(name))
        first = next(iter(profiles.values()))['p']
        ax.plot(first[[0, -1], 0], first[[0, -1], 1], 'o', color='k', ms=4, label='A, B')
        ax.set_xlabel('px (m)')
        ax.set_ylabel('py (m)')
        ax.set_aspect('equal', adjustable='datalim')
    else:
        ax = fig.add_subplot(1, 1, 1, projection='3d')
        for name, prof in profiles.items():
            ax.plot(prof['p'][:, 0], prof['p'][:, 1], prof['p'][:, 2], label=f'{name} method', **_style(name))
        first = next(iter(profiles.values()))['p']
        ax.plot(first[[0, -1], 0], first[[0, -1], 1], first[[0, -1], 2], 'k:', lw=0.8, label='chord A-B')
        ax.set_xlabel('px (m)')
        ax.set_ylabel('py (m)')
        ax.set_zlabel('pz (m)')
    ax.legend(fontsize=8)
    ax.set_title(f'{title}\nend-effector position (Fig. {"5(a)" if planar else "8(a)"})', fontsize=9)
    return _save(fig, out_dir, 'ee_position.png')


def _derivative_norms(profiles: dict[str, Any], out_dir: str, title: str, kind: str) -> str:
    fig = _figure((6.0, 6.0))
    if kind == 'position':
        keys = [('dp', 'vel. |dp/ds| (m)'), ('ddp', 'acc. |d²p/ds²| (m)'), ('dddp', 'jerk |d³p/ds³| (m)')]
        norm = lambda a: np.linalg.norm(a, axis=-1)  # noqa: E731
        head = 'end-effector position velocity, acceleration, jerk (Fig. 5(b)/8(b))'
        name = 'ee_position_derivatives.png'
    else:
        keys = [('dR', "vel. |R'|_F"), ('ddR', "acc. |R''|_F"), ('dddR', "jerk |R'''|_F")]
        norm = lambda a: np.linalg.norm(a, axis=(-2, -1))  # noqa: E731
        head = 'end-effector orientation (n, o, a) velocity, acceleration, jerk (Fig. 5(d))'
        name = 'ee_orientation_derivatives.png'
    for i, (key, label) in enumerate(keys):
        ax = fig.add_subplot(3, 1, i + 1)
        series = []
        for meth, prof in profiles.items():
            series.append(norm(prof[key]))
            ax.plot(prof['s'], series[-1], label=f'{meth} method', **_style(meth))
        _tidy(ax, series)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
        if i == 0:
            ax.set_title(f'{title}\n{head}', fontsize=9)
            ax.legend(fontsize=8)
    ax.set_xlabel('s')
    return _save(fig, out_dir, name)


def _ee_orientation(profiles: dict[str, Any], out_dir: str, title: str, planar: bool) -> str:
    if planar:
        fig = _figure((5.5, 4.5))
        ax = fig.add_subplot(1, 1, 1)
        for meth, prof in profiles.items():
            R = prof['R']
            ax.plot(R[:, 0, 0], R[:, 1, 0], label=f'n, {meth}', **_style(meth))
            ax.plot(R[:, 0, 1], R[:, 1, 1], label=f'o, {meth}', **_style(meth))
        ax.set_xlabel('nx, ox')
        ax.set_ylabel('ny, oy')
        ax.legend(fontsize=8)
        ax.set_title(f'{title}\nend-effector orientation (Fig. 5(c))', fontsize=9)
        ax.grid(alpha=0.3)
        return _save(fig, out_dir, 'ee_orientation.png')
    fig = _figure((11.0, 4.0))
    for i, axis_name in enumerate('noa'):
        ax = fig.add_subplot(1, 3, i + 1, projection='3d')
        for meth, prof in profiles.items():
            v = prof['R'][:, :, i]
            ax.plot(v[:, 0], v[:, 1], v[:, 2], label=meth, **_style(meth))
        ax.set_xlabel(f'{axis_name}x', fontsize=8)
        ax.set_ylabel(f'{axis_name}y', fontsize=8)
        ax.set_zlabel(f'{axis_name}z', fontsize=8)
        ax.tick_params(labelsize=6)
        ax.set_title(f'{axis_name} (Fig. 10)', fontsize=9)
        if i == 0:
            ax.legend(fontsize=7)
    fig.suptitle(f'{title}: end-effector orientation', fontsize=9)
    return _save(fig, out_dir, 'ee_orientation.png')


def _joints(profiles: dict[str, Any], out_dir: str, title: str) -> str:
    fig = _figure((12.0, 3.6))
    labels = [('q', 'joint positions'), ('dq', 'joint velocities'), ('ddq', 'joint accelerations'),
              ('dddq', 'joint jerks')]
    colors = ['C0', 'C1', 'C2', 'C3', 'C4', 'C5', 'C6', 'C7']
    for i, (key, label) in enumerate(labels):
        ax = fig.add_subplot(1, 4, i + 1)
        _tidy(ax, [prof[key] for prof in profiles.values()])
        for meth, prof in profiles.items():
            arr = prof[key]
            for j in range(arr.shape[1]):
                ax.plot(prof['s'], arr[:, j], color=colors[j % len(colors)],
                        label=f'joint {j + 1}, {meth}', **_style(meth))
        ax.set_xlabel('s')
        ax.set_title(label, fontsize=9)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
        if i == 0:
            ax.legend(fontsize=6)
    fig.suptitle(f'{title}: joint space (Fig. 6/9)', fontsize=9)
    return _save(fig, out_dir, 'joints.png')


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
                      title: str = '') -> str:
    """One PNG of joint trajectories side by side: rows position, velocity, acceleration vs time.

    Args:
        path: PNG file to write.
        columns: (heading, trajectory or None) per column, e.g. before and after processing;
            t in s, positions (N, dof) in rad or m, velocities /s, accelerations /s² (None: not
            in the message, shown as a note).
        title: figure title.

    Returns:
        ``path`` as a string.
    """
    ncols = max(len(columns), 1)
    fig = _figure((6.0 * ncols, 8.0))
    axes = fig.subplots(3, ncols, sharey='row', squeeze=False)
    labels = ('position [rad or m]', 'velocity [/s]', 'acceleration [/s²]')
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
        if not legend_done:
            axes[0, col].legend(fontsize=7, loc='best')
            legend_done = True
    for row, label in enumerate(labels):
        axes[row, 0].set_ylabel(label)
        for col in range(ncols):
            axes[row, col].grid(True, alpha=0.3)
    for col in range(ncols):
        axes[-1, col].set_xlabel('time from start [s]')
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(os.fspath(path), dpi=90)
    return os.fspath(path)


__all__ = ['JointSeries', 'is_planar', 'plot_comparison', 'plot_trajectories']
