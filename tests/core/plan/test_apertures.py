"""Doors and openings of a wall (``apertures``): floor seen beyond the wall against its base
seen standing, one vote per photo; and in a whole plan of a closed rendered room, one photo
whose layout took a far line for the wall's base (its floor fan runs metres past a wall its
neighbours saw) opens no wall."""

import numpy as np
import pytest

from findme_core.plan import apertures, floorplan, fuse
from findme_core.single import layout
from findme_core.single.search import SegKind
from findme_core.synth.render import _boundary_polyline, _camera
from findme_core.synth.room import Pose, Room
from tests.core.plan.test_floorplan import H, _session

A, B = np.array([0.0, 0.0]), np.array([5.0, 0.0])   # outward normal (0, -1): beyond is z < 0


def _fan(x0, x1, depth=1.0, cam=(2.5, 2.0)):
    """A floor fan from a camera inside the room reaching ``depth`` m past the wall over
    x0..x1."""
    return np.array([cam, (x0, -depth), (x1, -depth)])


def _base(x0, x1, z=0.0, step=0.05):
    x = np.arange(x0, x1 + 1e-9, step)
    return np.column_stack([x, np.full(len(x), z)]), np.full(len(x), step)


def test_floor_seen_beyond_and_no_base_is_an_opening():
    (got,) = apertures.stretches(A, B, [_fan(1.5, 3.0)])
    # the fan's ray to the wall's outside at 0.25 m, spreading from the camera at (2.5, 2)
    assert got[0] == pytest.approx(1.75, abs=0.06) and got[1] == pytest.approx(2.875, abs=0.06)


def test_a_short_wall_or_a_short_stretch_has_none():
    assert apertures.stretches(A, np.array([0.4, 0.0]), [_fan(0.0, 0.4)]) == ()
    assert apertures.stretches(A, B, [_fan(2.0, 2.3)]) == ()


def test_the_base_seen_by_more_photos_keeps_the_wall():
    fan = [_fan(1.5, 3.0)]
    pts, ln = _base(0.0, 5.0)
    two = np.concatenate([pts, pts]), np.concatenate([ln, ln])
    who = np.repeat([1, 2], len(pts))
    assert apertures.stretches(A, B, fan, [0], *two, who) == ()
    # one against one: each photo one vote, and a tie leaves the opening
    (got,) = apertures.stretches(A, B, fan, [0], pts, ln, np.ones(len(pts), int))
    assert got[0] == pytest.approx(1.75, abs=0.06)
    # two photos seeing the floor go on against one base: the opening stands
    assert apertures.stretches(A, B, [_fan(1.5, 3.0), _fan(1.5, 3.0, cam=(2.0, 1.5))], [0, 3],
                               *two, who)
    # one photo's several fans are one vote
    assert apertures.stretches(A, B, fan * 3, [0, 0, 0], *two, who) == ()


def test_only_a_base_on_the_walls_line_counts():
    fan = [_fan(1.5, 3.0)]
    front, ln = _base(0.0, 5.0, z=0.5)          # a cabinet's face 0.5 m in front of the wall
    who = np.repeat([1, 2], len(front))
    assert apertures.stretches(A, B, fan, [0], np.concatenate([front, front]),
                               np.concatenate([ln, ln]), who)
    on = apertures.base_seen(A, B, np.array([1.0, 2.0, 4.0]), *_base(0.9, 2.1))
    assert on.tolist() == [True, True, False]
    assert not apertures.base_seen(A, B, np.array([1.0]), np.zeros((0, 2))).any()


def far_line_session():
    """The rendered 5 x 4 m room's session (exact layouts) with photo 3's boundary drawn
    110 px too high, metres past its wall (as a photo whose top hypothesis is a far line,
    e.g. a poster's lower edge on the wall ahead, gets): (layouts, links, spot labels,
    placement)."""
    room = Room.rectangle(5.0, 4.0)
    lays, links, lab, _, _ = _session(room, [(-0.8, -0.5), (1.0, 0.6)])
    pl = fuse.place(lays, links, lab)
    pose = Pose(-0.8, -0.5, H, 150.0, 25.0, 0.0)     # photo 3 of the first spot
    cam = _camera(640, 480, 70.0, None, pose.gravity_cam)
    poly = _boundary_polyline(room, pose, cam)
    poly = poly[np.isfinite(poly[:, 1])] - [0.0, 110.0]
    wrong = layout.from_hypothesis(cam, H, poly, np.full(len(poly) - 1, SegKind.WALL))
    assert np.nanmedian(wrong.range) > np.nanmedian(lays[3].range) + 1.0
    return lays[:3] + [wrong] + lays[4:], links, lab, pl


def test_a_far_line_in_one_photo_opens_no_wall_of_a_closed_room():
    """``far_line_session``: the plan's walls stand as its other photos saw them, with no
    opening, though the wrong photo's floor runs metres past one of them."""
    lays, links, lab, pl = far_line_session()
    fan = apertures.fans(lays[3], pl.poses[3])
    plan = floorplan.build(lays, pl.poses, spot=lab, links=links)
    assert plan.closed and len(plan.walls) == 4

    def past(w, q):                                   # metres outside the wall a -> b
        u = (w.b - w.a) / w.length_m
        return (q - w.a) @ np.array([u[1], -u[0]])
    assert max(past(w, q) for w in plan.walls for f in fan for q in f) > 1.0
    assert all(w.apertures == () for w in plan.walls), [w.apertures for w in plan.walls]


def test_session_fans_name_their_photo_and_skip_the_unplaced():
    lays, _, _, pl = far_line_session()
    poses = pl.poses.copy()
    poses[1] = np.nan                                  # photo 1 not placed
    fans, who = apertures.session_fans([None] + lays[1:], poses)
    assert len(fans) == len(who) and set(who) == set(range(2, len(lays)))
    one = apertures.fans(lays[5], poses[5])
    np.testing.assert_allclose(np.concatenate([fans[k] for k in np.flatnonzero(who == 5)]),
                               np.concatenate(one))
