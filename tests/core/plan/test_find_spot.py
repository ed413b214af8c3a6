"""Find me from a turn: several photos taken at one new place, found together on a placed
session (``find_spot``) or on a plan's walls (``layout.merged`` + ``relocalise.locate_turn``),
on rooms the project renders, where the exact poses are known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.errors import GeometryError, HypothesisError
from findme_core.motion import register
from findme_core.plan import find_spot, floorplan, fuse, heading, relocalise
from findme_core.single import layout
from findme_core.synth.room import Pose, Room
from tests.core.plan.test_floorplan import H, _layout, _session
from tests.plan_room import first_frame_truth

L_ROOM = Room.l_shape(6.0, 5.0, 2.5, 2.0)
L_SPOTS = [(-1.5, -1.0), (1.2, -1.4)]


def _turn(room, spots_xz, at, yaws, pitch=25.0):
    """(placed layouts, their true poses (N, 3), the turn's layouts, the links between them
    (indices N ..), the turn's true poses (K, 3)); frame: photo 0's level frame."""
    lays, links, lab, truth, _ = _session(room, spots_xz)
    first = Pose(spots_xz[0][0], spots_xz[0][1], H, 0.0, pitch, 0.0)
    new = [Pose(at[0], at[1], H, float(y), pitch, 0.0) for y in yaws]
    t_new, _ = first_frame_truth(room, [first, *new])
    n = len(lays)
    new_links = [fuse.Link(n + k, n + k + 1, math.radians(yaws[k + 1] - yaws[k]), 1e-4)
                 for k in range(len(yaws) - 1)]
    return lays, truth, [_layout(room, p) for p in new], new_links, t_new[1:]


def _near(pose, want, t=0.03, deg=0.5):
    return (np.hypot(*(pose[:2] - want[:2])) < t
            and abs(math.degrees(fuse.wrap(pose[2] - want[2]))) < deg)


def test_a_turn_is_found_exactly_in_an_l_shaped_room():
    lays, truth, new, links, want = _turn(L_ROOM, L_SPOTS, (-1.0, 1.2), (30, 90, 150))
    cands, scores = find_spot.place(lays, truth, new, links)
    assert cands.shape == (len(scores), 3, 3) and np.all(np.diff(scores) <= 0)
    for k in range(3):                 # every photo of the turn, at the best candidate
        assert _near(cands[0, k], want[k]), (cands[0, k], want[k])


def test_a_photo_the_turn_does_not_link_turns_in_place():
    lays, truth, new, links, want = _turn(L_ROOM, L_SPOTS, (-1.0, 1.2), (30, 90, 200))
    cands, _ = find_spot.place(lays, truth, new, links[:1])   # the 3rd photo: no link
    assert _near(cands[0, 2], want[2]), (cands[0, 2], want[2])


def test_a_symmetric_room_gives_the_truth_among_its_candidates():
    room = Room.rectangle(5.0, 4.0)
    lays, truth, new, links, want = _turn(room, [(-0.8, -0.5), (1.0, 0.6)], (0.3, -1.0),
                                          (115, 175))
    cands, scores = find_spot.place(lays, truth, new, links)
    assert len(scores) > 1             # the half-turn twin is an answer too
    assert any(_near(c[0], want[0]) and _near(c[1], want[1]) for c in cands)


def test_the_phones_heading_leaves_the_symmetric_rooms_truth_alone():
    room = Room.rectangle(5.0, 4.0)
    lays, truth, new, links, want = _turn(room, [(-0.8, -0.5), (1.0, 0.6)], (0.3, -1.0),
                                          (115, 175))
    # every photo's heading: its room yaw plus one offset (a compass's north), 20 deg off at
    # most; the half-turn twin turns the new photos 180 deg from what the phone says
    rng = np.random.default_rng(3)
    yaws = np.concatenate([truth[:, 2], want[:, 2]])
    yaws = yaws + 1.1 + rng.uniform(-0.3, 0.3, len(yaws))
    h = heading.table([(y, math.radians(20), "M") for y in yaws])
    cands, scores = find_spot.place(lays, truth, new, links, headings=h)
    assert _near(cands[0, 0], want[0]) and _near(cands[0, 1], want[1]), cands[0]
    assert all(abs(fuse.wrap(c[0, 2] - want[0, 2])) < math.radians(60) for c in cands)
    # the phone read the new photos 45 deg off (a magnet nearby): nothing the walls allow
    # (the room's quarter turns) fits, and it says so rather than pick one
    h = heading.table([(y + (math.pi / 4 if k >= len(truth) else 0.0), math.radians(5), "M")
                       for k, y in enumerate(yaws)])
    with pytest.raises(GeometryError, match="phone's heading"):
        find_spot.place(lays, truth, new, links, headings=h)


def test_degenerate_turns_are_clear_errors():
    lays, truth, new, links, _ = _turn(L_ROOM, L_SPOTS, (-1.0, 1.2), (30, 90))
    with pytest.raises(GeometryError, match="no new photo"):
        find_spot.place(lays, truth, [], [])
    with pytest.raises(GeometryError, match="no layout"):
        find_spot.place(lays, truth, [None, None], links)


def test_turned_layout_is_the_layout_seen_from_the_turned_frame():
    L = _layout(L_ROOM, Pose(-1.0, 1.2, H, 40.0, 25.0, 0.0))
    T = layout.turned(L, 0.7)
    R = register.rot2(np.array([0.7]), L.walls.reshape(-1, 2))[0].reshape(-1, 2, 2)
    np.testing.assert_allclose(T.walls, R, atol=1e-12)
    ok = np.isfinite(L.range)
    np.testing.assert_allclose(np.sort(T.points[np.isfinite(T.range)], 0),
                               np.sort(register.rot2(np.array([0.7]), L.points[ok])[0], 0),
                               atol=1e-9)
    assert np.all(np.diff(T.azimuth) >= 0)
    back = layout.turned(T, -0.7)
    np.testing.assert_allclose(back.walls, L.walls, atol=1e-12)


def test_a_merged_turn_is_located_on_the_plans_walls():
    lays, links, lab, truth, _ = _session(L_ROOM, L_SPOTS)
    plan = floorplan.build(lays, fuse.place(lays, links, lab).poses)
    _, _, new, _, want = _turn(L_ROOM, L_SPOTS, (-1.0, 1.2), (30, 90, 150))
    yaws = [math.radians(y - 30) for y in (30, 90, 150)]
    m = layout.merged(new, yaws)
    assert len(m.walls) == sum(len(x.walls) for x in new)
    _, found = relocalise.locate_turn(plan, new, np.zeros(3, int), np.array(yaws))
    best = np.array([found[0].x, found[0].z, found[0].yaw])
    assert _near(best, want[0], t=0.08, deg=1.5), (best, want[0])


def test_merging_refuses_what_is_not_one_place():
    L = _layout(L_ROOM, Pose(-1.0, 1.2, H, 40.0, 25.0, 0.0))
    with pytest.raises(HypothesisError, match="no layout"):
        layout.merged([], [])
    other = layout.Layout(L.walls, L.ends, L.azimuth, L.range, L.kind, L.sigma, L.wall, H + 0.3)
    with pytest.raises(HypothesisError, match="camera height"):
        layout.merged([L, other], [0.0, 0.5])
