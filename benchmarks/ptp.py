#!/usr/bin/env python3
"""PTP of least kinetic energy (issue 39, section 1): plan time and energy against the best of many starts.

Run:  .venv/bin/python benchmarks/ptp.py [--arm ur5|panda] [--pairs 40] [--references 12] [--markdown FILE]

Pairs: start and goal uniform within the joint limits of the arm's URDF (whole-range moves; seeded).
Per pair, ``kinetic_energy_path`` is timed (thread CPU time and wall clock: the machine is shared)
and its energy E = int q'^T M(q) q' ds judged independently (pinocchio's crba on the URDF's own
model, Simpson's rule on 2001 samples). The reference is the best of: the planner's result, and
the same minimisation with ``--references`` perturbed starts and 12 modes (a denser search than
the planner's own 4); the ratio E / reference is the planner's loss. Also the joint line's energy
(what the minimisation saves) and the paths that leave the limits (on 2001 samples; expected 0).
Targets (6 joints): p50 <= 50 ms, p99 <= 200 ms, within 1 % of the best of the starts. Nothing is
asserted.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]

from geodesic_planner import load_robot  # noqa: E402
from geodesic_planner.core import least_energy  # noqa: E402
from geodesic_planner.core.ptp import JointLinePath, UrdfMass, kinetic_energy_path  # noqa: E402

from markdown_block import replace_block  # noqa: E402
from run import machine  # noqa: E402

DATA = ROOT / 'test' / 'data' / 'real_arms' / 'example-robot-data'
ARMS = {'ur5': (DATA / 'ur5_robot.urdf', 'tool0'), 'panda': (DATA / 'panda.urdf', 'panda_link8')}


class Judge:
    """The independent energy: crba of the URDF's model, Simpson on 2001 samples."""

    def __init__(self, urdf: Path, names: list[str]) -> None:
        import pinocchio as pin

        self.pin, self.model = pin, pin.buildModelFromUrdf(str(urdf))
        self.data = self.model.createData()
        self.idx = [self.model.joints[self.model.getJointId(n)].idx_q for n in names]

    def __call__(self, path: object) -> float:
        s = np.linspace(0.0, 1.0, 2001)
        q, v = path.evaluate(s, 1)  # type: ignore[attr-defined]
        f = np.empty(s.size)
        full = self.pin.neutral(self.model)
        for k, (qk, vk) in enumerate(zip(q, v)):
            full[self.idx] = qk
            m = self.pin.crba(self.model, self.data, full)
            m = np.triu(m) + np.triu(m, 1).T
            f[k] = vk @ m[np.ix_(self.idx, self.idx)] @ vk
        h = s[1]
        return float(h / 3.0 * (f[0] + f[-1] + 4.0 * f[1:-1:2].sum() + 2.0 * f[2:-1:2].sum()))


def reference(robot: object, mass: UrdfMass, q_a: np.ndarray, q_b: np.ndarray, starts: int) -> object:
    return least_energy.least_energy_path(robot, mass.terms, q_a, q_b, modes=12, perturbed=starts)  # type: ignore[arg-type]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--arm', choices=sorted(ARMS), default='ur5')
    ap.add_argument('--pairs', type=int, default=40)
    ap.add_argument('--references', type=int, default=12)
    ap.add_argument('--markdown', help='write the table into this Markdown file (block ptp-ARM)')
    args = ap.parse_args(argv)
    urdf, tip = ARMS[args.arm]
    robot = load_robot(str(urdf), tip_link=tip)
    mass = UrdfMass(robot, urdf.read_text())
    judge = Judge(urdf, robot.joint_names)
    rng = np.random.default_rng(39)
    pairs = [(rng.uniform(robot.lower, robot.upper), rng.uniform(robot.lower, robot.upper))
             for _ in range(args.pairs)]
    kinetic_energy_path(robot, mass, *pairs[0])              # warm-up (imports)
    cpu, wall, ratio, saved, outside, bound = [], [], [], [], 0, 0
    s = np.linspace(0.0, 1.0, 2001)
    for q_a, q_b in pairs:
        t0, c0 = time.perf_counter(), time.thread_time()
        path = kinetic_energy_path(robot, mass, q_a, q_b)
        cpu.append((time.thread_time() - c0) * 1e3)
        wall.append((time.perf_counter() - t0) * 1e3)
        e = judge(path)
        ref = min(e, judge(reference(robot, mass, q_a, q_b, args.references)))
        ratio.append(e / ref)
        saved.append(e / judge(JointLinePath(robot, q_a, q_b)))
        q = path.evaluate(s, 0)[0]
        outside += int(not np.all((q >= robot.lower - 1e-9) & (q <= robot.upper + 1e-9)))
        bound += int(bool(path.limited))
    ratio_a = np.array(ratio)
    lines = [
        f'### PTP kinetic_energy, {args.arm} ({robot.dof} joints), {args.pairs} whole-range pairs '
        f'(`benchmarks/ptp.py --arm {args.arm} --pairs {args.pairs}`)',
        '',
        f'{machine()}',
        '',
        '| figure | value |',
        '|---|---|',
        f'| plan time, thread CPU p50 / p99 / max (ms) | {np.percentile(cpu, 50):.1f} / {np.percentile(cpu, 99):.1f} '
        f'/ {max(cpu):.1f} |',
        f'| plan time, wall p50 / p99 (ms) | {np.percentile(wall, 50):.1f} / {np.percentile(wall, 99):.1f} |',
        f'| E / best of {args.references + 1} starts on 12 modes: median / max | {np.median(ratio_a):.5f} / '
        f'{ratio_a.max():.4f} |',
        f'| pairs more than 1 % above that best | {int(np.sum(ratio_a > 1.01))} |',
        f'| E / joint line\'s E: median / max | {np.median(saved):.3f} / {max(saved):.3f} |',
        f'| paths with a limit binding / outside the limits | {bound} / {outside} |',
    ]
    text = '\n'.join(lines)
    print(text)
    if args.markdown:
        replace_block(args.markdown, f'ptp-{args.arm}', text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
