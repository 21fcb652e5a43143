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
