"""Figures of the motion types: a blended sequence (tool path with its zones, tool speed against
time) and a PTP comparison (joints and kinetic energy of two paths).

matplotlib through :class:`matplotlib.figure.Figure` and the Agg canvas, as in
:mod:`geodesic_planner.io.plotting`.
"""
from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from .plotting import T_LABEL, _figure, save_png

__all__ = ['plot_ptp_comparison', 'plot_sequence']


def plot_sequence(path: str | os.PathLike[str], t: np.ndarray, tool: np.ndarray, speed: np.ndarray,
                  zones: Sequence[tuple[float, float]], goals: np.ndarray, labels: Sequence[str], *,
                  title: str = '') -> str:
    """One PNG: the tool path in the top view (xy plane, base frame) and, when it leaves its plane,
    the side view (xz plane), with the goals and the parts inside blend zones; right, the tool speed
    against time with the zones shaded.

    Args:
        path: PNG file to write.
        t: (N,) times, s; tool: (N, 3) tool positions, m; speed: (N,) tool speed, m/s.
        zones: (t_start, t_end) of each blend zone, s.
        goals: (K, 3) the start and every item's goal, m; labels: the K - 1 items' motion types.
        title: figure title.
    Returns:
        ``path`` as a string.
    """
    views = [((0, 1), 'tool path, top view (xy plane, base frame)')]
    if np.ptp(tool[:, 2]) > 1e-9:
        views.append(((0, 2), 'tool path, side view (xz plane, base frame)'))
    fig = _figure((5.5 * len(views) + 6.0, 4.4))
    axs = fig.subplots(1, len(views) + 1, gridspec_kw={'width_ratios': [1.0] * len(views) + [1.3]})
    ax_v = axs[-1]
    inside = [(t >= a) & (t <= b) for a, b in zones]
    for ax, ((i, j), name) in zip(axs[:-1], views):
        ax.plot(tool[:, i], tool[:, j], color='C0', lw=1.6, label='tool path', gid='tool path')
        for k, mask in enumerate(inside):
            ax.plot(tool[mask, i], tool[mask, j], color='C3', lw=3.0, alpha=0.7,
                    label='inside a blend zone' if k == 0 else None)
        ax.plot(goals[:, i], goals[:, j], 'ko', ms=5, mfc='none', label='start and goals')
        ax.annotate('start', goals[0, [i, j]], xytext=(5, -12), textcoords='offset points', fontsize=8)
        for k, kind in enumerate(labels):
            mid = 0.5 * (goals[k] + goals[k + 1])
            ax.annotate(kind, mid[[i, j]], fontsize=8, color='0.3')
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_xlabel(f'tool ${"xyz"[i]}$ (m)')
        ax.set_ylabel(f'tool ${"xyz"[j]}$ (m)')
        ax.set_title(name, fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc='best')
    for k, (a, b) in enumerate(zones):
        ax_v.axvspan(a, b, color='C3', alpha=0.15, label='blend zone' if k == 0 else None)
    ax_v.plot(t, speed, color='C0', lw=1.6, label='tool speed')
    ax_v.set_xlabel(T_LABEL)
    ax_v.set_ylabel(r'tool speed $|v|$ (m/s)')
    ax_v.set_title('tool speed: no stop inside the blends', fontsize=9)
    ax_v.grid(True, alpha=0.3)
    ax_v.legend(fontsize=7, loc='best')
    return save_png(fig, path, title)


def plot_ptp_comparison(path: str | os.PathLike[str],
                        runs: Sequence[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
                        joint_names: Sequence[str], *, title: str = '') -> str:
    """One PNG: left, every joint against the path parameter for each run; right, the kinetic
    energy of each timed run against time (one time axis: each run ends at its duration, marked).

    Args:
        path: PNG file to write.
        runs: (label, s (N,), q (N, dof) rad or m, t (M,) s, kinetic energy at t (M,) J) per path
            (e.g. kinetic_energy and joint_line).
        joint_names: the joints' names.
        title: figure title.
    Returns:
        ``path`` as a string.
    """
    from matplotlib.lines import Line2D

    fig = _figure((12.0, 4.6))
    ax_q, ax_e = fig.subplots(1, 2)
    styles = ('-', '--', ':')
    for k, (label, s, q, t, energy) in enumerate(runs):
        ls = styles[k % len(styles)]
        for j in range(q.shape[1]):
            ax_q.plot(s, q[:, j], color=f'C{j % 10}', ls=ls, lw=1.3)
        ax_e.plot(t, energy, color=f'C{k}', ls=ls, lw=1.6, label=label)
        ax_e.axvline(t[-1], color=f'C{k}', ls=':', lw=0.9)
        ax_e.annotate(f'{t[-1]:.3f} s', (t[-1], 0.0), xytext=(3, 4), textcoords='offset points', fontsize=8,
                      color=f'C{k}', rotation=90, va='bottom')
    handles = [Line2D([], [], color=f'C{j % 10}', lw=1.5) for j in range(len(joint_names))]
    handles += [Line2D([], [], color='k', ls=styles[k % len(styles)]) for k in range(len(runs))]
    names = [n.replace('_', ' ') for n in joint_names] + [r[0].split(':')[0] for r in runs]
    ax_q.legend(handles, names, fontsize=7, loc='best', ncol=2, framealpha=0.85)
    ax_q.set_xlabel(r'path parameter $s$ (1)')
    ax_q.set_ylabel('joint position (rad)')
    ax_q.set_title('joints along each path', fontsize=9)
    ax_e.set_xlabel(T_LABEL)
    ax_e.set_ylabel('kinetic energy (J)')
    ax_e.set_title('kinetic energy of the timed motions (each ends at its duration)', fontsize=9)
    ax_e.set_ylim(bottom=0.0)
    ax_e.legend(fontsize=7, loc='best', framealpha=0.85)
    for ax in (ax_q, ax_e):
        ax.grid(True, alpha=0.3)
    return save_png(fig, path, title)
