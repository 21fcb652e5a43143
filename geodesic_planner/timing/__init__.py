"""Time laws: rest-to-rest timing of a joint path under per-joint limits, and the Trajectory type."""
from __future__ import annotations

from .parameterize import Trajectory, time_parameterize

__all__ = ['Trajectory', 'time_parameterize']
