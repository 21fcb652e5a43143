"""Sequences in YAML requests and through geodesic-plan (msg_examples/sequence_ur5e.yaml)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from geodesic_planner.core.errors import RequestError
from geodesic_planner.io.requests import load_request, parse_request

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / 'msg_examples' / 'sequence_ur5e.yaml'


def test_the_example_sequence_parses_and_plans() -> None:
    req = load_request(str(EXAMPLE))
    assert [it.motion for it in req.items] == ['LIN', 'CIRC', 'LIN', 'PTP']
    assert [it.blend_radius for it in req.items] == [0.03, 0.03, 0.0, 0.0]
    assert req.items[1].centre is not None and req.items[1].interim is None
    assert req.mass is None                       # a DH preset: no inertias
    path = req.plan()
    assert path.notes == ['sequence item 3: PTP kinetic_energy: no mass model (no <inertial> masses), '
                          'planned as the joint line']
    q = path.evaluate(np.array([0.0, 1.0]), 0)[0]
    np.testing.assert_allclose(q[0], req.start_joints, atol=1e-12)
    np.testing.assert_allclose(q[1], req.start_joints, atol=1e-9)     # the PTP goes back


@pytest.mark.parametrize('item,words', [
    ({'motion': 'LIN', 'goal_joints': [0] * 6, 'radius': 0.1}, "unknown keys \\['radius'\\]"),
    ({'motion': 'CIRC', 'goal_joints': [0] * 6, 'center': [0, 0, 'x']}, 'center must be'),
    ({'motion': 'LIN', 'goal_joints': [0] * 5}, 'goal_joints'),
])
def test_bad_items_are_named(item, words) -> None:
    with pytest.raises(RequestError, match=words):
        parse_request({'robot': 'ur5e', 'start_joints': [0.3, -1.2, 1.4, -1.5, -1.4, 0.2], 'sequence': [item]})


def test_a_sequence_replaces_goal() -> None:
    with pytest.raises(RequestError, match='replaces goal'):
        parse_request({'robot': 'ur5e', 'start_joints': [0] * 6, 'goal_joints': [0.1] * 6,
                       'sequence': [{'motion': 'PTP', 'goal_joints': [0.2] * 6}]})


def test_geodesic_plan_writes_the_notes(tmp_path: Path) -> None:
    out = tmp_path / 'seq.json'
    proc = subprocess.run([sys.executable, '-m', 'geodesic_planner.cli.plan', str(EXAMPLE), '--output', str(out)],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    assert 'joint line' in data['notes'][0]
    assert len(data['blend_zones']) == 2
