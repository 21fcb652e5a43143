#!/usr/bin/env python3
"""Collision checking: its cost beside a plan, on the UR5 with its meshes and the ur5e with capsules (issues 22, 37).

Run:  .venv/bin/python benchmarks/collision.py [--moves 20] [--repeats 5] [--markdown FILE]

Two arms: the UR5 of example-robot-data with its collision meshes (convex hulls) and its SRDF
(test/data/real_arms; the corpus' ur5e URDF names meshes we do not have), and the ``ur5e`` preset
(DH, capsules of DEFAULT_LINK_RADIUS along its links). Per arm, ``--moves`` seeded line moves as
in test/core/test_real_arm_moves.py (start uniform within the limits, goal = the tool pose of a
configuration up to 0.3 rad away on every joint); a start the model finds in collision is drawn
again. Each move is planned (``GeodesicPlanner.plan`` + ``path.timed()``), then checked twice:
self-collision alone, and with 10 scene primitives (boxes, spheres, cylinders, sizes 4-16 cm)
placed 12-40 cm from the tool's line but clear of the whole motion (each candidate is kept only if
the arm stays 2 cm beyond the padding from it on 201 samples of the motion). The check timed is
``check_state(start)`` + ``branches.check_trajectory(model, trajectory, refine=False)``, the way
the planner node checks a plan before publishing it; ``min_clearance`` (``refined()`` of that
result, as the node bounds it after publishing) is timed apart.

Printed per arm and scene: moves checked, median plan + timing time (ms), median check time (ms),
the ratio of the two medians (same run), the median of the per-move ratios, the median number of
configurations checked, the median time of min_clearance (ms) and its configurations (the
check's included), the least clearance found, and moves refused by the check (expected 0:
the scenes are built clear of the motions). Timings are the median of ``--repeats`` runs of each
call after a warm-up (wall clock, shared 2-core machine). The issue's target: at most 2 ms added
per plan. Nothing is asserted.
"""
from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / 'test'), str(ROOT / 'test' / 'core')]

from test_real_arm_moves import random_move  # noqa: E402  (test tooling, after the path set-up)

from geodesic_planner import GeodesicPlanner, load_robot  # noqa: E402
from geodesic_planner.core.branches import check_trajectory  # noqa: E402
from geodesic_planner.core.collision import CollisionModel, MotionClearance, SceneObject, Shape  # noqa: E402
from geodesic_planner.core.errors import CollisionError, GeodesicPlannerError  # noqa: E402
from geodesic_planner.core.kinematics import Chain, trans  # noqa: E402
from geodesic_planner.core.transforms import so3_exp  # noqa: E402

from markdown_block import replace_block  # noqa: E402  (benchmarks/ is the script's directory)
from run import machine  # noqa: E402

DATA = ROOT / 'test' / 'data' / 'real_arms'
MESHES = DATA / 'meshes'
UR5_URDF = DATA / 'example-robot-data' / 'ur5_robot.urdf'
UR5_SRDF = MESHES / 'example-robot-data' / 'robots' / 'ur_description' / 'srdf' / 'ur5.srdf'
#: Scene primitives per move, their distance from the tool's line (m) and the margin (m) beyond the
#: padding by which the whole motion must clear each of them.
N_OBJECTS, NEAR, FAR, MARGIN = 10, 0.12, 0.40, 0.02
#: Samples of a motion on which a candidate object is tested (scene building only, not timed).
SCENE_SAMPLES = 201


def arms() -> dict[str, tuple[Chain, CollisionModel]]:
    """Name -> (chain, self-collision model)."""
    ur5 = load_robot(str(UR5_URDF), base_link='base_link', tip_link='tool0')
    ur5_model = CollisionModel.for_robot(ur5, UR5_URDF.read_text(), package_dirs=[str(MESHES)],
                                         srdf=UR5_SRDF.read_text())
    ur5e = load_robot('ur5e')
    return {'ur5 (meshes, hulls, ur5.srdf)': (ur5, ur5_model),
            'ur5e (capsules)': (ur5e, CollisionModel.for_robot(ur5e))}


def timed_median(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time (ms) of ``repeats`` calls of fn after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e3)


def random_shape(rng: np.random.Generator) -> Shape:
    kind = ('box', 'sphere', 'cylinder')[int(rng.integers(3))]
    if kind == 'box':
        return Shape('box', tuple(float(x) for x in rng.uniform(0.04, 0.16, 3)))
    if kind == 'sphere':
        return Shape('sphere', (float(rng.uniform(0.02, 0.08)),))
    return Shape('cylinder', (float(rng.uniform(0.04, 0.16)), float(rng.uniform(0.02, 0.08))))


def scene(model: CollisionModel, traj, rng: np.random.Generator) -> list[SceneObject]:
    """N_OBJECTS primitives NEAR..FAR from the tool's line, each clear of the motion by MARGIN."""
    s = traj.s_of_t(np.linspace(0.0, traj.duration, SCENE_SAMPLES))[0]
    qs = traj.path.evaluate(s, order=0)[0]
    line = traj.path.ee_poses(s)[:, :3, 3]
    objects: list[SceneObject] = []
    for _ in range(200 * N_OBJECTS):
        if len(objects) == N_OBJECTS:
            break
        u = rng.normal(size=3)
        centre = line[int(rng.integers(line.shape[0]))] + rng.uniform(NEAR, FAR) * u / np.linalg.norm(u)
        pose = trans(*centre)
        pose[:3, :3] = so3_exp(rng.normal(size=3))
        candidate = SceneObject(f'object_{len(objects)}', random_shape(rng), pose)
        d, _ = model.with_objects([candidate]).distances(qs)
        if d.min() > model.padding + MARGIN:
            objects.append(candidate)
    return objects


@dataclass
class Move:
    """One planned move: its plan time and, per scene ('self', 'scene'), the check's time (ms),
    configurations checked, min_clearance's time (ms) and configurations, and the least clearance
    (m); None where the check refused the move."""

    plan_ms: float
    objects: int
    check_ms: dict[str, float | None] = field(default_factory=dict)
    checks: dict[str, int] = field(default_factory=dict)
    clearance: dict[str, float] = field(default_factory=dict)
    clearance_ms: dict[str, float] = field(default_factory=dict)
    clearance_checks: dict[str, int] = field(default_factory=dict)


def run_arm(robot: Chain, model: CollisionModel, moves: int, repeats: int, seed: int
            ) -> tuple[list[Move], int, int]:
    """(moves, starts in collision drawn again, plans refused)."""
    planner = GeodesicPlanner(robot)
    rng = np.random.default_rng(seed)
    out: list[Move] = []
    redrawn = refused = 0
    while len(out) < moves:
        q_a, q_b = random_move(robot, rng)
        try:
            model.check_state(q_a)
        except CollisionError:
            redrawn += 1
            continue
        T_b = robot.fk(q_b)
        try:
            traj = planner.plan(None, T_b, start_joints=q_a).timed()
        except GeodesicPlannerError:
            refused += 1
            continue
        with_scene = model.with_objects(scene(model, traj, rng))
        move = Move(timed_median(lambda: planner.plan(None, T_b, start_joints=q_a).timed(), repeats),
                    len(with_scene.objects))
        for key, m in (('self', model), ('scene', with_scene)):
            def check(m: CollisionModel = m) -> MotionClearance:
                m.check_state(q_a)
                return check_trajectory(m, traj, refine=False)
            try:
                result = check()
            except CollisionError:
                move.check_ms[key] = None
                continue
            move.check_ms[key] = timed_median(check, repeats)
            move.checks[key] = result.checks
            move.clearance_ms[key] = timed_median(result.refined, repeats)
            whole = result.refined()
            move.clearance_checks[key] = whole.checks
            move.clearance[key] = whole.min_clearance
        out.append(move)
    return out, redrawn, refused


def rows(name: str, moves: list[Move], redrawn: int, refused: int) -> list[str]:
    plan = np.array([m.plan_ms for m in moves])
    out = []
    for key, label in (('self', 'self'), ('scene', f'self + {N_OBJECTS} primitives')):
        ok = [m for m in moves if m.check_ms[key] is not None]
        n_refused = len(moves) - len(ok)
        if not ok:
            out.append(f'| {name} | {label} | 0 | {np.median(plan):.1f} | - | - | - | - | - | - | - | {n_refused} |')
            continue
        t = np.array([m.check_ms[key] for m in ok], dtype=float)
        ratio = t / np.array([m.plan_ms for m in ok])
        out.append(f'| {name} | {label} | {len(ok)} | {np.median(plan):.1f} | {np.median(t):.2f} | '
                   f'{np.median(t) / np.median(plan):.3f} | {np.median(ratio):.3f} | '
                   f'{np.median([m.checks[key] for m in ok]):.0f} | '
                   f'{np.median([m.clearance_ms[key] for m in ok]):.2f} | '
                   f'{np.median([m.clearance_checks[key] for m in ok]):.0f} | '
                   f'{min(m.clearance[key] for m in ok):.3f} | {n_refused} |')
    objects = np.mean([m.objects for m in moves])
    out.append(f'| {name} | (draws: {redrawn} starts in collision drawn again, {refused} plans refused, '
               f'{objects:.1f} objects per scene) | | | | | | | | | | |')
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--moves', type=int, default=20)
    ap.add_argument('--repeats', type=int, default=5, help='timed calls per measurement (median)')
    ap.add_argument('--markdown', help='also write the table into this Markdown file (block "collision")')
    args = ap.parse_args()
    lines = [f'Machine: {machine()}', '',
             f'{args.moves} seeded line moves per arm; scene: {N_OBJECTS} primitives {NEAR:g}-{FAR:g} m from '
             f'the tool line, each clear of the motion by padding + {MARGIN:g} m.', '']
    head = ('| arm | checked against | moves | median plan + timed (ms) | median check (ms) | '
            'ratio of medians | median per-move ratio | median configurations checked | '
            'median min_clearance (ms) | its median configurations | least clearance (m) | '
            'moves refused by the check |')
    lines += [head, '|' + '---|' * (head.count('|') - 1)]
    for i, (name, (robot, model)) in enumerate(arms().items()):
        lines += rows(name, *run_arm(robot, model, args.moves, args.repeats, seed=2200 + i))
    lines += ['', 'Target (issue 22): at most 2 ms added per plan (median check).']
    text = '\n'.join(lines)
    print(text)
    if args.markdown:
        replace_block(args.markdown, 'collision', text)


if __name__ == '__main__':
    main()
