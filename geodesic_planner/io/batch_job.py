"""A batch job on Ray: many requests planned by workers that load the robot and scenes once.

:func:`run_job` reads the requests (:mod:`.batch_input`), hands them in small chunks to Ray actors
(one per worker; each builds the job's :class:`~.batch_plan.BatchContext` once and plans with
:func:`~.batch_plan.plan_row`), and writes each shard (:mod:`.batch_output`) as soon as its
rows are in. Ray places the actors (a local instance on this machine's cores, or an existing
cluster at ``address``); the driver keeps at most two chunks in flight per worker, so memory is
bounded by the shards being filled, not by the job.

Failures. A request that raises is a failed row (its code and message, from ``plan_row``); one
that runs past its time limit stops at the library's next checkpoint (TIMED_OUT). A worker that
dies (a crash, a killed process, a lost node) or does not come back within its chunk's time
limit plus :data:`GRACE` is replaced: the requests it held are planned again, one at a time,
and a request that kills a worker twice, or has to be stopped, is a failed row with the reason.

Network. Ray is never left to look up this machine's address: without one it connects towards a
public DNS server to find it, and it resolves a node address of 127.0.0.1 the same way unless
``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER`` is 0. A local instance runs on 127.0.0.1 with that variable
set (before Ray is imported, and so for its workers); a cluster's ``HOST:PORT`` gives the node
address (:func:`_node_address`: the loopback one for a cluster on this machine, else the source
address of the route towards HOST).
"""
from __future__ import annotations

import collections
import hashlib
import ipaddress
import os
import shutil
import socket
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..core.codes import PlanCode
from ..core.errors import GeodesicPlannerError, RequestError, quoted
from .batch_input import Record, count_records, input_format, read_records
from .batch_output import done_shards, shard_name, write_manifest, write_shard
from .batch_plan import DEFAULT_SAMPLE_PERIOD, BatchContext, failure_row, plan_row, request_id

__all__ = ['GRACE', 'MAX_SHARD_SIZE', 'MAX_WORKERS', 'BatchError', 'JobReport', 'JobSpec', 'run_job']

#: Largest number of workers (actors) of one job.
MAX_WORKERS = 1024
#: Largest shard, rows.
MAX_SHARD_SIZE = 100_000
#: Time a worker is given beyond its chunk's time limits before it is replaced, s.
GRACE = 10.0
#: Time a new worker is given to start (import the library, build the robot and scenes), s.
START_TIME = 300.0
#: Most requests per call to a worker: a call costs the driver ~0.7 ms of CPU (Ray's threads
#: included), against ~6 ms per ur5e LIN plan; a job hands each worker at least 8 chunks.
MAX_CHUNK = 16
#: Object store of a local instance, bytes (rows are small; Ray's default is 30 % of the RAM).
OBJECT_STORE_BYTES = 256 << 20


class BatchError(GeodesicPlannerError):
    """A batch job cannot start or go on (bad input with ``strict``, Ray cannot be started)."""


@dataclass(frozen=True)
class JobSpec:
    """What a job plans and where its results go.

    Attributes:
        input: the requests (JSON Lines or Parquet).
        output: the results' directory (created if missing).
        robot: default robot (preset name or URDF path; '' : each request names its own).
        scenes: scene name -> scene YAML path ('' : the default scene).
        fmt: 'jsonl', 'parquet', or '' (from the input's name).
        shard_size: requests per shard, 1 to :data:`MAX_SHARD_SIZE`.
        sample_period: time between a trajectory's points, s.
        time_limit: a request's time limit, s.
        ptp_around: in a scene, blocked PTP items plan around the obstacles (rows then depend on
            OMPL's random state); ptp_planning_timeout: that search's budget per item, s.
    """

    input: str
    output: str
    robot: str = ''
    scenes: Mapping[str, str] = field(default_factory=dict)
    fmt: str = ''
    shard_size: int = 1000
    sample_period: float = DEFAULT_SAMPLE_PERIOD
    time_limit: float = 60.0
    ptp_around: bool = False
    ptp_planning_timeout: float = 1.0


@dataclass
class JobReport:
    """What a job did.

    Attributes:
        total: requests in the input (malformed lines and rows included).
        resumed: of them, those found done in the shards already written.
        planned: requests planned by this run.
        failed: of them, those whose row is not SUCCESS.
        skipped: malformed lines or rows: ('line N' or 'row N', reason).
        shards: shards written by this run.
        workers: workers used.
        seconds: wall time of the planning (Ray's start-up excluded).
        driver_cpu: CPU time of this process over that time (reading, handing out, gathering,
            writing the shards), s.
        worker_cpu: CPU time of the workers over that time (of those not replaced), s.
    """

    total: int = 0
    resumed: int = 0
    planned: int = 0
    failed: int = 0
    skipped: list[tuple[str, str]] = field(default_factory=list)
    shards: int = 0
    workers: int = 0
    seconds: float = 0.0
    driver_cpu: float = 0.0
    worker_cpu: float = 0.0


class _Worker:
    """A Ray actor's state: the job's context, built once."""

    def __init__(self, context: BatchContext) -> None:
        context.load()
        self.context = context
        self.cpu0 = time.process_time()

    def ready(self) -> int:
        return os.getpid()

    def cpu(self) -> float:
        """CPU time of this worker's process since it was ready, s (Ray's threads included)."""
        return time.process_time() - self.cpu0

    def plan(self, items: list[tuple[int, Any]]) -> list[dict[str, Any]]:
        return [plan_row(data, self.context, index) for index, data in items]


@dataclass
class _Call:
    ref: Any
    slot: int
    items: list[tuple[int, Any]]
    attempt: int = 0
    started: float | None = None


def _file_digest(path: str) -> str:
    digest = hashlib.sha256()
    with open(path, 'rb') as fh:
        for block in iter(lambda: fh.read(1 << 20), b''):
            digest.update(block)
    return digest.hexdigest()


def _node_address(address: str) -> str:
    """This machine's address as the cluster at ``address`` (HOST:PORT) sees it: the loopback
    address for a cluster on this machine, else the source address of a route towards HOST (a UDP
    socket's, nothing is sent), so that Ray never looks for it through a public server.

    Raises:
        RequestError: not HOST:PORT; BatchError: no route to HOST.
    """
    host, sep, port = address.rpartition(':')
    host = host.strip('[]')
    if not sep or not host or not port.isdigit() or '://' in address:
        raise RequestError(f'--address must be HOST:PORT (the head\'s address, as ray start --head prints it), '
                           f'got {quoted(address)}')
    try:
        infos = socket.getaddrinfo(host, int(port), type=socket.SOCK_DGRAM)
        if ipaddress.ip_address(infos[0][4][0]).is_loopback:
            return '127.0.0.1'
        with socket.socket(infos[0][0], socket.SOCK_DGRAM) as sock:
            sock.connect(infos[0][4])
            return str(sock.getsockname()[0])
    except (OSError, ValueError, IndexError) as err:
        raise BatchError(f'cannot reach the Ray cluster at {quoted(address)}: {err}') from err


def _start_ray(workers: int | None, address: str | None) -> tuple[Any, bool, str]:
    """(the ray module, whether this call started it, its temporary directory or '')."""
    os.environ.setdefault('RAY_USAGE_STATS_ENABLED', '0')
    node = '127.0.0.1' if address is None else _node_address(address)
    if node == '127.0.0.1':
        os.environ['RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER'] = '0'
    import ray
    if ray.is_initialized():
        return ray, False, ''
    from ray._private import ray_constants
    if node == '127.0.0.1':
        ray_constants.ENABLE_RAY_CLUSTER = False      # Ray imported before the variable was set
    if address is not None:
        try:
            ray.init(address=address, _node_ip_address=node, include_dashboard=False, configure_logging=False)
        except (ConnectionError, RuntimeError, ValueError) as err:
            raise BatchError(f'cannot join the Ray cluster at {quoted(address)}: {err}') from err
        return ray, True, ''
    # Ray's socket paths under it must fit 107 bytes: $TMPDIR if short, else /tmp
    base = tempfile.gettempdir()
    temp = tempfile.mkdtemp(prefix='gpray', dir=base if len(base) <= 40 else '/tmp')
    try:
        ray.init(num_cpus=workers, _node_ip_address='127.0.0.1', include_dashboard=False, _temp_dir=temp,
                 object_store_memory=OBJECT_STORE_BYTES, configure_logging=False, log_to_driver=False)
    except (ConnectionError, RuntimeError, ValueError, OSError) as err:
        shutil.rmtree(temp, ignore_errors=True)
        raise BatchError(f'cannot start a local Ray instance: {err}') from err
    return ray, True, temp


def run_job(spec: JobSpec, *, workers: int | None = None, address: str | None = None, resume: bool = False,
            strict: bool = False, on_progress: Callable[[int, int, int], None] | None = None,
            on_skip: Callable[[str, str], None] | None = None) -> JobReport:
    """Plan every request of ``spec.input`` and write the result shards (see the module's doc).

    Args:
        spec: the job.
        workers: workers (Ray actors); None: this machine's cores (local), the cluster's CPUs.
        address: an existing Ray cluster's address (``ray.init(address=...)``); None: a local
            instance started for this job and stopped after it.
        resume: go on with the job whose shards ``spec.output`` holds.
        strict: refuse an input with a malformed line or row (before planning anything) instead
            of skipping it.
        on_progress: called with (requests done, total, planned by this run) as rows come in.
        on_skip: called with ('line N' or 'row N', reason) for each malformed one.
    Returns:
        The report.
    Raises:
        RequestError: unreadable input, an unwritable output, a resume of another job.
        RequestError: with ``strict``, a malformed line or row (named).
        BatchError: Ray cannot be started.
        GeodesicPlannerError: the robot or a scene cannot be loaded.
    """
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise RequestError(f'workers must be 1 to {MAX_WORKERS}, got {workers}')
    if not 1 <= spec.shard_size <= MAX_SHARD_SIZE:
        raise RequestError(f'shard size must be 1 to {MAX_SHARD_SIZE} rows, got {spec.shard_size}')
    fmt = input_format(spec.input, spec.fmt)
    total = count_records(spec.input, fmt, strict=strict)    # strict: malformed input refused here
    scenes = {name: os.path.abspath(path) for name, path in spec.scenes.items()}
    base_dir = os.path.dirname(os.path.abspath(spec.input))
    context = BatchContext(spec.robot, scenes, base_dir, spec.sample_period, spec.time_limit, spec.ptp_around,
                           spec.ptp_planning_timeout)
    context.load()                      # a bad robot or scene is refused before Ray starts
    try:
        os.makedirs(spec.output, exist_ok=True)
    except OSError as err:
        raise RequestError(f'cannot create {quoted(spec.output)}: {err.strerror or err}') from err
    job = {'input': os.path.abspath(spec.input), 'sha256': _file_digest(spec.input), 'format': fmt,
           'robot': spec.robot, 'scenes': scenes, 'shard_size': spec.shard_size,
           'sample_period': spec.sample_period, 'time_limit': spec.time_limit, 'ptp_around': spec.ptp_around,
           'ptp_planning_timeout': spec.ptp_planning_timeout, 'version': 1}
    write_manifest(spec.output, job, resume=resume)
    done = done_shards(spec.output) if resume else set()
    ray, started, temp = _start_ray(workers, address)
    try:
        n = workers or max(1, int(ray.cluster_resources().get('CPU', 1)))
        driver = _Driver(ray, spec, context, n, done, strict, on_progress, on_skip)
        driver.report.total = total
        driver.chunk = max(1, min(MAX_CHUNK, total // (8 * n)))
        return driver.run(read_records(spec.input, fmt, skip=driver.skip))
    finally:
        if started:
            ray.shutdown()
        if temp:
            shutil.rmtree(temp, ignore_errors=True)


class _Driver:
    """Hands chunks to the workers, gathers their rows into shards, replaces failed workers."""

    def __init__(self, ray: Any, spec: JobSpec, context: BatchContext, n: int, done: set[int],  # noqa: ANN401
                 strict: bool, on_progress: Callable[[int, int, int], None] | None,
                 on_skip: Callable[[str, str], None] | None) -> None:
        self.ray, self.spec, self.context, self.done = ray, spec, context, done
        self.strict, self.on_progress, self.on_skip = strict, on_progress, on_skip
        self.remote = ray.remote(num_cpus=1, max_restarts=0, max_task_retries=0)(_Worker)
        self.actors: list[Any] = [None] * n
        self.queues: list[collections.deque[_Call]] = [collections.deque() for _ in range(n)]
        self.fresh = [True] * n
        self.retry: collections.deque[tuple[list[tuple[int, Any]], int]] = collections.deque()
        self.rows: dict[int, list[dict[str, Any]]] = {}     # shard -> rows in
        self.open: dict[int, int] = {}                       # shard -> requests not yet back
        self.reading = -1                                    # the shard being read
        self.report = JobReport(workers=n)
        self.counted = 0
        self.chunk = 1

    def skip(self, index: int) -> bool:
        if (index - 1) // self.spec.shard_size in self.done:
            self.report.resumed += 1
            return True
        return False

    def _progress(self) -> None:
        if self.on_progress is not None:
            self.on_progress(self.report.resumed + self.counted, self.report.total, self.report.planned)

    def _new_actor(self, slot: int) -> None:
        self.actors[slot] = self.remote.remote(self.context)
        self.fresh[slot] = True

    def run(self, records: Iterator[Record]) -> JobReport:
        for slot in range(len(self.actors)):
            self._new_actor(slot)
        t0, c0 = time.monotonic(), time.process_time()
        exhausted = False
        while True:
            while sum(map(len, self.queues)) < 2 * len(self.actors) and (self.retry or not exhausted):
                if self.retry:
                    items, attempt = self.retry.popleft()
                else:
                    items, exhausted = self._read(records)
                    attempt = 0
                if items:
                    self._submit(items, attempt)
            self._flush(exhausted)
            calls = {c.ref: c for q in self.queues for c in q}
            if not calls:
                break
            ready, _ = self.ray.wait(list(calls), num_returns=1, timeout=1.0)
            for ref in ready:
                self._finish(calls[ref])
            self._check_deadlines()
        self._flush(True)
        self.report.seconds = time.monotonic() - t0
        self.report.driver_cpu = time.process_time() - c0
        try:
            self.report.worker_cpu = sum(self.ray.get([a.cpu.remote() for a in self.actors], timeout=GRACE))
        except self.ray.exceptions.RayError:
            self.report.worker_cpu = float('nan')
        return self.report

    def _read(self, records: Iterator[Record]) -> tuple[list[tuple[int, Any]], bool]:
        """Up to ``chunk`` requests from the input, and whether it is exhausted."""
        items: list[tuple[int, Any]] = []
        while len(items) < self.chunk:
            rec = next(records, None)
            if rec is None:
                return items, True
            shard = (rec.index - 1) // self.spec.shard_size
            self.reading = max(self.reading, shard)
            self.rows.setdefault(shard, [])
            self.open.setdefault(shard, 0)
            if rec.problem:
                if self.strict:
                    raise BatchError(f'{rec.where}: {rec.problem} (--strict: the job stops here)')
                self.report.skipped.append((rec.where, rec.problem))
                if self.on_skip is not None:
                    self.on_skip(rec.where, rec.problem)
                self.counted += 1
                self._progress()
                continue
            self.open[shard] += 1
            items.append((rec.index, rec.data))
        return items, False

    def _submit(self, items: list[tuple[int, Any]], attempt: int) -> None:
        slot = min(range(len(self.actors)), key=lambda s: len(self.queues[s]))
        ref = self.actors[slot].plan.remote(items)
        call = _Call(ref, slot, items, attempt)
        if not self.queues[slot]:
            call.started = time.monotonic()
        self.queues[slot].append(call)

    def _finish(self, call: _Call) -> None:
        queue = self.queues[call.slot]
        if not any(c is call for c in queue):
            return              # its worker was replaced meanwhile: the call was handed out again
        try:
            rows = self.ray.get(call.ref)
        except self.ray.exceptions.RayError as err:
            self._worker_lost(call.slot, f'its worker died ({type(err).__name__}: {_first_line(err)})')
            return
        queue.remove(call)
        self.fresh[call.slot] = False
        if queue:
            queue[0].started = time.monotonic()
        self._take(rows)

    def _take(self, rows: list[dict[str, Any]]) -> None:
        for row in rows:
            shard = (int(row['index']) - 1) // self.spec.shard_size
            self.rows[shard].append(row)
            self.open[shard] -= 1
            self.report.planned += 1
            self.report.failed += int(row['status']) != PlanCode.SUCCESS
            self.counted += 1
        self._progress()

    def _worker_lost(self, slot: int, reason: str, *, timed_out: bool = False) -> None:
        """Replace the worker of ``slot``; plan its calls again (the first one, which it was
        working on, one request at a time: a single request that failed so is a failed row)."""
        calls = list(self.queues[slot])
        self.queues[slot].clear()
        self.ray.kill(self.actors[slot], no_restart=True)
        self._new_actor(slot)
        if not calls:
            return
        head, rest = calls[0], calls[1:]
        for call in reversed(rest):
            self.retry.appendleft((call.items, call.attempt))
        if len(head.items) > 1:
            for item in reversed(head.items):
                self.retry.appendleft(([item], head.attempt))
        elif timed_out or head.attempt >= 1:
            index, data = head.items[0]
            code = PlanCode.TIMED_OUT if timed_out else PlanCode.PLANNING_FAILED
            again = '' if timed_out else ' (twice)'
            self._take([failure_row(index, request_id(data, index), code, f'{reason}{again}')])
        else:
            self.retry.appendleft((head.items, head.attempt + 1))

    def _check_deadlines(self) -> None:
        now = time.monotonic()
        for slot, queue in enumerate(self.queues):
            started = queue[0].started if queue else None
            if started is None:
                continue
            head = queue[0]
            budget = len(head.items) * self.spec.time_limit + GRACE + (START_TIME if self.fresh[slot] else 0.0)
            if now - started > budget:
                self._worker_lost(slot, f'ran past its time limit of {self.spec.time_limit:g} s and did not stop '
                                        f'within {GRACE:g} s more: its worker was replaced', timed_out=True)

    def _flush(self, exhausted: bool) -> None:
        """Write every shard that is read to its end and has all its rows."""
        for shard in sorted(self.open):
            if self.open[shard] == 0 and (exhausted or shard < self.reading):
                write_shard(self.rows.pop(shard), os.path.join(self.spec.output, shard_name(shard)))
                del self.open[shard]
                self.report.shards += 1


def _first_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return text[0][:200] if text else ''
