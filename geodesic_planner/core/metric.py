"""The Riemannian metric on joint space: pull-back of the pose embedding (paper eq. 5-7).

``metric='paper'`` (default) is the paper's improved metric ``g = dp² + dn² + do² + da²``, i.e.
``G(q) = Jᵀ Ω J`` with J the 12 x dof Jacobian of f = (p, n, o, a) and Ω the weights
(position_weight² on p, orientation_weight² on n, o, a). ``metric='position'`` is the traditional
``g1 = dp²`` (orientation weight 0). An optional joint-space term ``epsilon · I`` makes the metric
regular for redundant arms (more than 6 joints), where the paper's metric is singular.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import RequestError, SingularMetricError
from .kinematics import Chain

METRICS = ('paper', 'position')
#: Default joint-space regularisation for arms with more than 6 joints (rad⁻² · m²).
DEFAULT_REDUNDANT_EPSILON = 1e-4
#: G is called singular when its smallest eigenvalue is below this fraction of the largest.
SINGULAR_RCOND = 1e-9


@dataclass(frozen=True)
class Metric:
    """Metric choice and weights.

    Attributes:
        kind: ``'paper'`` or ``'position'``.
        position_weight: weight on dp (dimensionless).
        orientation_weight: weight on dn, do, da, m (a length scale: 1 m turns 1 rad into ~1.4 m).
        epsilon: joint-space term ε in ``G + ε I`` (0 for none).
    """

    kind: str = 'paper'
    position_weight: float = 1.0
    orientation_weight: float = 1.0
    epsilon: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in METRICS:
            raise RequestError(f'metric: unknown metric {self.kind!r}; choose one of {list(METRICS)}')
        for name in ('position_weight', 'orientation_weight', 'epsilon'):
            val = getattr(self, name)
            if not (np.isfinite(val) and val >= 0):
                raise RequestError(f'metric: {name} must be finite and >= 0, got {val}')
        if self.position_weight == 0 and self.effective_orientation_weight == 0:
            raise RequestError('metric: position and orientation weights are both 0')

    @property
    def effective_orientation_weight(self) -> float:
        """Orientation weight actually used (0 for the traditional position metric)."""
        return 0.0 if self.kind == 'position' else self.orientation_weight

    @property
    def mask(self) -> np.ndarray:
        """Weights Ω of the 4x4 matrix entries whose top 3x4 block is (n o a p), shape (4, 4)."""
        om = np.zeros((4, 4))
        om[:3, :3] = self.effective_orientation_weight ** 2
        om[:3, 3] = self.position_weight ** 2
        return om

    def describe(self) -> str:
        """Short human-readable name, e.g. ``paper (wp=1, wo=1)``."""
        s = f'{self.kind} (wp={self.position_weight:g}, wo={self.effective_orientation_weight:g}'
        return s + (f', epsilon={self.epsilon:g})' if self.epsilon else ')')

    def tensor(self, robot: Chain, q: np.ndarray) -> np.ndarray:
        """Metric tensor G(q): joint positions (..., dof) -> (..., dof, dof)."""
        q = np.asarray(q, dtype=float)
        flat = q.reshape(-1, robot.dof)
        G = self.tensor_from_generators(*robot.generators(flat))
        return G.reshape(q.shape[:-1] + (robot.dof, robot.dof))

    def tensor_from_generators(self, X: np.ndarray, T: np.ndarray) -> np.ndarray:
        """G from ``robot.generators(q)`` (X (N, dof, 4, 4), T (N, 4, 4)) -> (N, dof, dof)."""
        Y = X @ T[:, None]
        return np.einsum('nixy,njxy->nij', Y * self.mask, Y) + self.epsilon * np.eye(X.shape[1])

    def check_regular(self, robot: Chain, q: np.ndarray, what: str | list[str] = 'configuration') -> None:
        """Raise SingularMetricError if G is singular at any of the configurations q (..., dof).

        ``what`` names the configurations in the message: one label, or one per row of q.
        """
        G = self.tensor(robot, q).reshape(-1, robot.dof, robot.dof)
        ev = np.linalg.eigvalsh(G)
        bad = ev[:, 0] <= SINGULAR_RCOND * np.maximum(ev[:, -1], 1e-300)
        if np.any(bad):
            i = int(np.argmax(bad))
            qi = np.asarray(q, dtype=float).reshape(-1, robot.dof)[i]
            label = what if isinstance(what, str) else what[i]
            hint = ''
            if self.kind == 'position' and robot.dof > 2:
                hint = (' (the traditional dp² metric has rank <= 3 on a planar arm and < dof beyond 3 joints:'
                        ' paper eq. 15-16)')
            elif robot.dof > 6 and self.epsilon == 0:
                hint = ' (more than 6 joints: use epsilon > 0)'
            raise SingularMetricError(
                f'metric {self.describe()} is singular for robot {robot.name!r} at {label} '
                f'q={np.round(qi, 6).tolist()}: smallest eigenvalue {ev[i, 0]:.3g}, '
                f'largest {ev[i, -1]:.3g}{hint}')

    def speed(self, robot: Chain, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Metric speed sqrt(qdᵀ G qd) for (..., dof) arrays -> (...)."""
        G = self.tensor(robot, q)
        return np.sqrt(np.maximum(np.einsum('...i,...ij,...j->...', qd, G, qd), 0.0))
