"""``tools/rendered_sessions.py``: what it calls a confidently wrong pose, and the sessions it
renders (the plans themselves come from the mapper's handler)."""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tools"))
from rendered_sessions import LAYOUTS, ROOMS, TURNS, confident_wrong  # noqa: E402


def test_a_pose_is_confidently_wrong_when_the_truth_is_beyond_3_sigma_on_any_axis():
    sig = (0.1, 0.1, math.radians(1))
    assert not confident_wrong((1.0, 2.0, 0.5), sig, (1.0, 2.0, 0.5))
    assert not confident_wrong((1.0, 2.0, 0.5), sig, (1.3, 2.0, 0.5))      # 3 sigma
    assert confident_wrong((1.0, 2.0, 0.5), sig, (1.35, 2.0, 0.5))         # x: 3.5 sigma
    assert confident_wrong((1.0, 2.0, 0.5), sig, (1.0, 1.6, 0.5))          # z
    assert confident_wrong((1.0, 2.0, 0.5), sig, (1.0, 2.0, 0.5 + math.radians(4)))
    # the yaw error wraps: +179 deg against -179 deg is 2 deg
    assert not confident_wrong((0, 0, math.radians(179)), sig, (0, 0, math.radians(-179)))
    # a wide sigma covers a half turn
    assert not confident_wrong((0, 0, 0), (0.1, 0.1, math.radians(61)), (0, 0, math.pi))


def test_the_sessions_cover_overlapping_sparse_and_split_turns():
    assert {room for room, _ in LAYOUTS} == set(ROOMS)
    steps = sorted({t[1] for t in TURNS})
    assert steps == [50, 55, 60, 65, 70] and (0, 50, 180, 230) in TURNS
    for t in TURNS:   # a turn never comes round onto its first photo
        assert max(t) < 360 and len(set(t)) == len(t)
