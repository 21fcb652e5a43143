"""Collision checking: the robot's own links and the cell, along the whole motion.

A :class:`CollisionModel` holds the robot's bodies (:mod:`.collision_bodies`), the scene objects,
the pairs it checks and a padding (m). A pair is in collision where its distance is at most the
padding.

Pairs skipped, each with its reason in :attr:`CollisionModel.skipped`:

- bodies on one rigid segment (they never move against each other: a link's several
  ``<collision>`` elements, links joined by fixed joints, an attached object and the tool link);
- adjacent links, one joint apart (they touch at the joint by construction, as MoveIt assumes);
- pairs listed in an SRDF's ``<disable_collisions>`` (MoveIt configuration packages);
- robot pairs within the padding at the robot's home pose (MoveIt Setup Assistant's "Default":
  with them every plan near home would be refused, and they are a modelling artefact, e.g. hulls
  that overlap at a joint);
- scene objects against bodies fixed to the base (no motion changes their distance: a base
  bolted to a table is not a collision a plan could avoid).

Along a motion (:meth:`CollisionModel.check_motion`) the check is conservative. A point of a body
on segment k moves at most ``sum_j |dq_j/dt| * reach_jk`` (m/s), where ``reach_jk`` bounds the
distance of the body from joint j's axis by the segment lengths (triangle inequality, independent
of the configuration). A pair's distance therefore changes at most at the sum of its two bodies'
speeds ``R``; an interval [a, b] is clear when ``d(a) + d(b) - R (b - a) > 2 padding``, else it
is bisected: a thin plate between two checks is caught. What the check guarantees: a motion it
accepts keeps every checked pair more than the padding apart all along; a motion it refuses has a
pair at most the padding plus :data:`RESOLUTION` (its 1 mm margin) apart at the place it names.
:meth:`CollisionModel.check_path` checks a geometric path q(s) this way, with s in place of t and
a bound on |dq/ds| (so no time law can change its answer), and
:func:`~.clearance.refine_min_clearance` then bounds the smallest distance over the whole path
(``min_clearance``, within :data:`CLEARANCE_RESOLUTION` below it, never above).

Exact distances are coal's, except between spheres and capsules (the presets' links): those come
in batches from :mod:`.capsules`, equal to coal's within about 1e-16 m.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import coal
import numpy as np

from .cancel import checkpoint
from .capsules import capsule_distances
from .clearance import path_speed, refine_min_clearance, time_at
from .collision_bodies import (
    Body,
    SceneObject,
    Shape,
    capsule_bodies,
    object_bodies,
    pair_key,
    srdf_disabled,
    urdf_bodies,
)
from .errors import (
    GoalInCollisionError,
    PathInCollisionError,
    RequestError,
    StartInCollisionError,
    quoted,
)
from .kinematics import Chain

__all__ = ['CLEARANCE_RESOLUTION', 'DEFAULT_LINK_RADIUS', 'DEFAULT_PADDING', 'RESOLUTION', 'CollisionModel',
           'MotionClearance', 'PairTable', 'SceneObject', 'Shape']

#: Default ``collision_padding``: the clearance every checked pair keeps, m.
DEFAULT_PADDING = 0.01
#: Radius of the capsules along the links of a model without ``<collision>`` geometry, m.
DEFAULT_LINK_RADIUS = 0.05
#: The check's margin, m: a motion is refused where a distance it finds is at most the padding
#: plus this (it certifies clear only intervals whose bound is above the padding).
RESOLUTION = 1e-3
#: min_clearance is within this below the true smallest distance over the path (never above), m.
CLEARANCE_RESOLUTION = 1e-3
#: Largest number of configurations one motion check evaluates before it refuses.
MAX_CHECKS = 20_000
#: Largest number of configurations min_clearance's refinement adds (past it: a lower bound, more
#: than CLEARANCE_RESOLUTION below MotionClearance.closest).
MAX_CLEARANCE_CHECKS = 20_000
#: Largest number of scene objects.
MAX_OBJECTS = 1000
#: Bound used for a prismatic joint's travel when its limits are infinite, m.
UNBOUNDED_TRAVEL = 10.0
#: Margin on the joint speed bound (a trajectory may pass its limits by round-off).
SPEED_MARGIN = 1.05


@dataclass(frozen=True)
class MotionClearance:
    """What a motion check found.

    Attributes:
        min_clearance: the smallest distance between checked bodies over the whole path, m: a
            lower bound, within :data:`CLEARANCE_RESOLUTION` (1 mm) of the true minimum and never
            above it (inf when nothing is checked); a property of the path (:meth:`CollisionModel.check_path`:
            time laws do not change it). From ``refine=False``: the smallest bound at the
            configurations checked, until :meth:`refined`.
        pair: the two bodies that come closest (('', '') when nothing is checked).
        time: where, s (the check's own parameter when no time law is given; nan until
            :meth:`refined` when one is); fraction: where, as the path parameter s in [0, 1].
        checks: configurations evaluated.
        closest: the exact distance of ``pair`` there, m (nan until refined): the true minimum
            lies in [min_clearance, closest].
    """

    min_clearance: float
    pair: tuple[str, str]
    time: float
    fraction: float
    checks: int
    closest: float = math.nan
    _refine: Callable[[], MotionClearance] | None = field(default=None, repr=False, compare=False)

    def refined(self) -> MotionClearance:
        """This result with ``min_clearance`` over the whole path (itself if it already is)."""
        return self if self._refine is None else self._refine()

    def summary(self) -> str:
        """One line for a reply or a log: the value, its guarantee, and the closest pair and place."""
        if self.pair == ('', ''):
            return 'min_clearance inf m: no pair of bodies is checked'
        where = (f'{quoted(self.pair[0])} and {quoted(self.pair[1])} come closest at '
                 f'{100.0 * self.fraction:.1f} % of the way')
        if math.isnan(self.closest):
            return f'min_clearance {self.min_clearance:.4f} m at the configurations checked: {where}'
        return (f'min_clearance {self.min_clearance:.4f} m (the smallest distance over the path, at most '
                f'{CLEARANCE_RESOLUTION * 1e3:g} mm below it): {where}, {self.closest:.4f} m apart there')


class PairTable(NamedTuple):
    """The checked pairs (:attr:`CollisionModel.pair_table`). first, second: body indices (pairs,);
    radius: bounding-sphere radii (bodies,), m; segment: each body's segment (bodies,); geometry:
    each body's coal geometry; reach: (pairs, dof), the bound on how fast each pair's distance
    changes per unit of each joint, m/rad (or m/m)."""

    first: np.ndarray
    second: np.ndarray
    radius: np.ndarray
    segment: np.ndarray
    geometry: tuple[Any, ...]
    reach: np.ndarray


class CollisionModel:
    """The robot's bodies, the scene, the checked pairs and the padding (immutable).

    Build it with :meth:`for_robot`; :meth:`with_objects` gives the same robot in another scene.
    """

    def __init__(self, robot: Chain, bodies: Sequence[Body], disabled: dict[tuple[str, str], str],
                 padding: float, objects: Sequence[SceneObject] = (), *, exact_meshes: bool = False) -> None:
        if not (math.isfinite(padding) and padding >= 0.0):
            raise RequestError(f'collision_padding must be finite and >= 0 m, got {padding!r}')
        if len(objects) > MAX_OBJECTS:
            raise RequestError(f'scene: {len(objects)} objects, at most {MAX_OBJECTS}')
        ids = [o.id for o in objects]
        robot_names = {b.name for b in bodies}
        for i, name in enumerate(ids):
            if name in ids[:i]:
                raise RequestError(f'scene: two objects named {quoted(name)}')
            if name in robot_names:
                raise RequestError(f'scene: object {quoted(name)} has the name of a robot link')
        self.robot = robot
        self.padding = float(padding)
        self.exact_meshes = exact_meshes
        self.objects: tuple[SceneObject, ...] = tuple(objects)
        self._robot_bodies = tuple(bodies)
        self._disabled = dict(disabled)
        self._bodies = self._robot_bodies + tuple(b for o in objects
                                                  for b in object_bodies(o, robot, exact_meshes=exact_meshes))
        self.body_names: tuple[str, ...] = tuple(dict.fromkeys(b.name for b in self._robot_bodies))
        self.skipped: dict[tuple[str, str], str] = {}
        ia, ib = [], []
        for i, a in enumerate(self._bodies):
            for j in range(i + 1, len(self._bodies)):
                why = self._skip(a, self._bodies[j])
                key = pair_key(a.name, self._bodies[j].name)
                if why:
                    self.skipped.setdefault(key, why)
                else:
                    ia.append(i)
                    ib.append(j)
        self._ia, self._ib = np.array(ia, dtype=int), np.array(ib, dtype=int)
        names = [pair_key(self._bodies[i].name, self._bodies[j].name) for i, j in zip(ia, ib)]
        for key in names:
            self.skipped.pop(key, None)     # some of a link's bodies checked: the pair is checked
        self.pairs: tuple[tuple[str, str], ...] = tuple(dict.fromkeys(names))
        self._pair_names = names
        self._segment = np.array([b.segment for b in self._bodies], dtype=int)
        self._offset = np.array([b.offset for b in self._bodies]).reshape(-1, 4, 4)
        self._center = np.array([b.center for b in self._bodies]).reshape(-1, 3)
        self._radius = np.array([b.radius for b in self._bodies])
        self._relative_reach = self._pair_reaches()
        self._distance_fns: dict[int, Any] = {}
        self._request = coal.DistanceRequest()
        self._result = coal.DistanceResult()
        # spheres and capsules (the presets' links): their pairs' distances in batches (core.capsules)
        prims = [(g.halfLength, g.radius) if isinstance(g, coal.Capsule) else (0.0, g.radius)
                 if isinstance(g, coal.Sphere) else (np.nan, np.nan) for g in (b.geometry for b in self._bodies)]
        self._half = np.array([h for h, _ in prims], dtype=float)
        self._prim_radius = np.array([r for _, r in prims], dtype=float)
        self._analytic = np.isfinite(self._half[self._ia]) & np.isfinite(self._half[self._ib])

    # ------------------------------------------------------------------ construction
    @classmethod
    def for_robot(cls, robot: Chain, urdf: str | None = None, *, package_dirs: Sequence[str] = (),
                  srdf: str | None = None, padding: float = DEFAULT_PADDING, exact_meshes: bool = False,
                  link_radius: float = DEFAULT_LINK_RADIUS) -> CollisionModel:
        """The robot's collision model, with an empty scene.

        Args:
            robot: the chain.
            urdf: its URDF text; its ``<collision>`` elements give the bodies. None, or a URDF
                without them: capsules of ``link_radius`` along the segments.
            package_dirs: directories that hold the packages ``package://`` names.
            srdf: SRDF text whose ``<disable_collisions>`` pairs are skipped.
            padding: the clearance kept, m.
            exact_meshes: check meshes' triangles instead of their convex hulls (about 100x slower).
            link_radius: capsule radius, m.
        Raises:
            KinematicsError: the URDF's geometry cannot be read; RequestError: bad SRDF or values.
        """
        bodies = urdf_bodies(robot, urdf, package_dirs=package_dirs, exact_meshes=exact_meshes) if urdf else []
        if not bodies:
            if not (math.isfinite(link_radius) and link_radius > 0.0):
                raise RequestError(f'link_radius must be finite and > 0 m, got {link_radius!r}')
            bodies = capsule_bodies(robot, link_radius)
        disabled = srdf_disabled(srdf) if srdf else {}
        model = cls(robot, bodies, disabled, padding, exact_meshes=exact_meshes)
        return model._without_home_contacts()

    def _without_home_contacts(self) -> CollisionModel:
        """This model with the robot pairs within the padding at the home pose disabled."""
        if self._ia.size == 0:
            return self
        lower, _, _ = self._bounds(self.robot.home[None], exact_below=np.inf)
        close = {self._pair_names[p] for p in np.flatnonzero(lower[0] <= self.padding)}
        if not close:
            return self
        disabled = dict(self._disabled)
        for key in close:
            disabled.setdefault(key, f'within the padding ({self.padding:g} m) at the home pose')
        return CollisionModel(self.robot, self._robot_bodies, disabled, self.padding, self.objects,
                              exact_meshes=self.exact_meshes)

    @property
    def robot_bodies(self) -> tuple[Body, ...]:
        """The robot's own bodies (its links; the scene's objects are not among them)."""
        return self._robot_bodies

    def with_objects(self, objects: Sequence[SceneObject]) -> CollisionModel:
        """The same robot and pairs rules in the scene ``objects`` (replacing the current scene)."""
        return CollisionModel(self.robot, self._robot_bodies, self._disabled, self.padding, objects,
                              exact_meshes=self.exact_meshes)

    def with_padding(self, padding: float) -> CollisionModel:
        """The same model with another padding (the home-pose pairs are not recomputed)."""
        return CollisionModel(self.robot, self._robot_bodies, self._disabled, padding, self.objects,
                              exact_meshes=self.exact_meshes)

    def _skip(self, a: Body, b: Body) -> str:
        """Why the pair (a, b) is not checked ('' when it is)."""
        if a.kind != 'link' and b.kind != 'link':
            return '' if 'attached' in (a.kind, b.kind) and a.segment != b.segment else 'objects on one segment'
        if a.segment == b.segment:
            if a.kind == 'link' and b.kind == 'link':
                return 'one rigid segment'
            return 'the tool link touches what it carries' if 'attached' in (a.kind, b.kind) else \
                'fixed to the base: their distance cannot change'
        if a.kind == 'link' and b.kind == 'link':
            if abs(a.segment - b.segment) == 1:
                return 'adjacent links (one joint apart)'
            return self._disabled.get(pair_key(a.name, b.name), '')
        return ''

    def _pair_reaches(self) -> np.ndarray:
        """(pairs, dof): how fast each pair's distance can change per unit joint speed.

        A distance does not change when both bodies move together, so only the joints between
        the two segments count: in the frame of the lower segment, the body on the higher one
        moves, joint j (beyond the lower segment) contributing ``reach[j]`` per rad/s.
        """
        reach = self._reaches()
        seg = self._segment
        lo = np.minimum(seg[self._ia], seg[self._ib])
        hi_body = np.where(seg[self._ia] >= seg[self._ib], self._ia, self._ib)
        joints = np.arange(1, self.robot.dof + 1)
        return reach[hi_body] * (joints[None, :] > lo[:, None])

    def _reaches(self) -> np.ndarray:
        """(bodies, dof): speed of any point of each body per unit joint speed (m/rad, or 1 m/m)."""
        robot = self.robot
        n = robot.dof
        seg_len = np.linalg.norm(robot.segment_ends(), axis=1)       # (dof + 1,)
        travel = np.where(robot.revolute, 0.0,
                          np.nan_to_num(np.maximum(np.abs(robot.lower), np.abs(robot.upper)),
                                        posinf=UNBOUNDED_TRAVEL))
        reach = np.zeros((len(self._bodies), n))
        for b, body in enumerate(self._bodies):
            k = body.segment
            out = float(np.linalg.norm(body.center)) + body.radius   # from the segment origin
            for j in range(k, 0, -1):                                # joint j moves segments >= j
                reach[b, j - 1] = 1.0 if not robot.revolute[j - 1] else out
                out += seg_len[j - 1] + travel[j - 1]
        return reach

    # ------------------------------------------------------------------ queries
    @property
    def pair_table(self) -> PairTable:
        """The checked pairs' bodies, for terms that measure distances themselves (:mod:`.obstacle_penalty`)."""
        return PairTable(self._ia, self._ib, self._radius, self._segment,
                         tuple(b.geometry for b in self._bodies), self._relative_reach)

    def body_frames(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every body's frame (N, bodies, 4, 4) and bounding-sphere centre (N, bodies, 3) at qs (N, dof), base frame."""
        return self._poses(np.asarray(qs, dtype=float))

    def clear_above(self, qs: np.ndarray, distance: float) -> np.ndarray:
        """(N,) bool: every checked pair more than ``distance`` (m) apart at each of qs (N, dof) (exact
        distances only where the bounding spheres come that near)."""
        if self._ia.size == 0:
            return np.ones(len(qs), dtype=bool)
        lower = self._bounds(np.asarray(qs, dtype=float), exact_below=np.nextafter(distance, np.inf))[0]
        return np.all(lower > distance, axis=1)

    def _poses(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body frames (N, bodies, 4, 4) and bounding-sphere centres (N, bodies, 3), base frame."""
        S = self.robot.segment_frames(qs)[:, self._segment]
        centers = np.einsum('nbij,bj->nbi', S[..., :3, :3], self._center) + S[..., :3, 3]
        return S @ self._offset, centers

    def _exact_many(self, P: np.ndarray, ns: np.ndarray, ps: np.ndarray, cache: dict[tuple[int, int], Any]
                    ) -> np.ndarray:
        """Distances of pairs ``ps[k]`` at configurations ``ns[k]``, (K,), m: spheres and capsules
        in one batch (:func:`~.capsules.capsule_distances`), other shapes by coal (:meth:`_coal_distance`)."""
        ns, ps = np.asarray(ns, dtype=np.int64).reshape(-1), np.asarray(ps, dtype=np.int64).reshape(-1)
        out = np.empty(ns.size)
        fast = self._analytic[ps]
        if fast.any():
            out[fast] = capsule_distances(P, self._half, self._prim_radius, ns[fast], self._ia[ps[fast]],
                                          self._ib[ps[fast]])
        for k in np.flatnonzero(~fast):
            out[k] = self._coal_distance(P, int(ns[k]), int(ps[k]), cache)
        return out

    def _exact(self, P: np.ndarray, n: int, p: int, cache: dict[tuple[int, int], Any]) -> float:
        """Distance of pair p at configuration n, m (:meth:`_exact_many` of one)."""
        return float(self._exact_many(P, np.array([n]), np.array([p]), cache)[0])

    def _coal_distance(self, P: np.ndarray, n: int, p: int, cache: dict[tuple[int, int], Any]) -> float:
        """coal's distance of pair p at configuration n, m; ``cache`` keeps each body's coal
        transform per configuration (a body is in several pairs)."""
        i, j = int(self._ia[p]), int(self._ib[p])
        fn = self._distance_fns.get(p)
        if fn is None:
            fn = self._distance_fns[p] = coal.ComputeDistance(self._bodies[i].geometry, self._bodies[j].geometry)
        Ti = cache.get((n, i))
        if Ti is None:
            Ti = cache[n, i] = coal.Transform3s(P[n, i, :3, :3], P[n, i, :3, 3])
        Tj = cache.get((n, j))
        if Tj is None:
            Tj = cache[n, j] = coal.Transform3s(P[n, j, :3, :3], P[n, j, :3, 3])
        self._result.clear()
        return float(fn(Ti, Tj, self._request, self._result))

    def _bounds(self, qs: np.ndarray, exact_below: np.ndarray | float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Lower bounds of every pair's distance at each configuration, (N, pairs), m: the exact
        distance (:meth:`_exact_many`) where the bounding spheres' bound is below ``exact_below`` (scalar or (pairs,)),
        the spheres' bound elsewhere; with the mask of the exact ones and the body frames."""
        P, centers = self._poses(qs)
        lower = (np.linalg.norm(centers[:, self._ia] - centers[:, self._ib], axis=-1)
                 - self._radius[self._ia] - self._radius[self._ib])
        exact = lower < exact_below
        ns, ps = np.nonzero(exact)
        lower[ns, ps] = self._exact_many(P, ns, ps, {})
        return lower, exact, P

    def distances(self, qs: np.ndarray) -> tuple[np.ndarray, list[tuple[str, str]]]:
        """The smallest distance over the checked pairs at each configuration, and its pair.

        Args:
            qs: joint positions, shape (N, dof); rad or m.
        Returns:
            (d, pairs): d (N,) in m (0 or negative in contact; inf when no pair is checked) and the
            pair of names that has it (('', '') when none).
        """
        qs = self.robot.check_joints(np.atleast_2d(qs), 'qs')
        if self._ia.size == 0:
            return np.full(len(qs), np.inf), [('', '')] * len(qs)
        lower, exact, P = self._bounds(qs, exact_below=-np.inf)
        cache: dict[tuple[int, int], Any] = {}
        d, pairs = np.empty(len(qs)), []
        for n in range(len(qs)):
            while True:             # best first: the smallest bound, made exact, until it is exact
                p = int(np.argmin(lower[n]))
                if exact[n, p]:
                    break
                lower[n, p] = self._exact(P, n, p, cache)
                exact[n, p] = True
            d[n] = lower[n, p]
            pairs.append(self._pair_names[p])
        return d, pairs

    def check_state(self, q: np.ndarray, what: str = 'start') -> float:
        """The clearance of one configuration (m); raises when it is within the padding.

        Raises:
            StartInCollisionError: ``what == 'start'``; GoalInCollisionError: otherwise.
        """
        d, pairs = self.distances(np.asarray(q, dtype=float)[None])
        if d[0] <= self.padding:
            self._raise(what, pairs[0], float(d[0]), 0.0 if what == 'start' else 1.0, math.nan)
        return float(d[0])

    def _apart(self, d: float) -> str:
        """How far apart a refused pair is, and why that is refused."""
        pad = self.padding
        if d < 0.0:
            return f'overlap by {-d:.4f} m (collision_padding {pad:g} m)'
        if d == 0.0:
            return f'touch (collision_padding {pad:g} m)'
        if d <= pad:
            return f'are {d:.4f} m apart, closer than collision_padding {pad:g} m'
        return (f'are {d:.4f} m apart, within the motion check\'s {RESOLUTION * 1e3:g} mm margin of '
                f'collision_padding {pad:g} m (it refuses any distance it finds up to {pad + RESOLUTION:.4f} m: '
                f'between the configurations it evaluates it shows a motion clear of the padding only '
                f'to within that margin)')

    def _raise(self, what: str, pair: tuple[str, str], d: float, fraction: float, t: float,
               budget: bool = False) -> None:
        bodies = f'{quoted(pair[0])} and {quoted(pair[1])}'
        if what == 'start':
            raise StartInCollisionError(f'start state in collision: {bodies} {self._apart(d)}',
                                        pair=pair, fraction=fraction, time=t, clearance=d)
        if what == 'goal':
            raise GoalInCollisionError(f'goal state in collision: {bodies} {self._apart(d)}',
                                       pair=pair, fraction=fraction, time=t, clearance=d)
        place = f'{100.0 * fraction:.1f} % of the way (t = {t:.3f} s)'
        if budget:
            raise PathInCollisionError(
                f'collision on the way: refused, not shown clear of collision_padding {self.padding:g} m '
                f'within {MAX_CHECKS} configurations from {place} on ({bodies} at least {d:.4f} m '
                'apart there)', pair=pair, fraction=fraction, time=t, clearance=d)
        raise PathInCollisionError(f'collision on the way at {place}: {bodies} {self._apart(d)}',
                                   pair=pair, fraction=fraction, time=t, clearance=d)

    def check_path(self, path: Any, refine: bool = True, *,  # noqa: ANN401
                   s_of_t: Callable[[np.ndarray], np.ndarray] | None = None, duration: float = 0.0
                   ) -> MotionClearance:
        """Check a geometric path q(s), s in [0, 1], between its samples too: :meth:`check_motion`
        with s as the parameter and :func:`~.clearance.path_speed` as the bound on |dq/ds|. The
        answer (refusal, ``min_clearance``, pair and fraction) is the path's: no time law changes it.

        Args:
            path: has ``evaluate(s, order)`` -> (q, dq/ds, d²q/ds², ...), each (len(s), dof) (a
                :class:`~.path.JointPath`).
            refine: as :meth:`check_motion`'s.
            s_of_t: a time law's s(t), times (M,) s -> s (M,), nondecreasing from 0 to 1 over
                ``duration`` s: the places are also given as its times (``time``; else s).
            duration: the time law's duration, s.
        Raises:
            StartInCollisionError, GoalInCollisionError, PathInCollisionError: as :meth:`check_motion`.
        """
        def positions(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            s = np.asarray(s, dtype=float)
            return np.asarray(path.evaluate(s, order=0)[0]), s

        def times(s: np.ndarray) -> np.ndarray:
            assert s_of_t is not None
            return np.where(s >= 1.0, float(duration), time_at(s_of_t, float(duration), s))
        return self.check_motion(positions, 1.0, path_speed(path), refine,
                                 time_of=None if s_of_t is None else times)

    def check_motion(self, positions: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                     duration: float, joint_speed: np.ndarray, refine: bool = True, *,
                     time_of: Callable[[np.ndarray], np.ndarray] | None = None) -> MotionClearance:
        """Check a whole motion, between its samples too (see the module's doc for the rule).

        Args:
            positions: the motion's parameter (a time, or s itself), values (M,) -> (joint
                positions (M, dof), path parameter s (M,)).
            duration: the parameter's span, from 0 (s, or 1 for s).
            joint_speed: a bound on |dq/d(parameter)| over the motion, (dof,), rad/s or m/s.
            refine: bound ``min_clearance`` over the whole motion now (False: later, by
                :meth:`MotionClearance.refined`, e.g. after a trajectory is published).
            time_of: the parameter's values (M,) -> the times reported (None: the parameter).
        Returns:
            the smallest clearance found, with its pair and place.
        Raises:
            StartInCollisionError, GoalInCollisionError, PathInCollisionError: a clearance within
                the padding at the start, at the end, or on the way (the first place found; within
                the padding plus :data:`RESOLUTION` on the way).
        """
        def when(x: float) -> float:
            return float(x) if time_of is None else float(np.asarray(time_of(np.array([float(x)])))[0])

        speed = np.abs(np.asarray(joint_speed, dtype=float)) * SPEED_MARGIN
        T = float(duration)
        if self._ia.size == 0:
            return MotionClearance(math.inf, ('', ''), 0.0, 0.0, 0, math.inf)
        R = self._relative_reach @ speed                      # (pairs,) m/s
        pad, tol = self.padding, RESOLUTION
        times = np.linspace(0.0, T, 9) if T > 0.0 else np.zeros(1)
        qs, s = positions(times)
        D, E, P = self._bounds(np.asarray(qs, dtype=float), exact_below=pad + tol + R * (times[-1] - times[0]) / 8)
        all_t, all_s, all_D, all_E, all_P = [times], [np.asarray(s, dtype=float)], [D], [E], [P]
        self._stop_at_ends(D, times, np.asarray(s, dtype=float), when)
        ta, tb, Da, Db = times[:-1], times[1:], D[:-1], D[1:]
        checks = len(times)
        grid_hit = np.any(pad + tol >= D, axis=1)
        first = float(times[grid_hit].min()) if grid_hit.any() else math.inf
        budget = False
        while ta.size:
            checkpoint()
            unsafe = np.any(Da + Db - R * (tb - ta)[:, None] <= 2.0 * pad, axis=1) & (ta < first)
            ta, tb, Da, Db = ta[unsafe], tb[unsafe], Da[unsafe], Db[unsafe]
            if not ta.size:
                break
            if checks + ta.size > MAX_CHECKS:
                budget = float(ta.min()) < first
                first = min(first, float(ta.min()))
                break
            tm = 0.5 * (ta + tb)
            qm, sm = positions(tm)
            Dm, Em, Pm = self._bounds(np.asarray(qm, dtype=float), exact_below=pad + tol + R * (tm - ta).max())
            checks += tm.size
            all_t.append(tm)
            all_s.append(np.asarray(sm, dtype=float))
            all_D.append(Dm)
            all_E.append(Em)
            all_P.append(Pm)
            hit = np.any(Dm <= pad + tol, axis=1)
            if hit.any():
                first = min(first, float(tm[hit].min()))
            keep = ~hit      # every left half (an earlier contact may lie there), right halves of clear midpoints
            ta, tb = np.concatenate([ta, tm[keep]]), np.concatenate([tm, tb[keep]])
            Da, Db = np.concatenate([Da, Dm[keep]]), np.concatenate([Dm, Db[keep]])
        t_all, s_all, D_all = np.concatenate(all_t), np.concatenate(all_s), np.concatenate(all_D)
        if math.isfinite(first):
            n = int(np.argmin(np.abs(t_all - first)))
            p = int(np.argmin(D_all[n]))
            self._raise('path', self._pair_names[p], float(D_all[n, p]), float(s_all[n]), when(t_all[n]), budget)
        order = np.argsort(t_all, kind='stable')

        def whole() -> MotionClearance:
            return self._min_clearance(positions, R, t_all[order], s_all[order], D_all[order],
                                       np.concatenate(all_E)[order], np.concatenate(all_P)[order], checks, when)
        if refine:
            return whole()
        n_min, p_min = (int(i) for i in np.unravel_index(int(np.argmin(D_all)), D_all.shape))
        return MotionClearance(float(D_all[n_min, p_min]), self._pair_names[p_min],
                               float(t_all[n_min]) if time_of is None else math.nan,
                               float(s_all[n_min]), checks, math.nan, whole)

    def _min_clearance(self, positions: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], R: np.ndarray,
                       t: np.ndarray, s: np.ndarray, D: np.ndarray, E: np.ndarray, P: np.ndarray,
                       checks: int, when: Callable[[float], float]) -> MotionClearance:
        """The smallest distance over a clear motion, to within :data:`CLEARANCE_RESOLUTION` below
        (:func:`~.clearance.refine_min_clearance`)."""
        found = refine_min_clearance(
            lambda frames, ns, ps: self._exact_many(frames, ns, ps, {}),
            lambda qs: self._poses(self.robot.check_joints(np.asarray(qs, dtype=float), 'q'))[0],
            positions, R, t, s, D, E, P, checks, CLEARANCE_RESOLUTION, checks + MAX_CLEARANCE_CHECKS)
        return MotionClearance(found.lower, self._pair_names[found.pair], when(found.time), found.fraction,
                               found.checks, found.closest)

    def _stop_at_ends(self, D: np.ndarray, times: np.ndarray, s: np.ndarray, when: Callable[[float], float]
                      ) -> None:
        """Raise for a start or goal within the padding (exact there: the bound is small)."""
        for n, what in ((0, 'start'), (len(times) - 1, 'goal')):
            p = int(np.argmin(D[n]))
            if D[n, p] <= self.padding:
                self._raise(what, self._pair_names[p], float(D[n, p]), float(s[n]), when(times[n]))

    # ------------------------------------------------------------------ drawing
    def body_poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Every body's frame (4x4, base frame) at one configuration, by name (a link with several
        bodies: its first)."""
        P = self._poses(self.robot.check_joints(np.asarray(q, dtype=float)[None], 'q'))[0][0]
        out: dict[str, np.ndarray] = {}
        for b, body in enumerate(self._bodies):
            out.setdefault(body.name, P[b])
        return out

    def shapes(self) -> dict[str, Shape]:
        """The shapes of the bodies that have one (scene objects, capsule links), by name."""
        return {b.name: b.shape for b in self._bodies if b.shape is not None}
