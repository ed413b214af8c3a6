"""``room_view.judge`` on rendered scenes with exact truth: photos that are not a room view
(taken from above, an object filling the view, a plain wall, a boundary below the photo)
are refused with the reason; room views pass."""

from __future__ import annotations

import numpy as np
import pytest

from findme_core.single.hypotheses import Hypothesis, HypothesisSet
from findme_core.single.lines import Lines
from findme_core.single.methods import hypothesize
from findme_core.single.room_view import judge
from findme_core.single.search import SegKind
from findme_core.synth.render import Box, Pose, Room, render

H = 1.4   # camera height, metres


def _judge(view):
    hs = hypothesize(view.image, view.camera, camera_height=view.camera_height)
    return hs, judge(hs, view.camera, view.camera_height)


def test_a_top_down_photo_of_a_textured_floor_is_not_a_room_view():
    """The phone looks straight down at a wood floor (its gravity given, as the page's
    motion sensors send it): hypotheses follow the floorboards, but the photo is refused."""
    hs, v = _judge(render(Room.rectangle(6, 6), Pose(0, 0, H, 20, 88, 0)))
    assert hs.hypotheses, "the floorboards give confident-looking boundaries"
    assert not v.ok and v.reason.startswith("the camera looks 88° down: a photo taken from "
                                            "above shows no walls")


def test_an_object_filling_the_view_is_not_a_room_view():
    """A plain box 0.6 m in front of the phone, taller than it, tilted down 50 deg: only a
    strip of floor under it; the boundary is real, the room is not in the photo."""
    room = Room.rectangle(6, 6, boxes=(Box(0, 0.9, 2.6, 0.6, 1.8),))
    hs, v = _judge(render(room, Pose(0, 0, H, 0, 50, 0)))
    assert hs.hypotheses and not v.ok, v
    assert v.reason.startswith("something fills the view: the floor ends 0.8 m from the "
                               "camera all across the photo")
    assert v.cues["median_h"] < 0.7 and v.cues["farthest_h"] < 1.0


def test_a_plain_wall_is_not_a_room_view():
    """Level, 0.85 m from a plain painted wall (no poster, no baseboard in view)."""
    hs, v = _judge(render(Room.rectangle(1.3, 3.0), Pose(0, 0.65, H, 0, 0, 0)))
    assert not hs.hypotheses
    assert not v.ok and v.reason == ("no floor-wall boundary found (no straight lines found "
                                     "in the image)")


@pytest.mark.parametrize("rows,kind,why", [
    ((553.0, 553.0), SegKind.WALL, "its best boundary lies below the photo"),
    ((476.0, 477.0), SegKind.WALL, "the photo shows almost no floor under its best boundary"),
    ((477.0, 477.0), SegKind.NONE, "no floor is in the photo"),
])
def test_a_boundary_with_no_floor_under_it_is_not_a_room_view(rows, kind, why):
    """The issue's circuit board: a confident "wall" whose boundary lies below the 477 px
    photo (v = 553); also one hugging its bottom edge, and an explicit no-floor one."""
    from findme_core.geometry.camera import Camera
    cam = Camera.from_hfov(65.0, 640, 477)
    hyp = Hypothesis(np.array([[0.0, rows[0]], [639.0, rows[1]]]), np.array([kind]), 0.965)
    lines = Lines(np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0))
    v = judge(HypothesisSet(640, 477, [hyp], lines, np.zeros(0, int)), cam)
    assert not v.ok and v.reason.startswith(f"no floor-wall boundary in view: {why}")


@pytest.mark.parametrize("pose", [Pose(-0.5, -1.2, H, 10, 25, 2), Pose(-0.5, -1.2, H, 10, 0, 0),
                                  Pose(0.3, 0.2, H, 130, 35, -3)])
def test_room_views_pass(pose):
    room = Room.rectangle(5, 4, boxes=(Box(1.2, 1.2, 1.0, 0.5, 0.9),))
    hs, v = _judge(render(room, pose))
    assert hs.hypotheses and v.ok and v.reason is None, v
