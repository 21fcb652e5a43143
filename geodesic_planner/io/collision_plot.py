"""The collision figure: the arm along a motion among boxes, its links drawn as the solids the check
uses (top view, and a side view for a spatial arm), and the clearance to each box against the
fraction of the way.

matplotlib through :class:`matplotlib.figure.Figure` and the Agg canvas, as in
:mod:`geodesic_planner.io.plotting`.
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..core.collision_bodies import Shape
from .plotting import _figure, save_png

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ['ArmView', 'BoxTrace', 'Closest', 'convex_outline', 'outline', 'plot_collision']

#: One box of the figure: (label, centre (3,) m base frame, edge m, clearance along the motion
#: (N,) m, the fraction of the way where a plan with it was refused or NaN).
BoxTrace = tuple[str, np.ndarray, float, np.ndarray, float]
#: Arm poses drawn thin along the motion.
ARM_POSES = 7
#: Points per circle when a round solid is projected.
ROUND = 48
#: The projections: (axes of the base frame, name).
TOP, SIDE = ((0, 1), 'top view (xy plane, base frame)'), ((0, 2), 'side view (xz plane, base frame)')


@dataclass(frozen=True)
class ArmView:
    """One pose of the arm drawn as the solids the collision check uses.

    Attributes:
        label: e.g. ``'start'``, ``'goal'``, ``'refused here'``.
        solids: (shape, pose 4x4 in the base frame, m) of each checked body.
        colour: a matplotlib colour.
    """

    label: str
    solids: Sequence[tuple[Shape, np.ndarray]]
    colour: str


@dataclass(frozen=True)
class Closest:
    """Where a motion comes closest: ``value`` (m) between the bodies ``pair``, at their nearest
    points ``a`` and ``b`` (3,) m in the base frame, at the fraction ``fraction`` of the way."""

    value: float
    pair: tuple[str, str]
    a: np.ndarray
    b: np.ndarray
    fraction: float


def convex_outline(points: np.ndarray) -> np.ndarray:
    """The convex hull of 2-D points (M, 2), counter-clockwise, first point not repeated
    (Andrew's monotone chain)."""
    pts = np.unique(np.round(np.asarray(points, dtype=float), 12), axis=0)
    if len(pts) < 3:
        return pts

    def half(seq: np.ndarray) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2 and _turn(out[-2], out[-1], p) <= 0.0:
                out.pop()
            out.append(p)
        return out
    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _turn(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """The z component of (a - o) x (b - o): > 0 for a left turn."""
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _sphere_points(radius: float) -> np.ndarray:
    """Points on a sphere (ROUND x ROUND / 2 of them), m: a round solid projects to their hull."""
    a = np.linspace(0.0, 2.0 * math.pi, ROUND, endpoint=False)
    b = np.linspace(0.0, math.pi, ROUND // 2 + 1)
    A, B = np.meshgrid(a, b)
    return radius * np.stack([np.sin(B) * np.cos(A), np.sin(B) * np.sin(A), np.cos(B)], axis=-1).reshape(-1, 3)


def _circle(radius: float, z: float) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * math.pi, ROUND, endpoint=False)
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.full(ROUND, z)], axis=1)


def outline(shape: Shape, pose: np.ndarray, axes: tuple[int, int] = (0, 1)) -> np.ndarray | None:
    """The outline of a solid seen along the base frame's third axis: the convex hull (M, 2), m, of
    its projection onto the base-frame ``axes`` (a mesh: of its vertices' projection; None for a
    mesh file, whose vertices are not at hand).

    Args:
        shape: the solid (:class:`~geodesic_planner.core.collision_bodies.Shape`, its own frame).
        pose: 4x4, its frame in the base frame, m.
        axes: the two base-frame axes kept (0 x, 1 y, 2 z).
    """
    d = shape.dimensions
    if shape.kind == 'box':
        local = 0.5 * np.array([[sx * d[0], sy * d[1], sz * d[2]]
                                for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    elif shape.kind == 'sphere':
        local = _sphere_points(d[0])
    elif shape.kind == 'capsule':
        ball = _sphere_points(d[1])
        local = np.concatenate([ball + [0.0, 0.0, -0.5 * d[0]], ball + [0.0, 0.0, 0.5 * d[0]]])
    elif shape.kind == 'cylinder':
        local = np.concatenate([_circle(d[1], -0.5 * d[0]), _circle(d[1], 0.5 * d[0])])
    elif shape.kind == 'cone':
        local = np.concatenate([_circle(d[1], -0.5 * d[0]), [[0.0, 0.0, 0.5 * d[0]]]])
    elif shape.vertices is not None:
        local = np.asarray(shape.vertices, dtype=float) * np.asarray(shape.scale)
    else:
        return None
    world = local @ np.asarray(pose)[:3, :3].T + np.asarray(pose)[:3, 3]
    return convex_outline(world[:, list(axes)])


def _draw_solids(ax: Axes, solids: Sequence[tuple[Shape, np.ndarray]], axes: tuple[int, int], label: str,
                 **style: object) -> None:
    from matplotlib.patches import Polygon
    for shape, pose in solids:
        poly = outline(shape, pose, axes)
        if poly is not None and len(poly) >= 3:
            ax.add_patch(Polygon(poly, closed=True, label=label, **style))
            label = ''


def plot_collision(path: str | os.PathLike[str], arm: np.ndarray, tool: np.ndarray, s: np.ndarray,
                   boxes: Sequence[BoxTrace], padding: float, *, title: str = '',
                   views: Sequence[ArmView] = (), closest: Closest | None = None,
                   planar: bool | None = None) -> str:
    """One PNG: the arm among the boxes, top view (and side view for a spatial arm), and the
    clearance (m) of the motion to each box against the fraction of the way, with the padding.

    The geometry panels: the arm's polyline (base, joints, tool) at :data:`ARM_POSES` instants,
    thin; each of ``views`` as the outlines of its solids (the capsules the check uses); the tool
    path with its start and goal labelled; the boxes; the place of a refusal; ``closest`` as a
    segment between its two nearest points. The distance panel: each box's distance to the arm, the
    padding, the refusal, ``closest`` marked (over every checked pair: it may be two links), and the
    part below zero (the solids overlap) shaded.

    Args:
        path: PNG file to write.
        arm: (N, K, 3) points of the arm's polyline per sample (base, joints, tool), m.
        tool: (N, 3) tool positions, m.
        s: (N,) fraction of the way of each sample (0 at the start, 1 at the goal).
        boxes: :data:`BoxTrace` per box (its clearance: its distance to the arm's checked solids).
        padding: the collision padding, m.
        title: figure title.
        views: arm poses drawn as their solids.
        closest: the motion's smallest clearance, marked (e.g. the node's min_clearance).
        planar: one top view only; default: when the arm stays in the plane z = 0.
    Returns:
        ``path`` as a string.
    """
    if planar is None:
        planar = bool(np.ptp(arm[..., 2]) < 1e-9 and np.ptp(tool[:, 2]) < 1e-9)
    projections = [TOP] if planar else [TOP, SIDE]
    fig = _figure((11.0, 4.6) if planar else (15.5, 4.8))
    axs = fig.subplots(1, len(projections) + 1,
                       gridspec_kw={'width_ratios': [1.0] * len(projections) + [1.3]})
    ax_d = axs[-1]
    picks = np.unique(np.linspace(0, len(arm) - 1, ARM_POSES).round().astype(int))
    for ax, (axes, name) in zip(axs[:-1], projections):
        i, j = axes
        for k, n in enumerate(picks):
            ax.plot(arm[n, :, i], arm[n, :, j], '-o', color='0.55', alpha=0.5, lw=1.0, ms=2,
                    label='arm along the planned motion (joints)' if k == 0 else None)
        for view in views:
            _draw_solids(ax, view.solids, axes, f'{view.label}: checked capsules', fill=False,
                         edgecolor=view.colour, lw=1.3)
        for k, (label, centre, edge, _clearance, refused_at) in enumerate(boxes):
            colour = f'C{k + 3}'
            _draw_solids(ax, [(Shape('box', (edge, edge, edge)), _at(centre))], axes, f'box {label} ({edge:g} m)',
                         color=colour, alpha=0.35)
            if math.isfinite(refused_at):
                at = tool[0] + refused_at * (tool[-1] - tool[0])
                ax.plot(at[i], at[j], 'x', color=colour, ms=9, mew=2,
                        label=f'refused at {100 * refused_at:.1f} % of the way')
        ax.plot(tool[:, i], tool[:, j], color='C0', lw=1.4, label='tool path (planned)')
        for end, word in ((tool[0], 'start'), (tool[-1], 'goal')):
            ax.plot(end[i], end[j], 'o', color='C0', ms=5)
            ax.annotate(word, (end[i], end[j]), xytext=(6, 6), textcoords='offset points', fontsize=9,
                        color='C0', weight='bold')
        if closest is not None:
            ax.plot([closest.a[i], closest.b[i]], [closest.a[j], closest.b[j]], '-', color='k', lw=1.6,
                    marker='|', ms=8, label=f'min_clearance {closest.value:.4f} m')
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_xlabel(f'${"xyz"[i]}$ (m)')
        ax.set_ylabel(f'${"xyz"[j]}$ (m)')
        ax.set_title(name, fontsize=9)
        ax.grid(True, alpha=0.3)
    for k, (label, _centre, _edge, clearance, refused_at) in enumerate(boxes):
        colour = f'C{k + 3}'
        ax_d.plot(s, clearance, color=colour, lw=1.5, label=f'arm to the box {label}')
        if math.isfinite(refused_at):
            ax_d.axvline(refused_at, color=colour, ls=':', lw=1.0,
                         label=f'refused by the node at {100 * refused_at:.1f} %: first place within\n'
                               'the padding (to the check\'s 1 mm resolution)')
    ax_d.axhline(padding, color='k', ls='--', lw=0.8, label=f'collision_padding {padding:g} m')
    ax_d.axhline(0.0, color='k', lw=0.5)
    lowest = min([0.0] + [float(np.min(b[3])) for b in boxes])
    if lowest < 0.0:
        ax_d.axhspan(1.1 * lowest, 0.0, color='0.85', zorder=0,
                     label='below 0: the solids overlap;\nthe depth of penetration')
    if closest is not None:
        ax_d.plot(closest.fraction, closest.value, 'o', color='k', ms=6,
                  label=f'min_clearance {closest.value:.4f} m\n({closest.pair[0]!r}, {closest.pair[1]!r})')
    ax_d.set_xlabel('fraction of the way (1)')
    ax_d.set_ylabel('distance (m)')
    ax_d.set_title('distance of each box to the arm along the motion', fontsize=9)
    ax_d.grid(True, alpha=0.3)
    for ax in (axs[0], ax_d):          # the side view has the top view's entries
        ax.legend(fontsize=6.5, loc='best', framealpha=0.85)
    return save_png(fig, path, title)


def _at(centre: np.ndarray) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = centre
    return pose
