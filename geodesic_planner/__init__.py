"""geodesic_planner: robot-arm trajectories along geodesics of the improved metric of
Chen, Li & Tang (2016). The library needs only numpy and scipy (no ROS)."""
from __future__ import annotations

import logging

from .core.errors import (BagError, BVPError, FrameError, GeodesicPlannerError, IKError, KinematicsError,
                          LimitError, RequestError, SingularMetricError, StartStateError)
from .core.geodesic import GeodesicEquations, GeodesicPath, SolverReport
from .core.ik import IKSolution, solve_ik
from .core.kinematics import Chain, Joint, chain_from_dh
from .core.metric import Metric
from .core.path import JointPath
from .core.piecewise import PiecewiseGeodesicPath
from .core.planner import GeodesicPlanner
from .core.robots import PRESETS, load_robot

logging.getLogger(__name__).addHandler(logging.NullHandler())

__version__ = '0.1.0'

__all__ = [
                          'PRESETS',
                          'BVPError',
                          'BagError',
                          'Chain',
                          'FrameError',
                          'GeodesicEquations',
                          'GeodesicPath',
                          'GeodesicPlanner',
                          'GeodesicPlannerError',
                          'IKError',
                          'IKSolution',
                          'Joint',
                          'JointPath',
                          'KinematicsError',
                          'LimitError',
                          'Metric',
                          'PiecewiseGeodesicPath',
                          'RequestError',
                          'SingularMetricError',
                          'SolverReport',
                          'StartStateError',
                          'chain_from_dh',
                          'load_robot',
                          'solve_ik',
]
