"""Planner node latency: service request -> JointTrajectory received by a subscriber.

Starts the real node (console script ``geodesic_planner_node``) per robot, then from this process:

1. sequential requests (after warm-up): latency from ``call_async`` to the trajectory arriving in
   a subscription callback (a typed Python subscriber: the time includes deserialising the
   message), and to the service response; p50/p90/max in ms. The node logs its computation per
   request (plan, timing, trajectory message); "ROS overhead" is the latency minus that, so it
   can be compared across library versions and machine load;
2. sustained load: 4 concurrent clients sending back-to-back requests (each blocks on an event
   until its response: no polling); plans per second, and CPU time per plan of the node process
   (all threads, from /proc) and of this process.

``--joint-states-hz 250`` also publishes ``/joint_states`` during the run, as a robot driver
does (the node validates every message).

Fair measurement: this process runs the subscriber and the 4 clients on a helper node without
parameter services or rosout, spun by a SingleThreadedExecutor: with rclpy's
MultiThreadedExecutor the benchmark itself uses 8-9 ms CPU per plan on the 2 cores it shares with
the node and adds 5-7 ms to the measured latency.

Run inside the loopback-only network namespace (ROS must not leave the machine)::

    bash scripts/netns.sh .venv/bin/python benchmarks/node_latency.py [--requests 100] [--robots planar_3r ur5e] [--joint-states-hz 250]

Prints a table. Not a test: nothing is asserted (targets, issue 23: ur5e median <= 8 ms,
>= 100 plans/s with 4 clients; benchmarks/speed.py --node prints them with their ratios).
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import re
import signal
import subprocess
import sys
import sysconfig
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from geodesic_planner import load_robot

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tools/ lives at the repository root
from tools import netns
from geodesic_planner.ros import conversions as cv
from geodesic_planner.core.transforms import make_transform, so3_exp

DEADLINE = 60.0


@dataclass
class Result:
    robot: str
    points: int
    traj_ms: np.ndarray        # request -> trajectory received, per request
    resp_ms: np.ndarray        # request -> response received
    rate: float                # sustained plans/s, 4 clients
    rate_requests: int
    rate_failures: int
    compute_ms: np.ndarray     # node-side plan + timing + trajectory message, per sequential request
    node_cpu_ms: float         # node process CPU time per plan under load (all its threads)
    bench_cpu_ms: float        # this process's CPU time per plan under load (4 clients + subscriber)

    @property
    def overhead_ms(self) -> np.ndarray:
        """Request -> trajectory minus the node's computation: the ROS/threading overhead."""
        return self.traj_ms - self.compute_ms


#: The node's plan line; the stages before the trajectory is published: plan, timing, collision
#: (since issue 22; optional, for older checkouts) and the trajectory message.
_PLAN_LINE = re.compile(r'\]: plan: \d+ points.*?\(request [0-9.]+ ms: plan ([0-9.]+), '
                        r'timing ([0-9.]+), (?:collision ([0-9.]+), )?trajectory ([0-9.]+)')


def _process_cpu_s(pid: int) -> float:
    """User + system CPU time of a process (all threads), s."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def requests_for(robot_name: str, n: int, seed: int = 0) -> list[Any]:
    """``n`` GetPlan requests: the paper's 3R poses, or a line + 30 deg rotation for 6-joint arms,
    with small random goal offsets (so no two requests are the same)."""
    from nav_msgs.srv import GetPlan

    rng = np.random.default_rng(seed)
    robot = load_robot(robot_name)
    out = []
    for _ in range(n):
        if robot_name == 'planar_3r':
            a = make_transform([2.5, 1.5, 0.0], so3_exp([0.0, 0.0, math.radians(30.0)]))
            dx = rng.uniform(-0.02, 0.02, 2)
            b = make_transform([1.5 + dx[0], 2.5 + dx[1], 0.0],
                               so3_exp([0.0, 0.0, math.atan2(0.7, 0.714)]))
        else:
            q0 = robot.home + np.array([0.3, 0.37, -0.17, -0.13, 0.07, 0.2])[:robot.dof]
            a = robot.fk(q0)
            axis = np.array([1.0, 2.0, -1.0]) / math.sqrt(6.0)
            b = make_transform(a[:3, 3] + np.array([0.12, -0.08, 0.1]) + rng.uniform(-0.01, 0.01, 3),
                               so3_exp(math.radians(30.0) * axis) @ a[:3, :3])
        out.append(GetPlan.Request(start=cv.matrix_to_pose_stamped(a, ''),
                                   goal=cv.matrix_to_pose_stamped(b, '')))
    return out


class Bench:
    """Helper node in this process, spun by a SingleThreadedExecutor in a thread."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        rclpy.init()
        # Only what is measured is in the wait set (no parameter services, no rosout), and a
        # single-threaded executor: its callbacks only stamp times and set futures, and
        # rclpy's MultiThreadedExecutor cost this process about twice the CPU per plan
        # (8-9 ms vs 4 ms) and added 5-7 ms to the measured latency.
        self.node = rclpy.create_node('node_latency_bench', start_parameter_services=False,
                                      enable_rosout=False)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=5)
        self.node.destroy_node()
        rclpy.try_shutdown()


def start_node(robot: str, ns: str, log_dir: Path) -> subprocess.Popen:
    exe = Path(sysconfig.get_path('scripts')) / 'geodesic_planner_node'
    log = open(log_dir / f'{robot}.log', 'wb')  # noqa: SIM115 - lives as long as the process
    return subprocess.Popen([str(exe), '--ros-args', '-r', f'__ns:={ns}', '-p', f'robot:={robot}',
                             '--log-level', 'info'],
                            stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                            process_group=0)


def stop_node(proc: subprocess.Popen) -> int:
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if proc.poll() is not None:
            break
        proc.send_signal(sig)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            continue
    return proc.returncode


def publish_joint_states(node: Any, robot: str, rate_hz: float, stop: threading.Event) -> threading.Thread:
    """Publish the robot's home state on /joint_states at ``rate_hz`` from a thread (like a
    driver) until ``stop`` is set."""
    from sensor_msgs.msg import JointState

    pub = node.create_publisher(JointState, '/joint_states', 10)
    model = load_robot(robot)
    msg = cv.vector_to_joint_state(model.joint_names, model.home)

    def run() -> None:
        period = 1.0 / rate_hz
        next_t = time.monotonic()
        while not stop.is_set():
            pub.publish(msg)
            next_t += period
            stop.wait(max(0.0, next_t - time.monotonic()))
        node.destroy_publisher(pub)

    thread = threading.Thread(target=run, name='joint_states', daemon=True)
    thread.start()
    return thread


def measure(bench: Bench, robot: str, n_requests: int, warmup: int, per_client: int,
            log_dir: Path, joint_states_hz: float = 0.0) -> Result:
    from nav_msgs.srv import GetPlan
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from trajectory_msgs.msg import JointTrajectory

    ns = f'/bench_{robot}'
    proc = start_node(robot, ns, log_dir)
    node = bench.node
    arrivals: list[float] = []
    points: list[int] = []
    cond = threading.Condition()

    def on_traj(msg: JointTrajectory) -> None:
        t = time.perf_counter()
        with cond:
            arrivals.append(t)
            points.append(len(msg.points))
            cond.notify_all()

    sub = node.create_subscription(JointTrajectory, f'{ns}/geodesic_planner/joint_trajectory',
                                   on_traj, QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    clients = [node.create_client(GetPlan, f'{ns}/geodesic_planner/plan') for _ in range(4)]
    js_stop = threading.Event()
    js_thread = (publish_joint_states(node, robot, joint_states_hz, js_stop)
                 if joint_states_hz > 0 else None)
    try:
        for c in clients:
            if not c.wait_for_service(timeout_sec=DEADLINE):
                raise RuntimeError(f'{robot}: service not up; log:\n{(log_dir / f"{robot}.log").read_text()}')
        end = time.monotonic() + DEADLINE
        while sub.get_publisher_count() == 0:
            if time.monotonic() > end:
                raise RuntimeError('trajectory publisher never matched')
            time.sleep(0.01)

        warm = requests_for(robot, 1)[0]
        warm.goal.header.frame_id = '__warmup__'     # harmless: fails, publishes nothing
        for c in clients:
            # rmw_fastrtps drops a response until the server has matched the client's response
            # reader; wait_for_service does not cover that, so do one (retried) round trip.
            end = time.monotonic() + DEADLINE
            while True:
                done = threading.Event()
                fut = c.call_async(warm)
                fut.add_done_callback(lambda _f, d=done: d.set())
                if done.wait(3.0):
                    break
                c.remove_pending_request(fut)
                if time.monotonic() > end:
                    raise RuntimeError(f'{robot}: no warm-up response')

        def call(client: Any, req: Any) -> Any:
            done = threading.Event()
            fut = client.call_async(req)
            fut.add_done_callback(lambda _f: done.set())
            if not done.wait(DEADLINE):
                raise RuntimeError('no response')
            return fut.result()

        reqs = requests_for(robot, warmup + n_requests)
        traj_ms, resp_ms = [], []
        for i, req in enumerate(reqs):
            with cond:
                k = len(arrivals)
            t0 = time.perf_counter()
            resp = call(clients[0], req)
            t_resp = time.perf_counter()
            if not resp.plan.poses:
                raise RuntimeError(f'{robot}: request {i} failed (see {log_dir})')
            with cond:
                if not cond.wait_for(lambda: len(arrivals) > k, DEADLINE):
                    raise RuntimeError('trajectory never arrived')
                t_traj = arrivals[k]
            if i >= warmup:
                traj_ms.append((t_traj - t0) * 1e3)
                resp_ms.append((t_resp - t0) * 1e3)

        # sustained: 4 clients back to back
        load = requests_for(robot, 4 * per_client, seed=1)
        failures = [0]
        lock = threading.Lock()

        def worker(c: int) -> None:
            for req in load[c::4]:
                resp = call(clients[c], req)
                if not resp.plan.poses:
                    with lock:
                        failures[0] += 1

        with cond:
            k0 = len(arrivals)
        t0 = time.perf_counter()
        cpu0 = _process_cpu_s(proc.pid), time.process_time()
        threads = [threading.Thread(target=worker, args=(c,)) for c in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        expected = len(load) - failures[0]
        with cond:
            cond.wait_for(lambda: len(arrivals) >= k0 + expected, DEADLINE)
            t_end = arrivals[-1] if len(arrivals) > k0 else time.perf_counter()
        node_cpu = (_process_cpu_s(proc.pid) - cpu0[0]) * 1e3 / len(load)
        bench_cpu = (time.process_time() - cpu0[1]) * 1e3 / len(load)
        rate = expected / (t_end - t0)
    finally:
        js_stop.set()
        if js_thread is not None:
            js_thread.join(5.0)
        for c in clients:
            node.destroy_client(c)
        node.destroy_subscription(sub)
        rc = stop_node(proc)
        if rc != 0:
            print(f'warning: {robot} node exited with {rc}', file=sys.stderr)
    log = (log_dir / f'{robot}.log').read_text(errors='replace')   # complete once the node exited
    waits = [float(x) for x in re.findall(r'waited ([0-9.]+) ms for', log)]
    if waits or 'subscriptions matched after waiting' in log:
        print(f'note: {robot}: the node waited for subscription matching {len(waits)} times '
              f'(max {max(waits, default=0):.1f} ms)', file=sys.stderr)
    # The node logs one 'plan:' line per successful plan, in order (the warm-up requests fail):
    # the first warmup + n_requests are the sequential ones.
    stages = [sum(float(g) for g in m.groups() if g is not None)
              for m in _PLAN_LINE.finditer(log)][warmup:warmup + n_requests]
    if len(stages) != len(traj_ms):
        raise RuntimeError(f'{robot}: {len(stages)} plan lines in the node log for {len(traj_ms)} requests')
    return Result(robot, int(np.median(points)), np.array(traj_ms), np.array(resp_ms),
                  rate, len(load), failures[0], np.array(stages), node_cpu, bench_cpu)


def breakdown(robot: str, n: int) -> dict[str, float]:
    """Median stage times (ms) of the node's compute_plan in this process, no ROS transport."""
    from geodesic_planner.ros import params
    from geodesic_planner.ros import planning as pn
    from geodesic_planner.ros.service_requests import get_plan_request

    values = params.defaults(params.PLANNER_PARAMETERS)
    values['robot'] = robot
    config = pn.build_config(values)
    reqs = requests_for(robot, n + 3, seed=2)
    stages: dict[str, list[float]] = {}
    for i, req in enumerate(reqs):
        t0 = time.perf_counter()
        res = pn.compute_plan(config, get_plan_request(config, req), None)
        total = (time.perf_counter() - t0) * 1e3
        if i >= 3:
            for k, v in {**res.stage_ms, 'total': total}.items():
                stages.setdefault(k, []).append(v)
    return {k: float(np.median(v)) for k, v in stages.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--requests', type=int, default=100, help='sequential requests per robot')
    parser.add_argument('--warmup', type=int, default=5)
    parser.add_argument('--per-client', type=int, default=25, help='requests per client (4 clients)')
    parser.add_argument('--robots', nargs='+', default=['planar_3r', 'ur5e'])
    parser.add_argument('--joint-states-hz', type=float, default=0.0,
                        help='also publish /joint_states at this rate during the run, as a robot '
                             'driver does (e.g. 250); default: none')
    parser.add_argument('--log-dir', type=Path, default=None,
                        help='keep the node logs (<robot>.log) in this directory')
    args = parser.parse_args(argv)
    problem = netns.isolation_problem()
    if problem is not None:
        print(f'ERROR: {problem} (run: bash scripts/netns.sh .venv/bin/python {sys.argv[0]})',
              file=sys.stderr)
        return 1
    bench = Bench()
    results = []
    try:
        with tempfile.TemporaryDirectory(prefix='node_latency_') as tmp:
            log_dir = Path(tmp) if args.log_dir is None else args.log_dir
            log_dir.mkdir(parents=True, exist_ok=True)
            for robot in args.robots:
                results.append(measure(bench, robot, args.requests, args.warmup, args.per_client,
                                       log_dir, args.joint_states_hz))
    finally:
        bench.close()
    stages = {robot: breakdown(robot, min(args.requests, 30)) for robot in args.robots}
    load = os.getloadavg()
    print(f'# planner node latency ({platform.processor() or platform.machine()}, '
          f'{os.cpu_count()} cores, Python {platform.python_version()}, load average '
          f'{load[0]:.1f} / {load[1]:.1f}; {args.requests} sequential requests after '
          f'{args.warmup} warm-up; /joint_states at {args.joint_states_hz:g} Hz)')
    print('| robot | points | request->trajectory p50 / p90 / max (ms) | of which node compute p50 '
          '| ROS overhead p50 / p90 (ms) | request->response p50 / p90 (ms) '
          '| 4 clients: plans/s (requests, failures) | CPU per plan under load: node / benchmark (ms) |')
    print('|---|---|---|---|---|---|---|---|')
    for r in results:
        p = np.percentile(r.traj_ms, [50, 90])
        q = np.percentile(r.resp_ms, [50, 90])
        o = np.percentile(r.overhead_ms, [50, 90])
        print(f'| {r.robot} | {r.points} | {p[0]:.1f} / {p[1]:.1f} / {r.traj_ms.max():.1f} | '
              f'{np.median(r.compute_ms):.1f} | {o[0]:.1f} / {o[1]:.1f} | {q[0]:.1f} / {q[1]:.1f} | '
              f'{r.rate:.1f} ({r.rate_requests}, {r.rate_failures}) | '
              f'{r.node_cpu_ms:.1f} / {r.bench_cpu_ms:.1f} |')
    print('(node compute: plan + timing + collision + trajectory message as the node logs them; ROS '
          'overhead: request->trajectory minus that, per request)')
    print()
    print('# where the time goes: node compute_plan in-process (median ms, no ROS transport)')
    keys = list(next(iter(stages.values())))
    print('| robot | ' + ' | '.join(keys) + ' |')
    print('|---' * (len(keys) + 1) + '|')
    for robot, st in stages.items():
        print(f'| {robot} | ' + ' | '.join(f'{st[k]:.1f}' for k in keys) + ' |')
    print('(plan: library IK + BVP; timing: timed + sample; trajectory: message + validation; '
          'tool path: fk, Path, markers, built after the trajectory is published)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
