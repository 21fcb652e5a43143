"""The results of a batch job: Parquet shards in a directory, and the job's manifest.

Shard ``k`` (``part-00000k.parquet``) holds the rows of the requests numbered ``k * shard_size + 1``
to ``(k + 1) * shard_size`` (line or row numbers), sorted by that number: the same shards, bit for
bit, whatever the number of workers (only ``planning_time`` is a measurement). A shard is written
to a temporary name and renamed when complete, so a shard file is always whole; a job interrupted
anywhere resumes from the shards present (``job.json`` records what the job was, so that a
resume with another input or other options is refused instead of mixing results).

Columns (:data:`SCHEMA`): ``index`` (int64), ``id`` (string), ``status`` (int32, PlanErrorCode),
``message`` (string), ``fraction``, ``planning_time`` (s), ``duration`` (s), ``min_clearance``
(m; NaN without a scene or on failure) (float64), ``robot`` (string), ``joint_names``
(list<string>), ``times`` (list<float64>, s), ``positions``, ``velocities``, ``accelerations``
(list<list<float64>>, one list of dof values per time; rad or m, per s, per s^2).
"""
from __future__ import annotations

import contextlib
import json
import os
import re
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import numpy as np

from ..core.errors import RequestError, quoted

__all__ = ['MANIFEST', 'SHARD_PATTERN', 'done_shards', 'read_rows', 'schema', 'shard_name', 'write_manifest',
           'write_shard']

MANIFEST = 'job.json'
SHARD_PATTERN = re.compile(r'^part-(\d{6})\.parquet$')


def shard_name(k: int) -> str:
    """File name of shard ``k``."""
    return f'part-{k:06d}.parquet'


def schema() -> Any:  # noqa: ANN401
    """The shards' pyarrow schema."""
    import pyarrow as pa
    f64 = pa.float64()
    return pa.schema([
        ('index', pa.int64()), ('id', pa.string()), ('status', pa.int32()), ('message', pa.string()),
        ('fraction', f64), ('planning_time', f64), ('duration', f64), ('min_clearance', f64),
        ('robot', pa.string()), ('joint_names', pa.list_(pa.string())), ('times', pa.list_(f64)),
        ('positions', pa.list_(pa.list_(f64))), ('velocities', pa.list_(pa.list_(f64))),
        ('accelerations', pa.list_(pa.list_(f64)))])


def _offsets(lengths: Sequence[int] | np.ndarray) -> Any:  # noqa: ANN401
    import pyarrow as pa
    return pa.array(np.concatenate([[0], np.cumsum(lengths, dtype=np.int64)]).astype(np.int32))


def _matrix_column(rows: Sequence[Mapping[str, Any]], key: str) -> Any:  # noqa: ANN401
    """A list<list<float64>> column of the rows' (N, dof) arrays, built from numpy (no Python floats)."""
    import pyarrow as pa
    arrays = [np.asarray(r[key], dtype=float).reshape(len(r[key]), -1) if len(r[key]) else np.zeros((0, 0))
              for r in rows]
    flat = np.concatenate([a.reshape(-1) for a in arrays]) if arrays else np.zeros(0)
    dofs: Any = (np.concatenate([np.full(len(a), a.shape[1], dtype=np.int64) for a in arrays]) if arrays
                 else np.zeros(0, dtype=np.int64))
    inner = pa.ListArray.from_arrays(_offsets(dofs), pa.array(flat, pa.float64()))
    return pa.ListArray.from_arrays(_offsets([len(a) for a in arrays]), inner)


def write_shard(rows: Sequence[Mapping[str, Any]], path: str) -> None:
    """Write the rows (sorted by ``index``) to ``path`` as one Parquet file, atomically.

    Raises:
        RequestError: the file cannot be written (the reason).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq
    rows = sorted(rows, key=lambda r: int(r['index']))
    times = [np.asarray(r['times'], dtype=float) for r in rows]
    columns = {
        'index': pa.array([int(r['index']) for r in rows], pa.int64()),
        'id': pa.array([str(r['id']) for r in rows], pa.string()),
        'status': pa.array([int(r['status']) for r in rows], pa.int32()),
        'message': pa.array([str(r['message']) for r in rows], pa.string()),
        **{k: pa.array([float(r[k]) for r in rows], pa.float64())
           for k in ('fraction', 'planning_time', 'duration', 'min_clearance')},
        'robot': pa.array([str(r['robot']) for r in rows], pa.string()),
        'joint_names': pa.array([list(r['joint_names']) for r in rows], pa.list_(pa.string())),
        'times': pa.ListArray.from_arrays(_offsets([len(t) for t in times]),
                                          pa.array(np.concatenate(times) if times else np.zeros(0), pa.float64())),
        **{k: _matrix_column(rows, k) for k in ('positions', 'velocities', 'accelerations')},
    }
    table = pa.Table.from_pydict(columns, schema=schema())
    tmp = path + '.tmp'
    try:
        pq.write_table(table, tmp, use_dictionary=False)   # 3x faster, smaller: few values repeat
        os.replace(tmp, path)
    except OSError as err:
        _remove(tmp)
        raise RequestError(f'cannot write {quoted(path)}: {err.strerror or err}') from err
    except BaseException:
        _remove(tmp)            # Ctrl-C while writing: no half file left
        raise


def _remove(path: str) -> None:
    with contextlib.suppress(OSError):
        os.remove(path)


def done_shards(directory: str) -> set[int]:
    """The shards a directory holds (a half-written ``.tmp`` file is removed)."""
    done = set()
    for name in os.listdir(directory):
        m = SHARD_PATTERN.match(name)
        if m:
            done.add(int(m.group(1)))
        elif name.startswith('part-') and name.endswith('.parquet.tmp'):
            os.remove(os.path.join(directory, name))
    return done


def read_rows(directory: str) -> Iterator[dict[str, Any]]:
    """The rows of a job's shards in order, one shard in memory at a time (trajectories as arrays).

    Raises:
        RequestError: a shard that cannot be read.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq
    for k in sorted(done_shards(directory)):
        path = os.path.join(directory, shard_name(k))
        try:
            table = pq.read_table(path)
        except (OSError, pa.ArrowException) as err:
            raise RequestError(f'cannot read {quoted(path)}: {err}') from err
        for row in table.to_pylist():
            for key in ('times', 'positions', 'velocities', 'accelerations'):
                row[key] = np.asarray(row[key], dtype=float)
            yield row


def write_manifest(directory: str, job: Mapping[str, Any], *, resume: bool) -> None:
    """Record the job in ``directory/job.json``; on a resume, check that it is the same job.

    Raises:
        RequestError: without ``resume``, a directory that holds results already; with it, a
            directory without a manifest, or one whose job differs (the keys that differ named).
    """
    path = os.path.join(directory, MANIFEST)
    has_results = os.path.exists(path) or bool(done_shards(directory))
    if not resume:
        if has_results:
            raise RequestError(f'{quoted(directory)} holds the results of a job: --resume to go on with it, '
                               'or give another directory')
        _write_json(path, job)
        return
    if not os.path.exists(path):
        if has_results:
            raise RequestError(f'cannot resume: {quoted(directory)} has shards but no {MANIFEST}')
        _write_json(path, job)
        return
    try:
        with open(path, encoding='utf-8') as fh:
            old = json.load(fh)
    except (OSError, ValueError) as err:
        raise RequestError(f'cannot resume: {quoted(path)} cannot be read: {err}') from err
    differ = sorted(k for k in set(old) | set(job) if old.get(k) != job.get(k))
    if differ:
        shown = '; '.join(f'{k}: was {old.get(k)!r}, now {job.get(k)!r}' for k in differ[:4])
        raise RequestError(f'cannot resume: this is another job than the one in {quoted(directory)} ({shown})')


def _write_json(path: str, data: Mapping[str, Any]) -> None:
    try:
        with open(path + '.tmp', 'w', encoding='utf-8') as fh:
            json.dump(data, fh, indent=1, sort_keys=True)
            fh.write('\n')
        os.replace(path + '.tmp', path)
    except OSError as err:
        raise RequestError(f'cannot write {quoted(path)}: {err.strerror or err}') from err
