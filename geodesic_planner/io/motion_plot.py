"""Figures of the motion types: a blended sequence (tool path with its zones, tool speed against
time) and a PTP comparison (joints and kinetic energy of two paths).

matplotlib through :class:`matplotlib.figure.Figure` and the Agg canvas, as in
:mod:`geodesic_planner.io.plotting`.
"""
from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from .plotting import _figure, save_png, tool_path_and_speed_axes

__all__ = ['plot_ptp_comparison', 'plot_sequence']


def plot_sequence(path: str | os.PathLike[str], t: np.ndarray, tool: np.ndarray, speed: np.ndarray,
                  zones: Sequence[tuple[float, float]], goals: np.ndarray, labels: Sequence[str], *,
                  title: str = '') -> str:
    """One PNG: left, the tool path (xy plane, base frame) with the goals and the parts inside blend
    zones; right, the tool speed against time with the zones shaded.

    Args:
        path: PNG file to write.
        t: (N,) times, s; tool: (N, 3) tool positions, m; speed: (N,) tool speed, m/s.
        zones: (t_start, t_end) of each blend zone, s.
        goals: (K, 3) the start and every item's goal, m; labels: the K - 1 items' motion types.
        title: figure title.
    Returns:
        ``path`` as a string.
    """
    fig = _figure((11.0, 4.2))
    ax_xy, ax_v = fig.subplots(1, 2, gridspec_kw={'width_ratios': [1.0, 1.3]})
    ax_xy.plot(tool[:, 0], tool[:, 1], color='C0', lw=1.6, label='tool path')
    for k, (a, b) in enumerate(zones):
        inside = (t >= a) & (t <= b)
        ax_xy.plot(tool[inside, 0], tool[inside, 1], color='C3', lw=3.0, alpha=0.7,
                   label='inside a blend zone' if k == 0 else None)
        ax_v.axvspan(a, b, color='C3', alpha=0.15, label='blend zone' if k == 0 else None)
    ax_xy.plot(goals[:, 0], goals[:, 1], 'ko', ms=5, mfc='none', label='start and goals')
    for k, name in enumerate(labels):
        mid = 0.5 * (goals[k] + goals[k + 1])
        ax_xy.annotate(name, mid[:2], fontsize=8, color='0.3')
    ax_v.plot(t, speed, color='C0', lw=1.6, label='tool speed')
    tool_path_and_speed_axes(ax_xy, ax_v, 'tool speed: no stop inside the blends')
    for ax in (ax_xy, ax_v):
        ax.legend(fontsize=7, loc='best')
    return save_png(fig, path, title)


def plot_ptp_comparison(path: str | os.PathLike[str],
                        runs: Sequence[tuple[str, np.ndarray, np.ndarray, np.ndarray]],
                        joint_names: Sequence[str], *, title: str = '') -> str:
    """One PNG: left, every joint against the path parameter for each run; right, the kinetic
    energy against normalised time.

    Args:
        path: PNG file to write.
        runs: (label, s (N,), q (N, dof) rad or m, kinetic energy at s (N,) J for the timed motion)
            per path (e.g. kinetic_energy and joint_line).
        joint_names: the joints' names.
        title: figure title.
    Returns:
        ``path`` as a string.
    """
    fig = _figure((11.0, 4.2))
    ax_q, ax_e = fig.subplots(1, 2)
    styles = ('-', '--', ':')
    for k, (label, s, q, energy) in enumerate(runs):
        ls = styles[k % len(styles)]
        for j in range(q.shape[1]):
            ax_q.plot(s, q[:, j], color=f'C{j}', ls=ls, lw=1.3,
                      label=f'{joint_names[j]}' if k == 0 else None)
        ax_e.plot(np.linspace(0.0, 1.0, energy.size), energy, color=f'C{k}', ls=ls, lw=1.6, label=label)
    for k, (label, *_rest) in enumerate(runs):
        ax_q.plot([], [], color='k', ls=styles[k % len(styles)], label=label)
    ax_q.set_xlabel(r'path parameter $s$ (1)')
    ax_q.set_ylabel('joint position (rad)')
    ax_q.set_title('joints', fontsize=9)
    ax_e.set_xlabel('time / duration (1)')
    ax_e.set_ylabel('kinetic energy (J)')
    ax_e.set_title('kinetic energy of the timed motions', fontsize=9)
    for ax in (ax_q, ax_e):          # legends below the axes: never over a curve
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc='upper center', bbox_to_anchor=(0.5, -0.16), ncol=2)
    return save_png(fig, path, title)
