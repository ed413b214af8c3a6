"""1-sigma of a photo's pose on a plan (plan_pose), on rooms the project renders."""

import math

import numpy as np

from findme_core.single import layout
from findme_core.plan import pose as plan_pose
from findme_core.synth.room import Pose, Room
from test_floorplan import H, _layout, _plan   # rendered-room helpers (same folder)


def test_pose_sigma_of_an_exact_plan_is_small_and_finite():
    plan, pl, truth, _ = _plan(Room.rectangle(5.0, 4.0), [(-0.8, -0.5), (1.0, 0.6)])
    lays, *_ = _session_layouts()
    sig = []
    for L, p in zip(lays, pl.poses):
        C = plan_pose.covariance(plan, L, p)
        if C is None:
            continue
        assert np.allclose(C, C.T) and np.all(np.linalg.eigvalsh(C) > 0)
        sig.append(np.sqrt(np.diag(C)))
    assert len(sig) >= len(lays) // 2          # most photos see two non-parallel walls
    sig = np.array(sig)
    assert np.all(sig[:, :2] < 0.1) and np.all(sig[:, 2] < math.radians(3)), sig
    assert np.all(sig[:, :2] > 0.0005)         # the floor keeps it honest: never zero


def test_a_wrong_pose_has_larger_sigma_and_one_wall_pins_nothing():
    plan, pl, _, _ = _plan(Room.rectangle(5.0, 4.0), [(-0.8, -0.5), (1.0, 0.6)])
    lays, *_ = _session_layouts()
    k = next(i for i, L in enumerate(lays) if plan_pose.covariance(plan, L, pl.poses[i]) is not None)
    good = np.sqrt(np.diag(plan_pose.covariance(plan, lays[k], pl.poses[k])))
    off = pl.poses[k] + np.array([0.06, -0.04, math.radians(1.0)])
    bad = plan_pose.covariance(plan, lays[k], off)
    assert bad is not None and np.sqrt(bad[2, 2]) > good[2]   # the residuals grew
    # a photo close to one wall, looking straight at it: only parallel constraints (room
    # (0, 1.2) is plan (0.8, 1.7): the plan's frame is photo 0's, at room (-0.8, -0.5), yaw 0)
    L = _layout(Room.rectangle(5.0, 4.0), Pose(0.0, 1.2, H, 0.0, 35.0, 0.0), hfov=30.0)
    assert len(L.walls) == 1
    assert plan_pose.covariance(plan, L, np.array([0.8, 1.7, 0.0])) is None


def test_degenerate_inputs_give_none():
    plan, pl, _, _ = _plan(Room.rectangle(5.0, 4.0), [(-0.8, -0.5)])
    empty = layout.Layout(np.zeros((0, 2, 2)), np.zeros((0, 2), int), np.zeros(0), np.zeros(0),
                          np.zeros(0, int), np.zeros(0), np.zeros(0, int), H)
    assert plan_pose.covariance(plan, empty, pl.poses[0]) is None
    assert plan_pose.covariance(plan, None, pl.poses[0]) is None
    lays, *_ = _session_layouts()
    assert plan_pose.covariance(plan, lays[0], np.full(3, np.nan)) is None


def _session_layouts():
    from test_floorplan import _session
    return _session(Room.rectangle(5.0, 4.0), [(-0.8, -0.5), (1.0, 0.6)])

