"""The collision figure: the arm along a motion among boxes (top view), and the clearance to each box
against the fraction of the way.

matplotlib through :class:`matplotlib.figure.Figure` and the Agg canvas, as in
:mod:`geodesic_planner.io.plotting`.
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

from .plotting import _figure, save_png

__all__ = ['BoxTrace', 'plot_collision']

#: One box of the figure: (label, centre (3,) m base frame, edge m, clearance along the motion
#: (N,) m, the fraction of the way where a plan with it was refused or NaN).
BoxTrace = tuple[str, np.ndarray, float, np.ndarray, float]
#: Arm poses drawn along the motion.
ARM_POSES = 7


def plot_collision(path: str | os.PathLike[str], arm: np.ndarray, tool: np.ndarray, s: np.ndarray,
                   boxes: Sequence[BoxTrace], padding: float, *, title: str = '') -> str:
    """One PNG: left, the arm (xy plane, base frame) at :data:`ARM_POSES` instants along the motion,
    the tool path and each box (a refusal marked on the path); right, the clearance (m) of the
    motion to each box against the fraction of the way, with the padding.

    Args:
        path: PNG file to write.
        arm: (N, K, 3) points of the arm's polyline per sample (base, joints, tool), m.
        tool: (N, 3) tool positions, m.
        s: (N,) fraction of the way of each sample (0 at the start, 1 at the goal).
        boxes: :data:`BoxTrace` per box.
        padding: the collision padding, m.
        title: figure title.
    Returns:
        ``path`` as a string.
    """
    from matplotlib.patches import Rectangle

    fig = _figure((11.0, 4.4))
    ax_xy, ax_d = fig.subplots(1, 2, gridspec_kw={'width_ratios': [1.0, 1.3]})
    picks = np.unique(np.linspace(0, len(arm) - 1, ARM_POSES).round().astype(int))
    for k, n in enumerate(picks):
        alpha = 0.25 + 0.75 * k / max(len(picks) - 1, 1)
        ax_xy.plot(arm[n, :, 0], arm[n, :, 1], '-o', color='0.35', alpha=alpha, lw=2.0, ms=3,
                   label='arm along the planned motion' if k == 0 else None)
    ax_xy.plot(tool[:, 0], tool[:, 1], color='C0', lw=1.2, label='tool path (planned)')
    for k, (label, centre, edge, clearance, refused_at) in enumerate(boxes):
        colour = f'C{k + 3}'
        ax_xy.add_patch(Rectangle((centre[0] - edge / 2, centre[1] - edge / 2), edge, edge, color=colour,
                                  alpha=0.35, label=f'box {label}'))
        ax_d.plot(s, clearance, color=colour, lw=1.5, label=f'to the box {label}')
        if math.isfinite(refused_at):
            at = tool[0] + refused_at * (tool[-1] - tool[0])
            ax_xy.plot(at[0], at[1], 'x', color=colour, ms=9, mew=2,
                       label=f'refused at {100 * refused_at:.1f} % of the way')
            ax_d.axvline(refused_at, color=colour, ls=':', lw=1.0,
                         label=f'refusal reported by the node ({100 * refused_at:.1f} %)')
    ax_d.axhline(padding, color='k', ls='--', lw=0.8, label=f'collision_padding {padding:g} m')
    ax_d.axhline(0.0, color='k', lw=0.5)
    ax_xy.set_aspect('equal', adjustable='datalim')
    ax_xy.set_xlabel(r'$x$ (m)')
    ax_xy.set_ylabel(r'$y$ (m)')
    ax_xy.set_title('arm and boxes (xy plane, base frame)', fontsize=9)
    ax_d.set_xlabel('fraction of the way (1)')
    ax_d.set_ylabel('clearance (m): smallest distance over the pairs')
    ax_d.set_title('clearance along the motion', fontsize=9)
    for ax in (ax_xy, ax_d):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc='best')
    return save_png(fig, path, title)
