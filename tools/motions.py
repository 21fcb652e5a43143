"""The motion types in figures and figures of merit: a blended LIN -> CIRC -> LIN sequence, PTP
with minimum kinetic energy against the joint line, and a PTP blocked by a box that goes around it
(library only, no ROS).

``python -m tools.motions [--output DIR]`` writes ``DIR/sequence.png``, ``DIR/ptp.png`` and
``DIR/around.png`` and
prints, per motion type, its accuracy, duration and plan time; :func:`motions_demo` is the main
demo's step (tools/demo.py). Demo tooling, not part of the installed library.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.circ import arc_through, plan_arc
from geodesic_planner.core.motions import MotionItem, plan_sequence
from geodesic_planner.core.ptp import JointLinePath, UrdfMass, action, kinetic_energy_path
from geodesic_planner.core.transforms import segment_distance

__all__ = ['UR5_URDF', 'motions_demo']

ROOT = Path(__file__).resolve().parents[1]
#: A real arm with <inertial> elements (example-robot-data's UR5).
UR5_URDF = ROOT / 'test' / 'data' / 'real_arms' / 'example-robot-data' / 'ur5_robot.urdf'
Q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])


def _ms(fn: Callable[[], Any]) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, (time.perf_counter() - t0) * 1e3


def _shifted(T: np.ndarray, dp: list[float]) -> np.ndarray:
    out = T.copy()
    out[:3, 3] = T[:3, 3] + np.asarray(dp)
    return out


def _tool_speed(robot: Any, q: np.ndarray, dq: np.ndarray) -> np.ndarray:  # noqa: ANN401
    return np.linalg.norm(np.einsum('nij,nj->ni', robot.jacobian(q)[:, :3], dq), axis=1)


def _sequence(output: Path) -> dict[str, Any]:
    from geodesic_planner.io.motion_plot import plot_sequence

    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    T0 = robot.fk(Q0)
    T1, T2, T3 = _shifted(T0, [0.15, 0.0, 0.0]), _shifted(T0, [0.25, 0.1, 0.0]), _shifted(T0, [0.25, 0.25, -0.05])
    centre = T0[:3, 3] + np.array([0.15, 0.1, 0.0])
    kinds = ['LIN', 'CIRC', 'LIN']
    out: dict[str, Any] = {}
    for r in (0.0, 0.03):
        items = [MotionItem('LIN', goal=T1, blend_radius=r), MotionItem('CIRC', goal=T2, centre=centre, blend_radius=r),
                 MotionItem('LIN', goal=T3)]
        path, plan_ms = _ms(lambda items=items: plan_sequence(planner, items, start_joints=Q0))
        traj, timing_ms = _ms(path.timed)
        out['stopping' if r == 0.0 else 'blended'] = {
            'blend_radius_m': r, 'duration_s': float(traj.duration), 'plan_ms': plan_ms, 'timing_ms': timing_ms,
            'zones_max_distance_m': [float(z.max_distance) for z in getattr(path, 'zones', [])]}
    t = np.linspace(0.0, traj.duration, 1501)
    q, dq, _ = traj.at_time(t)
    tool = robot.fk(q)[:, :3, 3]
    s = traj.s_of_t(t)[0]
    zones = [(float(np.interp(z.s_start, s, t)), float(np.interp(z.s_end, s, t))) for z in path.zones]
    plot_sequence(output / 'sequence.png', t, tool, _tool_speed(robot, q, dq), zones,
                  np.array([T[:3, 3] for T in (T0, T1, T2, T3)]), kinds,
                  title='ur5e: LIN -> CIRC -> LIN, blended within 3 cm at both inner goals')
    return out


def _accuracy(robot: Any, planner: GeodesicPlanner) -> dict[str, Any]:  # noqa: ANN401
    """LIN and CIRC alone on ur5e: tool deviation, duration, plan time."""
    T0 = robot.fk(Q0)
    T_lin = _shifted(T0, [0.2, -0.1, 0.15])
    lin, lin_ms = _ms(lambda: planner.plan(None, T_lin, start_joints=Q0))
    centre = T0[:3, 3] + np.array([0.0, 0.1, 0.0])
    rel = T0[:3, 3] - centre

    def on_circle(deg: float) -> np.ndarray:
        c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        return centre + np.array([c * rel[0] - s * rel[1], s * rel[0] + c * rel[1], rel[2]])
    T_circ = T0.copy()
    T_circ[:3, 3] = on_circle(200.0)
    arc = arc_through(T0[:3, 3], on_circle(90.0), T_circ[:3, 3])
    circ, circ_ms = _ms(lambda: plan_arc(robot, Q0, T_circ, arc))
    s = np.linspace(0.0, 1.0, 4001)
    p_lin = robot.fk(lin.evaluate(s, 0)[0])[:, :3, 3]
    return {
        'LIN': {'deviation_m': float(segment_distance(p_lin, T0[:3, 3], T_lin[:3, 3]).max()),
                'duration_s': float(lin.timed().duration), 'plan_ms': lin_ms},
        'CIRC (200 deg through an interim point)': {
            'deviation_m': float(arc.distance(robot.fk(circ.evaluate(s, 0)[0])[:, :3, 3]).max()),
            'duration_s': float(circ.timed().duration), 'plan_ms': circ_ms},
    }


def _ptp(output: Path) -> dict[str, Any]:
    from geodesic_planner.io.motion_plot import plot_ptp_comparison

    robot = load_robot(str(UR5_URDF), tip_link='tool0')
    mass = UrdfMass(robot, UR5_URDF.read_text())
    q_a = np.array([0.0, -1.0, 1.2, -1.5, -1.4, 0.2])
    q_b = q_a + np.array([1.5, 0.6, -0.9, 0.5, 1.0, -1.0])
    runs, out = [], {}
    for name, make in (('kinetic_energy', lambda: kinetic_energy_path(robot, mass, q_a, q_b)),
                       ('joint_line', lambda: JointLinePath(robot, q_a, q_b))):
        path, plan_ms = _ms(make)
        traj = path.timed()
        t = np.linspace(0.0, traj.duration, 801)
        q, dq, _ = traj.at_time(t)
        energy = np.array([0.5 * v @ mass.matrix(x) @ v for x, v in zip(q, dq)])
        integral = float(np.sum(0.5 * (energy[1:] + energy[:-1]) * np.diff(t)))
        s = np.linspace(0.0, 1.0, 201)
        runs.append((f'{name}: action {action(path, mass):.3f}, {traj.duration:.3f} s, '
                     f'energy integral {integral:.3f} J s', s, path.evaluate(s, 0)[0], t, energy))
        out[name] = {'action': action(path, mass), 'duration_s': float(traj.duration),
                     'energy_integral_J_s': integral, 'plan_ms': plan_ms}
    plot_ptp_comparison(output / 'ptp.png', runs, robot.joint_names,
                        title='UR5 (example-robot-data): PTP of least kinetic energy against the joint line')
    return out


def _around(output: Path) -> dict[str, Any]:
    """A PTP blocked by a box goes around it (issue 39, section 2): the UR5 with its collision
    meshes, the arm along the way, the box, and the clearance against the fraction of the way."""
    from geodesic_planner.core.around import AroundOptions
    from geodesic_planner.core.collision import CollisionModel, SceneObject, Shape
    from geodesic_planner.core.kinematics import trans
    from geodesic_planner.io.collision_plot import plot_collision

    meshes = ROOT / 'test' / 'data' / 'real_arms' / 'meshes'
    srdf = meshes / 'example-robot-data' / 'robots' / 'ur_description' / 'srdf' / 'ur5.srdf'
    robot = load_robot(str(UR5_URDF), tip_link='tool0')
    mass = UrdfMass(robot, UR5_URDF.read_text())
    q_a = np.array([0.8, -1.2, 1.4, -1.8, -1.57, 0.0])
    q_b = np.array([-0.8, -1.2, 1.4, -1.8, -1.57, 0.0])
    centre, edge = robot.fk(0.5 * (q_a + q_b))[:3, 3], 0.12
    model = CollisionModel.for_robot(robot, UR5_URDF.read_text(), package_dirs=[str(meshes)],
                                     srdf=srdf.read_text()).with_objects(
        [SceneObject('box', Shape('box', (edge,) * 3), trans(*centre))])
    path, plan_ms = _ms(lambda: plan_sequence(GeodesicPlanner(robot), [MotionItem('PTP', goal_joints=q_b)],
                                              start_joints=q_a, mass=mass, around=AroundOptions(model, 1.0)))
    s = np.linspace(0.0, 1.0, 201)
    q = path.evaluate(s, 0)[0]
    frames, tool = robot.frames(q)
    arm = np.concatenate([np.zeros((len(q), 1, 3)), frames[:, :, :3, 3], tool[:, None, :3, 3]], axis=1)
    clearance = model.distances(q)[0]
    direct = model.distances(JointLinePath(robot, q_a, q_b).evaluate(s, 0)[0])[0]
    note = path.notes[0]
    plot_collision(output / 'around.png', arm, tool[:, :3, 3], s,
                   [('(planned around it)', centre, edge, clearance, math.nan),
                    ('(the blocked joint line)', centre, edge, direct, math.nan)], model.padding,
                   title='UR5 (meshes): a PTP blocked by a box goes around it\n' + note.split(': ', 1)[1][:150])
    return {'plan_ms': plan_ms, 'note': note, 'min_clearance_m': float(clearance.min()),
            'direct_min_m': float(direct.min()), 'duration_s': float(path.timed().duration)}


def motions_demo(output: Path, say: Callable[[str], None] = print) -> dict[str, Any]:
    """Write ``sequence.png``, ``ptp.png`` and ``around.png`` into ``output``; return the figures of merit."""
    output.mkdir(parents=True, exist_ok=True)
    robot = load_robot('ur5e')
    summary = {'accuracy': _accuracy(robot, GeodesicPlanner(robot)), 'sequence': _sequence(output),
               'ptp': _ptp(output), 'around': _around(output)}
    for name, part in summary['accuracy'].items():
        say(f'  {name}: tool within {part["deviation_m"]:.1e} m of its geometry, {part["duration_s"]:.3f} s, '
            f'planned in {part["plan_ms"]:.1f} ms')
    seq = summary['sequence']
    say(f'  LIN -> CIRC -> LIN: stopping {seq["stopping"]["duration_s"]:.3f} s, blended (3 cm) '
        f'{seq["blended"]["duration_s"]:.3f} s, planned in {seq["blended"]["plan_ms"]:.1f} ms')
    for name, part in summary['ptp'].items():
        say(f'  PTP {name} (UR5): action {part["action"]:.3f}, energy integral {part["energy_integral_J_s"]:.3f} J s, '
            f'{part["duration_s"]:.3f} s, planned in {part["plan_ms"]:.1f} ms')
    part = summary['around']
    say(f'  PTP around a box (UR5 meshes): {part["note"]}; dense min distance {part["min_clearance_m"]:.4f} m '
        f'(the blocked joint line: {part["direct_min_m"]:.4f} m), {part["duration_s"]:.3f} s, planned in '
        f'{part["plan_ms"]:.0f} ms')
    say(f'wrote {output / "sequence.png"}, {output / "ptp.png"}, {output / "around.png"}')
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m tools.motions``: 0 ok, 1 error."""
    parser = argparse.ArgumentParser(prog='python -m tools.motions', description=__doc__.splitlines()[0])
    parser.add_argument('--output', default='out/motions', help='output directory (default out/motions)')
    args = parser.parse_args(argv)
    try:
        motions_demo(Path(args.output))
    except Exception as err:  # noqa: BLE001 - a demo: one line, exit 1
        print(f'ERROR: {type(err).__name__}: {err}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
