"""sensor_msgs/PointCloud2 -> points (N, 3): the x, y and z fields, checked before any allocation.

Accepted: x, y, z each once, FLOAT32 or FLOAT64 (mixed: float64), count 1, inside ``point_step``;
either byte order; organised (height > 1, rows of ``row_step`` bytes, any padding after a row's
points) or not (height 1). Other fields (rgb, intensity) are ignored; NaN points are kept here (the
library skips them). Refused with :class:`CloudError` naming the field and the values: more points
than ``max_points`` (width x height, checked first: a huge width allocates nothing), a missing or
repeated coordinate, another datatype or count, a field beyond ``point_step``, a ``row_step``
shorter than a row's points, ``data`` whose length is not ``row_step * height``.
"""
from __future__ import annotations

import numpy as np
from sensor_msgs.msg import PointCloud2, PointField

from ..core.errors import RequestError

__all__ = ['CloudError', 'cloud_points']

#: PointField datatype -> numpy type letter and size.
FLOATS = {PointField.FLOAT32: ('f', 4), PointField.FLOAT64: ('f', 8)}


class CloudError(RequestError):
    """A PointCloud2 that cannot be read as points (the message says which field and why)."""


def cloud_points(msg: PointCloud2, max_points: int) -> np.ndarray:
    """The points of ``msg``, (width * height, 3), float32 (all three fields float32) or float64.

    Raises:
        CloudError: see the module's doc.
    """
    width, height, step, row = int(msg.width), int(msg.height), int(msg.point_step), int(msg.row_step)
    n = width * height
    if n > max_points:
        raise CloudError(f'{n} points ({width} x {height}), more than max_cloud_points {max_points}')
    if n == 0:
        return np.zeros((0, 3), dtype=np.float32)
    fields = {}
    for f in msg.fields:
        if f.name in ('x', 'y', 'z'):
            if f.name in fields:
                raise CloudError(f'field {f.name!r} given twice')
            fields[f.name] = f
    missing = [c for c in 'xyz' if c not in fields]
    if missing:
        raise CloudError(f'no field {", ".join(map(repr, missing))} (fields: {[f.name for f in msg.fields]})')
    order = '>' if msg.is_bigendian else '<'
    formats, offsets = [], []
    for c in 'xyz':
        f = fields[c]
        if f.datatype not in FLOATS:
            raise CloudError(f'field {c!r}: datatype {f.datatype}, expected FLOAT32 (7) or FLOAT64 (8)')
        if f.count != 1:
            raise CloudError(f'field {c!r}: count {f.count}, expected 1')
        letter, size = FLOATS[f.datatype]
        if f.offset + size > step:
            raise CloudError(f'field {c!r}: offset {f.offset} + {size} bytes beyond point_step {step}')
        formats.append(f'{order}{letter}{size}')
        offsets.append(int(f.offset))
    if row < width * step:
        raise CloudError(f'row_step {row} is shorter than width {width} x point_step {step}')
    data = msg.data
    if len(data) != row * height:
        raise CloudError(f'data has {len(data)} bytes, row_step {row} x height {height} = {row * height} expected')
    dtype = np.dtype({'names': ['x', 'y', 'z'], 'formats': formats, 'offsets': offsets, 'itemsize': step})
    raw = np.frombuffer(data, dtype=np.uint8)
    if row != width * step:
        raw = np.ascontiguousarray(raw.reshape(height, row)[:, :width * step])
    points = raw.view(dtype).reshape(-1)
    out = np.float32 if all(fields[c].datatype == PointField.FLOAT32 for c in 'xyz') else np.float64
    return np.stack([points['x'], points['y'], points['z']], axis=1).astype(out, copy=False)
