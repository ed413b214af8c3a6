"""Gravity from the image knows when it does not know: frames that explain a photo's lines
nearly as well are kept as alternatives and widen its 1-sigma, on rendered rooms whose
floorboards pose as walls, and never a tight wrong tilt."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.geometry.manhattan import gravity_of
from findme_core.single import gravity_alternatives as alt
from findme_core.single.photo import hypothesize_without_gravity
from findme_core.single.vanishing import estimate_gravity
from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room


def test_distinct_keeps_strong_frames_far_from_the_best_and_from_each_other():
    best = gravity_of(30.0, 0.0)
    others = [(gravity_of(31.0, 0.5), 0.99),        # the same frame, 1 deg away: not distinct
              (gravity_of(-20.0, 0.0), 0.97),       # 50 deg away, nearly as strong
              (gravity_of(-19.0, 0.5), 0.96),       # a copy of the one before
              (gravity_of(10.0, 30.0), 0.5)]        # far, but weak
    got = alt.distinct(best, 1.0, others, ratio=0.85, distinct_deg=5.0)
    assert len(got) == 1 and alt.angle_deg(got[0][0], gravity_of(-20.0, 0.0)) < 1e-6
    assert got[0][1] == pytest.approx(0.97)
    assert alt.distinct(best, 0.0, others, 0.85, 5.0) == ()       # no score: nothing to say


def test_widen_covers_the_alternative_and_leaves_a_lone_estimate_alone():
    g, cov = gravity_of(30.0, 0.0), np.eye(2) * math.radians(0.4) ** 2
    assert alt.widen(g, cov, ()) is not None and np.array_equal(alt.widen(g, cov, ()), cov)
    a = gravity_of(-20.0, 0.0)
    wide = alt.widen(g, cov, ((a, 1.0),))
    # two equally strong frames 50 deg apart: the answer is off by 0 or 50 deg, each half
    # the time, an RMS error of 50 / sqrt(2) about the answer
    assert math.degrees(math.sqrt(wide[0, 0])) == pytest.approx(50 / math.sqrt(2), abs=0.3)
    assert math.degrees(math.sqrt(wide[1, 1])) == pytest.approx(0.4, abs=0.01)
    assert "50 deg away" in alt.describe(g, ((a, 0.98),))


def _turn(room, yaw, pitch=30.0):
    pose = Pose(0.3, -0.2, 1.4, yaw, pitch, 0.0)
    v = render(room, pose, 640, 480, hfov_deg=70.0, supersample=1)
    return v, Camera(v.camera.fx, v.camera.fy, v.camera.cx, v.camera.cy, 640, 480)


@pytest.fixture(scope="module")
def floorboard_turn():
    """Eight photos turning at one spot of a 5 x 4 m room with a wood floor: its boards are
    the strongest lines of every photo, and fit many frames."""
    room = Room.rectangle(5.0, 4.0)
    return [_turn(room, float(y)) for y in range(0, 360, 45)]


def test_floorboards_never_give_a_tight_wrong_gravity(floorboard_turn):
    wrong = 0
    for view, cam in floorboard_turn:
        est = estimate_gravity(view.image, cam)
        err = alt.angle_deg(est.vector, view.camera.gravity)
        if est.source == "level":
            assert err <= 3 * math.degrees(est.sigma), est.reason
            continue
        wrong += err > 5.0
        # within 3 sigma whatever the frame found (Mahalanobis, in the tilt's covariance):
        # a wrong frame comes with its alternatives
        d = alt.tilt_offset(est.vector, view.camera.gravity)
        assert math.sqrt(d @ np.linalg.solve(est.cov, d)) <= 3.0, (err, est.cov, est.reason)
        if err > 5.0:
            assert est.alternatives and "ambiguous" in est.reason
    assert wrong >= 2          # the scene is hard: several photos find the boards' frame


def test_the_floor_lines_settle_what_the_boards_left_open(floorboard_turn):
    """With the boundary known, the boards lie on the floor: a photo whose first estimate was
    right but ambiguous ends unambiguous (its alternatives came from the boards)."""
    settled = 0
    for view, cam in floorboard_turn:
        first = estimate_gravity(view.image, cam)
        if not first.alternatives or alt.angle_deg(first.vector, view.camera.gravity) > 2.0:
            continue
        _, est = hypothesize_without_gravity(view.image, cam)
        assert alt.angle_deg(est.vector, view.camera.gravity) < 2.0
        settled += not est.alternatives and math.degrees(est.sigma) < 2.0
    assert settled >= 1


def test_a_blank_wall_says_level_assumed_with_its_reason():
    img = np.full((480, 640, 3), 180, np.uint8)
    img = cv2.GaussianBlur((img + np.random.default_rng(0).normal(0, 2, img.shape)).clip(0, 255)
                           .astype(np.uint8), (5, 5), 0)
    est = estimate_gravity(img, Camera.from_hfov(65.0, 640, 480))
    assert est.source == "level" and "level assumed" in est.reason
    assert math.degrees(est.sigma) >= 10.0 and not est.alternatives


@pytest.mark.parametrize("families", [(0, 30, 0), (0, 30, 2)],
                         ids=["one horizontal direction", "one direction and a stray line"])
def test_one_horizontal_direction_and_no_vertical_is_never_tight_and_wrong(families):
    """Lines of one horizontal direction (floorboards, a shelf's edges) and no vertical one:
    any frame that keeps them horizontal fits; the estimate says level with its reason, or
    its 1-sigma covers the error."""
    from findme_core.single.segments import Segments
    from tests.core.geometry.test_manhattan import CAM, manhattan_lines, true_frame
    R = true_frame(pitch_deg=25.0, roll_deg=3.0)
    segs, _ = manhattan_lines(R, n_per_dir=families, seed=4)
    seg = Segments(segs.astype(float), CAM.width, CAM.height, 1.0)
    est = estimate_gravity(np.zeros((CAM.height, CAM.width, 3), np.uint8), CAM, segments=seg)
    err = alt.angle_deg(est.vector, R[:, 1])
    assert est.source == "level" or err <= 3 * math.degrees(est.sigma), (est.source, err,
                                                                           est.reason)
    assert est.reason
