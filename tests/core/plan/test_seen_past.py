"""Outline walls the photos saw past (findme_core/plan/seen_past.py, consistency.check).

Exact geometry: a 4 x 3 m outline whose right wall stands 0.6 m in front of the wall the
photos saw; and a rendered 5 x 4 m room whose photos carry their exact boundaries, one of them
cut across a corner (the boundary search's joining of two walls by one line)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from findme_core.plan import consistency, floorplan, polygon, seen_past, walls
from findme_core.plan.floorplan import Plan
from findme_core.single import layout
from findme_core.single.search import SegKind
from findme_core.synth.render import _boundary_polyline, _camera
from findme_core.synth.room import Pose, Room
from tests.core.plan.test_floorplan import H, _match_polygon, _session

SQUARE = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]])    # counter-clockwise
Z = np.arange(0.2, 2.81, 0.05)                                        # along the right wall


def _wall(x, z=Z):
    return np.column_stack([np.full(len(z), x), z])


def test_a_wall_seen_past_is_measured_along_it_in_either_orientation():
    pts = _wall(4.6)                             # the room's wall, 0.6 m behind the outline's
    cams = np.tile([1.0, 1.5], (len(pts), 1))
    length, which = seen_past.seen_through(SQUARE, pts, cams)
    assert length[1] == pytest.approx(2.7) and list(which[1]) == list(range(len(pts)))
    assert length[[0, 2, 3]].tolist() == [0.0, 0.0, 0.0]
    cw, _ = seen_past.seen_through(SQUARE[::-1], pts, cams)
    assert sorted(cw) == sorted(length)


@pytest.mark.parametrize("x", [4.2, 5.5])
def test_the_wall_itself_and_another_room_behind_a_door_are_not_seen_past(x):
    # 0.2 m behind: the outline's own wall (dents thinner than 0.3 m are smoothed away);
    # 1.5 m behind: another room's wall, seen through an opening
    length, _ = seen_past.seen_through(SQUARE, _wall(x), np.tile([1.0, 1.5], (len(Z), 1)))
    assert not length.any()


def test_only_rays_from_the_room_through_the_wall_count():
    pts = _wall(4.6)
    outside = np.tile([5.0, 1.5], (len(pts), 1))        # a camera beyond the wall
    assert not seen_past.seen_through(SQUARE, pts, outside)[0].any()
    # samples behind the right wall's line beyond its end (z 3.2-4): not behind that wall
    beyond = _wall(4.6, np.arange(3.2, 4.01, 0.05))
    length, _ = seen_past.seen_through(SQUARE, beyond, np.tile([3.5, 2.5], (len(beyond), 1)))
    assert not length[1]


@pytest.mark.parametrize("verts", [SQUARE[:2], np.array([[0.0, 0], [1, 0], [2, 0]]),
                                   np.zeros((0, 2))])
def test_degenerate_outlines_see_nothing_past(verts):
    length, which = seen_past.seen_through(verts, _wall(4.6), np.tile([1.0, 1.5], (len(Z), 1)))
    assert length.shape == (len(verts),) and not length.any() and len(which) == len(verts)


def test_no_samples_and_a_repeated_vertex():
    verts = np.vstack([SQUARE[:2], SQUARE[1:]])        # wall 1 has no length
    assert not seen_past.seen_through(verts, np.zeros((0, 2)), np.zeros((0, 2)))[0].any()
    length, _ = seen_past.seen_through(verts, _wall(4.6), np.tile([1.0, 1.5], (len(Z), 1)))
    assert length[1] == 0.0 and length[2] == pytest.approx(2.7)


def _evidence(groups):
    """walls.Evidence of (points (S, 2), photo) groups; photo p stands at CAMS[p]."""
    pts = np.vstack([g[0] for g in groups])
    photo = np.concatenate([np.full(len(g[0]), g[1]) for g in groups])
    n = len(pts)
    return walls.Evidence(pts, np.full(n, 0.02), np.full(n, 0.05), np.tile([0.0, 1.0], (n, 1)),
                          photo, CAMS, np.zeros((0, 2, 2)), np.zeros(0, int))


CAMS = np.array([[1.0, 1.5], [2.0, 1.0], [3.0, 2.0], [3.2, 1.2]])
SPOT = np.array([0, 0, 1, 1])


def _lines(ev, line_of_sample):
    """WallLines: 0 the outline's right wall x = 4, 1 x = 0, 2 z = 0, 3 z = 3."""
    N = np.array([[1.0, 0], [-1, 0], [0, -1], [0, 1]])
    D = np.array([4.0, 0, 0, 3])
    return walls.WallLines(N, D, np.tile([-1.0, 5.0], (4, 1)), np.full(4, 3.0),
                           np.full(4, 2), np.full(4, "wall", object), line_of_sample, None)


def _outline(wl):
    return polygon.Outline(SQUARE, np.array([2, 0, 3, 1]), np.ones(4, bool),
                           polygon.Lines.of(wl))


def _case(right_wall_photos):
    """The outline's right wall (x = 4) seen by ``right_wall_photos``; photos 0 and 1
    (spot 0) saw the room's wall 0.6 m behind it."""
    groups = [(_wall(4.0), p) for p in right_wall_photos] + [(_wall(4.6), 0), (_wall(4.6), 1)]
    ev = _evidence(groups)
    line = np.concatenate([np.full(len(Z), 0)] * len(right_wall_photos)
                          + [np.full(2 * len(Z), -1)])
    return ev, _lines(ev, line)


def test_a_line_one_spot_saw_that_another_spot_saw_past_is_dropped():
    ev, wl = _case([2, 3])                      # both photos of spot 1
    assert seen_past.dropped(_outline(wl), ev, wl, SPOT).tolist() == [0]


def test_a_line_two_spots_saw_is_kept_and_the_plan_refused():
    ev, wl = _case([2, 0])                      # spot 1 and spot 0 saw it
    assert not len(seen_past.dropped(_outline(wl), ev, wl, SPOT))
    plan = Plan(SQUARE, (), 12.0, np.column_stack([CAMS, np.zeros(4)]), True)
    why = consistency.check(plan, evidence=ev, names=["a", "b", "c", "d"])
    assert why and "2 photo(s) (a, b) saw past it" in why and "along 2.7 m of its 3.0 m" in why
    assert consistency.check(plan) is None        # without the evidence: cameras only
    short = _evidence([(_wall(4.6, np.arange(0.2, 1.5, 0.05)), 0)])
    assert consistency.check(plan, evidence=short) is None      # 1.3 m: a door's width


def test_a_line_only_its_own_spot_saw_past_is_kept():
    ev, wl = _case([2])
    spot = np.array([1, 1, 1, 1])                # the photos that saw past are of its spot
    assert not len(seen_past.dropped(_outline(wl), ev, wl, spot))


def _corner_cut(room, spot_xz, yaw):
    """The layout of a photo whose boundary joins the two walls of the corner it sees by
    one straight line (150 px either side of the corner's image), as the boundary search
    does when the corner is faint."""
    pose = Pose(spot_xz[0], spot_xz[1], H, yaw, 25.0, 0.0)
    cam = _camera(640, 480, 70.0, None, pose.gravity_cam)
    pl = _boundary_polyline(room, pose, cam)
    pl = pl[np.isfinite(pl[:, 1])]
    c = 1 + int(np.argmin(pl[1:-1, 1]))        # the corner: the farthest inner vertex
    u = np.clip([pl[c, 0] - 150, pl[c, 0] + 150], 0, 639)
    ends = np.column_stack([u, np.interp(u, pl[:, 0], pl[:, 1])])
    cut = np.vstack([pl[pl[:, 0] < u[0]], ends, pl[pl[:, 0] > u[1]]])
    return layout.from_hypothesis(cam, H, cut, np.full(len(cut) - 1, SegKind.WALL))


@pytest.mark.parametrize("j", [9, 11, 12, 13, 14])
def test_a_corner_one_photo_cut_off_is_given_back(j):
    room, spots = Room.rectangle(5.0, 4.0), [(-0.8, -0.5), (1.0, 0.6)]
    lays, _, lab, truth, poly = _session(room, spots, yaws=range(0, 360, 50))
    first = lab.index(1)
    lays = list(lays)
    lays[j] = _corner_cut(room, spots[1], (j - first) * 50 + 7.0)
    keep = replace(floorplan.PlanParams(), seen_past=seen_past.SeenPastParams(max_redraws=0))
    cut = floorplan.build(lays, np.array(truth), keep, spot=np.array(lab), refine=False)
    assert len(cut.polygon) == 5                # without redrawing: the corner is cut off
    plan = floorplan.build(lays, np.array(truth), spot=np.array(lab), refine=False)
    _match_polygon(plan.polygon, poly, 0.04)
    assert abs(plan.area_m2 - 20.0) < 0.1 and cut.area_m2 < 19.8
