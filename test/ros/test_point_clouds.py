"""ros/point_clouds.py: PointCloud2 -> points, and the refusal of malformed clouds (no node).

The clouds are packed here with numpy's struct layouts (independent of the parser); the fuzz
mutates valid clouds with a seeded generator: every outcome is either the points or a CloudError,
never another exception.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip('sensor_msgs')

from sensor_msgs.msg import PointCloud2, PointField

from geodesic_planner.ros.point_clouds import CloudError, cloud_points


def pack(points: np.ndarray, *, datatype: int = PointField.FLOAT32, step: int = 16, row_pad: int = 0,
         big: bool = False, extra: bool = True) -> PointCloud2:
    """An organised cloud of points (H, W, 3): x y z at offsets 0, size, 2 size, then an intensity."""
    h, w, _ = points.shape
    size = 4 if datatype == PointField.FLOAT32 else 8
    order = '>' if big else '<'
    fmt = f'{order}f{size}'
    dtype = np.dtype({'names': ['x', 'y', 'z', 'i'], 'formats': [fmt, fmt, fmt, f'{order}f4'],
                      'offsets': [0, size, 2 * size, 3 * size], 'itemsize': step})
    rows = np.zeros((h, w * step + row_pad), dtype=np.uint8)
    arr = np.zeros((h, w), dtype=dtype)
    for k, c in enumerate('xyz'):
        arr[c] = points[..., k]
    rows[:, :w * step] = arr.view(np.uint8).reshape(h, w * step)
    fields = [PointField(name=c, offset=k * size, datatype=datatype, count=1) for k, c in enumerate('xyz')]
    if extra:
        fields.append(PointField(name='intensity', offset=3 * size, datatype=PointField.FLOAT32, count=1))
    msg = PointCloud2(height=h, width=w, fields=fields, is_bigendian=big, point_step=step,
                      row_step=w * step + row_pad)
    msg.data = rows.tobytes()
    return msg


@pytest.mark.parametrize('datatype, step, row_pad, big', [
    (PointField.FLOAT32, 16, 0, False), (PointField.FLOAT32, 20, 12, True),
    (PointField.FLOAT64, 32, 0, False), (PointField.FLOAT64, 40, 8, True)])
def test_points_read_in_every_layout(datatype: int, step: int, row_pad: int, big: bool) -> None:
    rng = np.random.default_rng(step + row_pad)
    pts = rng.normal(size=(7, 9, 3))
    pts[2, 3] = np.nan
    got = cloud_points(pack(pts, datatype=datatype, step=step, row_pad=row_pad, big=big), 1000)
    want = pts.reshape(-1, 3).astype(np.float32 if datatype == PointField.FLOAT32 else np.float64)
    assert got.dtype == want.dtype and got.shape == (63, 3)
    np.testing.assert_array_equal(got, want)


def test_refusals_name_the_cause() -> None:
    good = pack(np.zeros((2, 3, 3)))
    cases: list[tuple[dict[str, Any], str]] = [
        (dict(width=10**9), 'more than max_cloud_points'),
        (dict(data=bytes(good.data)[:-1]), 'data has 95 bytes'),
        (dict(row_step=8), 'row_step 8 is shorter'),
        (dict(fields=good.fields[1:]), "no field 'x'"),
        (dict(fields=[*good.fields, good.fields[0]]), "field 'x' given twice"),
        (dict(point_step=8), 'beyond point_step 8'),
    ]
    for change, reason in cases:
        msg = pack(np.zeros((2, 3, 3)))
        for k, v in change.items():
            setattr(msg, k, v)
        with pytest.raises(CloudError, match=reason):
            cloud_points(msg, 1000)
    msg = pack(np.zeros((2, 3, 3)))
    msg.fields[2].datatype = PointField.INT32
    with pytest.raises(CloudError, match=r"field 'z': datatype 5, expected FLOAT32 \(7\) or FLOAT64 \(8\)"):
        cloud_points(msg, 1000)
    msg.fields[2].datatype, msg.fields[1].count = PointField.FLOAT32, 3
    with pytest.raises(CloudError, match="field 'y': count 3"):
        cloud_points(msg, 1000)
    assert cloud_points(PointCloud2(), 10).shape == (0, 3)


@pytest.mark.parametrize('seed', range(6))
def test_fuzzed_clouds_are_points_or_refused(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(60):
        pts = rng.normal(size=(int(rng.integers(1, 5)), int(rng.integers(1, 7)), 3))
        msg = pack(pts, datatype=PointField.FLOAT32 if rng.random() < 0.5 else PointField.FLOAT64,
                   step=48, row_pad=int(rng.integers(0, 9)))
        what = int(rng.integers(0, 7))
        if what == 0:
            msg.width = int(rng.integers(0, 2**32))
        elif what == 1:
            msg.height = int(rng.integers(0, 2**32))
        elif what == 2:
            msg.point_step = int(rng.integers(0, 64))
        elif what == 3:
            msg.row_step = int(rng.integers(0, 400))
        elif what == 4:
            msg.data = bytes(msg.data)[:int(rng.integers(0, len(msg.data) + 1))]
        elif what == 5:
            f = msg.fields[int(rng.integers(0, 3))]
            f.offset, f.datatype, f.count = int(rng.integers(0, 64)), int(rng.integers(1, 9)), int(rng.integers(0, 3))
        else:
            msg.fields = list(rng.permutation(msg.fields))[:int(rng.integers(0, 5))]
        try:
            got = cloud_points(msg, 10_000)
        except CloudError:
            continue
        assert got.shape == (msg.width * msg.height, 3)
