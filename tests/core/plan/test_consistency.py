"""A plan that leaves a camera outside its outline is refused with the reason; one whose
cameras stand inside passes."""

from __future__ import annotations

import numpy as np

from findme_core.plan import consistency
from findme_core.plan.floorplan import Plan

SQUARE = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]])


def _plan(poses) -> Plan:
    return Plan(SQUARE, (), 12.0, np.asarray(poses, float), True)


def test_cameras_inside_the_outline_pass():
    plan = _plan([[1.0, 1.0, 0.0], [3.0, 2.0, 0.5], [np.nan, np.nan, np.nan]])
    d = consistency.camera_depths(plan.polygon, plan.poses)
    assert np.allclose(d[:2], [1.0, 1.0]) and np.isnan(d[2])
    assert consistency.check(plan) is None


def test_a_camera_outside_refuses_the_plan_and_names_it():
    plan = _plan([[1.0, 1.0, 0.0], [5.2, 1.5, 0.0], [4.1, 1.5, 0.0]])
    why = consistency.check(plan, names=["a.jpg", "b.jpg", "c.jpg"])
    # b is 1.2 m outside; c is 0.1 m outside, within a pose's uncertainty
    assert why and "1 camera(s) outside" in why and "b.jpg's by 1.20 m" in why


def test_a_degenerate_outline_has_no_depths():
    d = consistency.camera_depths(np.zeros((2, 2)), np.zeros((1, 3)))
    assert np.isnan(d).all()
