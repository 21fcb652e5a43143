"""The constant-speed law (the paper's Lemma 2): ``s = t/T``, optionally with short ramps.

A geodesic has constant metric speed in its parameter, ``|q'(s)|_G = L``; Lemma 2 sets its speed by
rescaling the parameter. With ``s = t/T`` the metric speed in time is the constant ``L/T`` over the
whole move: this law picks the smallest ``T`` for which every limit holds.

**Shape.** In normalised time ``u = t/T`` the law is ``s = σ(u)`` with a fixed shape:

* ``ramp = 0``: ``σ(u) = u``, the pure law. ``ṡ = 1/T`` from the first instant to the last, so the
  joint velocities jump from 0 to ``q'(0)/T`` at the start and back to 0 after the end (an
  unbounded acceleration there, which no limit row sees). The trajectory does *not* end at rest:
  :func:`~.validate.check_trajectory` (joint_trajectory_controller's rule of a zero final velocity)
  rejects its samples, and the planner node, which requires rest at the end, must never use it.
* ``ramp = r`` in (0, 0.5]: during the first and last ``r T`` the speed rises (falls) with a cubic
  smoothstep, ``ṡ = v (3w² − 2w³)``, ``w = u/r``, so ``s̈`` is continuous and zero at both ends
  (rest to rest: zero velocity and zero acceleration, as the smoothing law's rests); in between
  ``ṡ = v = 1/((1 − r) T)``, constant. Each ramp covers ``v r T / 2`` of s. (``r = 0.5`` leaves
  no constant stretch: the speed peaks at mid-move.)

The pure law's duration can be *below* the time-optimal rest-to-rest duration
(``Trajectory.topp_duration``), since its start and stop are velocity jumps no row constrains; with
ramps it is above it (see ``DEFAULT_RAMP``).

**Minimal T.** Since ``ṡ ∝ 1/T`` and ``s̈ ∝ 1/T²`` for a fixed shape, each row gives its bound in
closed form from the shape alone: velocity rows (joints and tool) ``T ≥ max_u |q'(σ)| σ'(u) /
v_max``, acceleration rows ``T² ≥ max_u |q' σ'' + q'' σ'²| / a_max``. The maxima are taken over a
dense grid in u with the path evaluated exactly (no interpolation), refined around the largest
samples, and ``T`` is divided by ``1 − CHECK_MARGIN``. ``duration=`` stretches uniformly (never
below the minimum, which the error names).

**Corners.** Where q' jumps (via points of a piecewise path) no law with ``ṡ > 0`` is feasible;
with ramps each rest-to-rest piece between corners gets its own constant-speed law (constant
metric speed within each piece, rest at the corner); with ``ramp = 0`` a path with corners is
refused.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import LimitError
from ._arrays import clip
from .law import final_duration
from .types import JointLimits, PathLike
from .sampling import PathSamples, refine_adaptively, sample_path
from .tool import tool_kinematics, tool_rows, tool_speeds, tool_twist
from .topp import topp
from .trajectory import Trajectory
from .tuning import CHECK_MARGIN, TOPP_MARGIN

#: Default ramp: the fraction of each piece's duration spent accelerating (and as much braking).
#: Shorter ramps need higher accelerations: on the paper's 3R, RRPP and ur5e/panda moves the law
#: lasts about 2.0-2.5x the time-optimal duration with ramp 0.1, 1.4-1.6x with 0.25, 1.2-1.4x with 0.5.
DEFAULT_RAMP = 0.25
#: Uniform samples in u per piece for the minimal-T search (plus as many in each ramp).
PIECE_CHECK_SAMPLES = 2000
#: Samples around which the grid is refined (per piece), and points per refinement.
REFINE_TOP = 8
REFINE_POINTS = 33
#: The time-optimal reference runs on this many times finer steps than the path samples.
TOPP_REFINE = 2


def shape(u: np.ndarray, ramp: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The law's shape σ(u) and its derivatives σ', σ'', σ''' at normalised times u in [0, 1].

    ``s = σ(t/T)`` goes from 0 to 1; ``ramp`` in [0, 0.5] (see the module docstring). Each (M,).
    """
    u = clip(np.asarray(u, dtype=float), 0.0, 1.0)
    if ramp <= 0.0:
        one, zero = np.ones_like(u), np.zeros_like(u)
        return u.copy(), one, zero, zero.copy()
    r = float(ramp)
    v = 1.0 / (1.0 - r)
    tail = u > 0.5
    x = np.where(tail, 1.0 - u, u)                     # mirror the braking ramp onto the first
    w = np.minimum(x / r, 1.0)
    in_ramp = x < r
    s_head = np.where(in_ramp, v * r * (w**3 - 0.5 * w**4), v * (0.5 * r + (x - r)))
    sd = np.where(in_ramp, v * (3.0 * w**2 - 2.0 * w**3), v)
    sdd = np.where(in_ramp, v / r * 6.0 * w * (1.0 - w), 0.0)
    sddd = np.where(in_ramp, v / (r * r) * (6.0 - 12.0 * w), 0.0)
    s = np.where(tail, 1.0 - s_head, s_head)
    return s, sd, np.where(tail, -sdd, sdd), sddd


def inverse_shape(y: np.ndarray, ramp: float) -> np.ndarray:
    """The normalised times u (M,) at which σ(u) = y (M,), y in [0, 1] (bisection, to round-off)."""
    y = clip(np.asarray(y, dtype=float), 0.0, 1.0)
    lo, hi = np.zeros_like(y), np.ones_like(y)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        below = shape(mid, ramp)[0] < y
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


@dataclass(frozen=True, eq=False)
class ConstantSpeedScaling:
    """``s(t)`` of the constant-speed law: one shaped piece per rest-to-rest stretch of the path.

    Piece k runs from ``t_offsets[k]`` to ``t_offsets[k + 1]`` and moves s from ``s_bounds[k]``
    to ``s_bounds[k + 1]`` along the shape σ of :func:`shape`.
    """

    ramp: float
    t_offsets: np.ndarray  # (L + 1,) start time of each piece, s; the last is the duration
    s_bounds: np.ndarray   # (L + 1,) path parameter at the pieces' ends, 0 ... 1

    @property
    def duration(self) -> float:
        return float(self.t_offsets[-1])

    def evaluate(self, t: np.ndarray, jerk: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """s, sdot, sddot and (if ``jerk``) sdddot at times t (M,), clipped to [0, duration]."""
        t = clip(np.asarray(t, dtype=float), 0.0, self.duration)
        n = self.t_offsets.size - 1
        k = clip(np.searchsorted(self.t_offsets, t, side='right') - 1, 0, n - 1)
        T = np.diff(self.t_offsets)[k]
        span = np.diff(self.s_bounds)[k]
        u = np.where(t >= self.t_offsets[k + 1], 1.0, (t - self.t_offsets[k]) / T)
        sg, d1, d2, d3 = shape(u, self.ramp)
        s = np.where(u >= 1.0, self.s_bounds[k + 1], self.s_bounds[k] + span * sg)
        return s, span * d1 / T, span * d2 / T**2, (span * d3 / T**3) if jerk else None


def _topp_duration(ps: PathSamples, limits: JointLimits, tool_cap: np.ndarray | None) -> float:
    """Time-optimal (bang-bang) duration along the sampled path, s: the reference of the law."""
    x = topp(ps, limits.max_velocity * (1.0 - TOPP_MARGIN), limits.max_acceleration * (1.0 - TOPP_MARGIN),
             tool_cap)
    v = np.sqrt(np.maximum(x, 0.0))
    den = v[:-1] + v[1:]
    return float(np.sum(np.where(den > 0, 2.0 * np.diff(ps.s) / np.where(den > 0, den, 1.0), 0.0)))


@dataclass(frozen=True)
class ConstantSpeed:
    """Constant metric speed along the path (the paper's Lemma 2), a :class:`~.law.TimeLaw`.

    ``s = t/T`` with the smallest T within every limit (joint velocity and acceleration, tool
    speed rows), between optional smooth acceleration ramps at both ends.

    Attributes:
        ramp: fraction of the duration (of each piece between corners) spent speeding up, and as
            much slowing down, in [0, 0.5]. 0: the pure ``s = t/T``, which starts and ends with a
            velocity jump (not rest to rest: JTC's validator rejects its end, and a path with
            corners is refused). > 0: rest to rest, zero velocity and acceleration at both ends.
        grid_points: uniform s intervals of the path samples for the time-optimal reference
            duration (``Trajectory.topp_duration``) and the corner search (>= 2).
        check_samples: uniform samples in u per piece of the minimal-T search (>= 10); as many
            again are placed in each ramp.
    Raises:
        LimitError: an option out of range (at construction).
    """

    ramp: float = DEFAULT_RAMP
    grid_points: int = 100
    check_samples: int = PIECE_CHECK_SAMPLES

    def __post_init__(self) -> None:
        try:
            ramp = float(self.ramp)
        except (TypeError, ValueError) as err:
            raise LimitError(f'ramp must be a number in [0, 0.5], got {self.ramp!r}') from err
        if not (0.0 <= ramp <= 0.5):
            raise LimitError(f'ramp must be in [0, 0.5] (a fraction of the duration), got {self.ramp!r}')
        if int(self.grid_points) < 2:
            raise LimitError(f'grid_points must be >= 2, got {self.grid_points!r}')
        if int(self.check_samples) < 10:
            raise LimitError(f'check_samples must be >= 10, got {self.check_samples!r}')

    @property
    def rest_to_rest(self) -> bool:
        """True when the law starts and ends at rest (ramp > 0)."""
        return float(self.ramp) > 0.0

    def __call__(self, path: PathLike, limits: JointLimits, duration: float | None) -> Trajectory:
        """Time ``path`` at constant speed within ``limits``.

        Raises:
            LimitError: ``duration`` shorter than the minimum (the message gives it); a path with
                corners and ``ramp = 0``; a piece of the path that does not move; bad derivatives.
        """
        ps = refine_adaptively(path, sample_path(path, int(self.grid_points)))
        joint_names, vmax, amax = limits.joint_names, limits.max_velocity, limits.max_acceleration
        if ps.aR.shape[1] != vmax.size:
            raise LimitError(f'path.evaluate returned {ps.aR.shape[1]} joints, expected {vmax.size}')
        common = dict(path=path, joint_names=joint_names, max_velocity=vmax, max_acceleration=amax,
                      max_tool_speed=limits.max_tool_speed,
                      max_tool_angular_speed=limits.max_tool_angular_speed)
        if float(max(np.abs(ps.aR).max(), np.abs(ps.aL).max())) == 0.0:
            T = 0.0 if duration is None else duration   # stationary path, as the smoothing law
            return Trajectory(duration=T, topp_duration=0.0, min_duration=0.0, rest_times=(0.0, float(T)),
                              **common)  # type: ignore[arg-type]
        ramp = float(self.ramp)
        corners = ps.s[ps.stop]
        if corners.size and ramp == 0.0:
            raise LimitError(f'constant speed with ramp = 0 cannot pass the corner of the path at s = '
                             f'{float(corners[0]):.6g} (q\' jumps there): use ramp > 0 to rest at it')
        tool = tool_rows(path, limits, ps)
        # The reference, computed as the smoothing law computes its own (same steps, same margin).
        t_opt = _topp_duration(ps.refined(TOPP_REFINE), limits,
                               None if tool is None else tool.speed_cap(TOPP_REFINE, TOPP_MARGIN))
        bounds = np.concatenate([[0.0], corners, [1.0]])
        # Non-corner breakpoints (q'' may jump): both one-sided values are checked.
        sided = ps.s[((ps.aL != ps.aR).any(axis=1) | (ps.bL != ps.bR).any(axis=1)) & ~ps.stop]
        piece_T = np.array([self._min_time(path, limits, a, b, sided[(sided > a) & (sided < b)])
                            for a, b in itertools.pairwise(bounds.tolist())])
        t_min = float(piece_T.sum())
        T = float(final_duration(duration, t_min))
        offsets = np.concatenate([[0.0], np.cumsum(piece_T)])
        offsets[-1] = t_min
        scaling = ConstantSpeedScaling(ramp, offsets, bounds)
        scale = T / t_min
        rests: tuple[float, ...] = tuple(bounds.tolist()) if ramp > 0.0 else ()
        rest_times = tuple(float(t) * scale for t in offsets[:-1]) + (T,) if ramp > 0.0 else ()
        return Trajectory(duration=T, topp_duration=t_opt, min_duration=t_min, rests=rests,
                          rest_times=rest_times, scaling=scaling, time_scale=scale,
                          **common)  # type: ignore[arg-type]

    def _min_time(self, path: PathLike, limits: JointLimits, a: float, b: float, sided: np.ndarray) -> float:
        """Smallest duration of the shaped law from s = a to s = b within every limit, s."""
        ramp = float(self.ramp)
        span = b - a
        m = int(self.check_samples)
        parts = [np.linspace(0.0, 1.0, m + 1)]
        if ramp > 0.0:
            parts += [np.linspace(0.0, ramp, m // 2 + 1), np.linspace(1.0 - ramp, 1.0, m // 2 + 1)]
        if sided.size:
            y = (np.concatenate([sided, sided - 1e-12]) - a) / span
            parts.append(inverse_shape(y, ramp))
        u = np.unique(np.concatenate(parts))
        need = self._needs(path, limits, a, span, u)
        # Refine around the largest samples (a peak between two samples is found to O(h^2 / 32^2)).
        top = np.argpartition(need, -min(REFINE_TOP, need.size))[-min(REFINE_TOP, need.size):]
        lo = u[np.maximum(top - 1, 0)]
        hi = u[np.minimum(top + 1, u.size - 1)]
        fine = (lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, REFINE_POINTS)).reshape(-1)
        worst = max(float(need.max()), float(self._needs(path, limits, a, span, fine).max()))
        if not (worst > 0.0 and math.isfinite(worst)):
            raise LimitError(f'the path does not move between s = {a:.6g} and s = {b:.6g}, or its '
                             f'derivatives are not finite there')
        return worst / (1.0 - CHECK_MARGIN)

    def _needs(self, path: PathLike, limits: JointLimits, a: float, span: float, u: np.ndarray) -> np.ndarray:
        """Per sample u (M,), the duration each row needs there: max(velocity, sqrt(acceleration)), s."""
        sg, d1, d2, _ = shape(u, float(self.ramp))
        s = clip(a + span * sg, 0.0, 1.0)
        q, q1, q2 = (np.asarray(x, dtype=float) for x in path.evaluate(s, order=2))
        vel = np.abs(q1) * (span * d1)[:, None] / limits.max_velocity
        acc = np.abs(q1 * (span * d2)[:, None] + q2 * ((span * d1) ** 2)[:, None]) / limits.max_acceleration
        need = np.maximum(vel.max(axis=1), np.sqrt(acc.max(axis=1)))
        if limits.max_tool_speed is not None or limits.max_tool_angular_speed is not None:
            lim = np.array([math.inf if x is None else float(x)
                            for x in (limits.max_tool_speed, limits.max_tool_angular_speed)])
            V, _ = tool_twist(tool_kinematics(path, 'max_tool_speed'), q, q1)
            rows = tool_speeds(V.T) * (span * d1)[None, :] / lim[:, None]
            need = np.maximum(need, rows.max(axis=0))
        return need


__all__ = ['DEFAULT_RAMP', 'ConstantSpeed', 'ConstantSpeedScaling', 'inverse_shape', 'shape']
