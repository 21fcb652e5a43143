"""A planning request: start, goal, via poses or a sequence of motions, and how to plan them.

Built from YAML (:mod:`geodesic_planner.io.requests`) or from service requests
(:mod:`geodesic_planner.ros.planning`); :meth:`PlanRequest.check` holds the checks they share.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .around import AroundOptions
from .errors import RequestError
from .kinematics import Chain
from .motions import MotionItem, plan_sequence
from .planner import GeodesicPlanner
from .ptp import MassModel

if TYPE_CHECKING:
    from .blend import BlendedPath
    from .geodesic import GeodesicPath
    from .piecewise import PiecewiseGeodesicPath

__all__ = ['MAX_ITEMS', 'MAX_VIA_POSES', 'PlanRequest']

#: Most via poses in one request (a PlanTrajectory request's ``via_poses``, a YAML request's ``via``).
MAX_VIA_POSES = 100
#: Most items of one sequence (a PlanSequence request's ``items``, a YAML request's ``sequence``).
MAX_ITEMS = 100


@dataclass
class PlanRequest:
    """A parsed, validated planning request."""

    robot: Chain
    start: np.ndarray | None
    goal: np.ndarray | None
    start_joints: np.ndarray | None = None
    goal_joints: np.ndarray | None = None
    via: list[np.ndarray] = field(default_factory=list)
    tolerance: float | None = None
    planner_options: dict[str, Any] = field(default_factory=dict)
    method: str = 'auto'
    blend_radius: float = 0.0
    items: list[MotionItem] = field(default_factory=list)
    mass: MassModel | None = None
    #: Where the robot came from: a preset's name or a URDF file's path ('' : not known).
    robot_source: str = ''
    #: PTP items whose path collides plan around the obstacles (None: they are refused).
    around: AroundOptions | None = None

    def check(self) -> None:
        """The checks every source of a request shares (YAML files, the services); the start may
        still be open (a node starts at the robot's current joint state).

        Raises:
            RequestError: no goal (unless a sequence), via poses ending at goal joints, more than
                :data:`MAX_VIA_POSES` via poses or :data:`MAX_ITEMS` items.
        """
        if len(self.items) > MAX_ITEMS:
            raise RequestError(f'sequence: {len(self.items)} items, more than {MAX_ITEMS}')
        if len(self.via) > MAX_VIA_POSES:
            raise RequestError(f'via: {len(self.via)} poses, more than {MAX_VIA_POSES}')
        if self.items:
            return
        if self.goal is None and self.goal_joints is None:
            raise RequestError('goal: give a goal pose or goal_joints')
        if self.via and self.goal is None:
            raise RequestError('via poses need a goal pose (goal_joints cannot end a via sequence)')

    def planner(self) -> GeodesicPlanner:
        """A planner for this request's robot and metric options."""
        return GeodesicPlanner(self.robot, **self.planner_options)

    def plan(self, planner: GeodesicPlanner | None = None, *,
             start_seed: np.ndarray | None = None
             ) -> GeodesicPath | PiecewiseGeodesicPath | BlendedPath:
        """Plan it: a geodesic, or a piecewise geodesic when via points are given (blended at the
        via points when ``blend_radius`` > 0).

        ``start_seed`` (dof,) seeds the start pose's IK (e.g. the robot's current joint state).
        """
        self.check()
        planner = planner or self.planner()
        if self.items:
            return plan_sequence(planner, self.items, start=self.start,  # type: ignore[return-value]
                                 start_joints=self.start_joints, tolerance=self.tolerance,
                                 start_seed=start_seed, mass=self.mass, around=self.around)
        if self.via:
            return planner.plan_through([self.start, *self.via, self.goal], self.start_joints,
                                        tolerance=self.tolerance, start_seed=start_seed,
                                        method=self.method, blend_radius=self.blend_radius)
        return planner.plan(self.start, self.goal, self.start_joints, self.goal_joints,
                            tolerance=self.tolerance, start_seed=start_seed, method=self.method)
