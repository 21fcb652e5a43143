"""The requests of a batch job: JSON Lines or Parquet, read a block at a time.

JSON Lines: one request (a JSON object, :mod:`.batch_plan`'s schema) per line; blank lines are
skipped; each request is numbered by its line (from 1). Parquet: one request per row, the
columns being the request's keys (poses as structs ``{position: {x, y, z}, orientation: {x, y,
z, w}}`` or lists, joints as lists; a null is an absent key); each request is numbered by its row
(from 1). Either way the number is the request's ``index`` in the results.

A line that is not a JSON object, or longer than :data:`MAX_LINE_BYTES`, and a Parquet row group
that cannot be read are *malformed*: :class:`Record` carries the reason instead of the request
(the job reports and skips it, or stops). Memory: one line, or one row group, at a time.
"""
from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from ..core.errors import RequestError, quoted

__all__ = ['FORMATS', 'MAX_LINE_BYTES', 'Record', 'count_records', 'input_format', 'read_records']

#: Input formats, by file name ending.
FORMATS = {'.jsonl': 'jsonl', '.ndjson': 'jsonl', '.json': 'jsonl', '.parquet': 'parquet', '.pq': 'parquet'}
#: Longest JSON line read, bytes (a request of MAX_ITEMS sequence items is well under it).
MAX_LINE_BYTES = 1 << 20


@dataclass(frozen=True)
class Record:
    """One request of the input, or why its line or row cannot be read.

    Attributes:
        index: line (JSON Lines) or row (Parquet) number, from 1.
        data: the decoded request (None when malformed).
        problem: why the line or row is malformed ('' when it is not).
    """

    index: int
    data: Any = None
    problem: str = ''

    @property
    def where(self) -> str:
        """'line N' or 'row N' (for messages)."""
        return f'{self.unit} {self.index}'

    unit: str = 'line'


def input_format(path: str, given: str = '') -> str:
    """'jsonl' or 'parquet': ``given``, else from the file name's ending.

    Raises:
        RequestError: an unknown format or ending.
    """
    if given:
        if given not in ('jsonl', 'parquet'):
            raise RequestError(f'input format must be jsonl or parquet, got {quoted(given)}')
        return given
    ext = os.path.splitext(path)[1].lower()
    if ext not in FORMATS:
        raise RequestError(f'cannot tell the format of {quoted(path)} from its name (endings: '
                           f'{", ".join(sorted(FORMATS))}): give --format jsonl or parquet')
    return FORMATS[ext]


def _open_regular(path: str) -> Any:  # noqa: ANN401
    try:
        if not os.path.isfile(path):
            why = 'no such file' if not os.path.exists(path) else 'not a regular file'
            raise RequestError(f'cannot read {quoted(path)}: {why}')
        return open(path, 'rb')  # closed by the caller
    except OSError as err:
        raise RequestError(f'cannot read {quoted(path)}: {err.strerror or err}') from err


def count_records(path: str, fmt: str, *, strict: bool = False) -> int:
    """How many requests (non-blank lines, or rows) the input holds.

    Args:
        strict: also decode every line (read every row group) and refuse the first malformed one.
    Raises:
        RequestError: the file cannot be read; with ``strict``, a malformed line or row (named).
    """
    if strict:
        n = 0
        for rec in read_records(path, fmt):
            if rec.problem:
                raise RequestError(f'{rec.where}: {rec.problem} (--strict: nothing was planned)')
            n += 1
        return n
    if fmt == 'parquet':
        return int(_parquet(path).metadata.num_rows)
    n = 0
    with _open_regular(path) as fh:
        for _, line in _lines(fh):
            n += bool(line is None or line.strip())
    return n


def _lines(fh: Any) -> Iterator[tuple[int, bytes | None]]:  # noqa: ANN401
    """(line number, bytes or None when longer than MAX_LINE_BYTES) of a binary file."""
    number = 0
    while True:
        line = fh.readline(MAX_LINE_BYTES + 1)
        if not line:
            return
        number += 1
        if len(line) > MAX_LINE_BYTES and not line.endswith(b'\n'):
            while True:     # the rest of the long line
                rest = fh.readline(MAX_LINE_BYTES)
                if not rest or rest.endswith(b'\n'):
                    break
            yield number, None
        else:
            yield number, line


def read_records(path: str, fmt: str, skip: Callable[[int], bool] = lambda index: False) -> Iterator[Record]:
    """The input's requests in order (see the module's doc).

    Args:
        path: the input file.
        fmt: 'jsonl' or 'parquet'.
        skip: index -> True for a request already done (a resumed job): its record is not decoded
            and not yielded.
    Raises:
        RequestError: the file cannot be opened (a Parquet file whose footer cannot be read).
    """
    if fmt == 'parquet':
        yield from _parquet_records(path, skip)
        return
    with _open_regular(path) as fh:
        for number, line in _lines(fh):
            if line is not None and not line.strip():
                continue
            if skip(number):
                continue
            yield _decode_line(number, line)


def _decode_line(number: int, line: bytes | None) -> Record:
    if line is None:
        return Record(number, problem=f'longer than {MAX_LINE_BYTES} bytes')
    try:
        data = json.loads(line.rstrip(b'\r\n').decode('utf-8'))   # not json's guess of UTF-16/32
    except UnicodeDecodeError as err:
        return Record(number, problem=f'not UTF-8 (byte {err.start + 1})')
    except json.JSONDecodeError as err:
        return Record(number, problem=f'malformed JSON at column {err.colno}: {err.msg}')
    except RecursionError:
        return Record(number, problem='nested too deeply')
    if not isinstance(data, dict):
        return Record(number, problem=f'expected a JSON object, got {type(data).__name__}')
    return Record(number, data)


def _parquet(path: str) -> Any:  # noqa: ANN401
    import pyarrow as pa
    import pyarrow.parquet as pq
    _open_regular(path).close()
    try:
        return pq.ParquetFile(path)
    except (OSError, pa.ArrowException) as err:
        raise RequestError(f'cannot read Parquet file {quoted(path)}: {err}') from err


def _parquet_records(path: str, skip: Callable[[int], bool]) -> Iterator[Record]:
    import pyarrow as pa
    pf = _parquet(path)
    first = 1
    for group in range(pf.metadata.num_row_groups):
        n = pf.metadata.row_group(group).num_rows
        todo = [i for i in range(first, first + n) if not skip(i)]
        if todo:
            try:
                rows = pf.read_row_group(group).to_pylist()
            except (OSError, pa.ArrowException) as err:
                for i in todo:
                    yield Record(i, problem=f'row group {group} cannot be read: {err}', unit='row')
                rows = None
            if rows is not None:
                for i in todo:
                    data = {k: v for k, v in rows[i - first].items() if v is not None}
                    yield Record(i, data, unit='row')
        first += n
