"""A placement the photos cannot decide is not stated as one pose: a photo that sees walls in
one direction only, with no features shared with the placed photos, stays unplaced
(``evidence.wall_directions``, ``evidence.linked``), and a block the search could turn to
another heading nearly as well gets a 1-sigma that covers it (``evidence.alike``,
``pose.spread``). Rendered rooms, exact boundaries: the answers are known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.plan import evidence, floorplan, fuse, pose as plan_pose
from findme_core.synth.room import Pose, Room
from tests.core.plan.test_floorplan import H, _layout, _session
from tests.plan_room import first_frame_truth

RECT = Room.rectangle(5.0, 4.0)
SPOTS = [(-0.8, -0.5), (1.0, 0.6)]


def _skipping_turn(yaws=(0, 50, 180, 330)):
    """Layouts of two spots turning with left-out views: the 180 deg photo overlaps neither
    neighbour (no rotation link), so its yaw rests on its layout alone."""
    poses = [Pose(x, z, H, float(y) + 7.0 * s, 28.0, 0.0)
             for s, (x, z) in enumerate(SPOTS) for y in yaws]
    lays = [_layout(RECT, p) for p in poses]

    def link(i, j):
        return fuse.Link(i, j, math.radians(poses[j].yaw_deg - poses[i].yaw_deg), 1e-4)
    links = [link(0, 1), link(0, 3), link(4, 5), link(4, 7)]
    truth, _ = first_frame_truth(RECT, poses)
    return lays, links, [0] * 4 + [1] * 4, truth


def _walls(*segments):
    """A stand-in layout with just these wall segments ((x0, z0, x1, z1), ...)."""
    class L:
        walls = np.array(segments, float).reshape(-1, 2, 2)
    return L()


def test_wall_directions_count_parallel_walls_once_in_the_blocks_frame():
    one, corner = _walls((-1, 2, 1, 2)), _walls((-1, 2, 1, 2), (1, 2, 1, 0))
    corridor = _walls((-1, 1, -1, 3), (1, 1, 1, 3))
    assert evidence.wall_directions([one], [0.0], [0]) == 1
    assert evidence.wall_directions([corner], [0.0], [0]) == 2
    assert evidence.wall_directions([corridor], [0.0], [0]) == 1
    assert evidence.wall_directions([_walls()], [0.0], [0]) == 0
    # two photos of one wall each: parallel or perpendicular once turned by their rel yaw
    assert evidence.wall_directions([one, one], [0.0, math.pi / 2], [0, 1]) == 2
    assert evidence.wall_directions([one, one], [0.0, math.pi], [0, 1]) == 1
    # within 30 deg of parallel (a wall's run split by noise) is one direction
    assert evidence.wall_directions([_walls((-1, 2, 0, 2), (0, 2, 1, 2.3))], [0.0], [0]) == 1


def test_linked_means_matches_or_a_motion_with_a_placed_photo():
    mo = fuse.Link(2, 5, 0.1, 0.01, (1.0, 0.0))
    assert evidence.linked({(1, 5): None}, (), [5], [0, 1])
    assert evidence.linked({}, [mo], [5], [2])
    assert not evidence.linked({(1, 5): None}, [mo], [5], [0, 3])   # 1, 2 not placed
    assert not evidence.linked(None, (), [5], [0, 1])


def test_a_photo_of_one_wall_with_nothing_else_is_left_unplaced_with_the_reason():
    lays, links, lab, truth = _skipping_turn()
    pl = fuse.place(lays, links, lab)
    assert evidence.wall_directions(lays, pl.rel_yaw, [2]) == 1
    assert np.all(np.isnan(pl.poses[2]))
    assert "walls in one direction only" in pl.reasons[pl.block[2]]
    # every other photo where it was (photo 6 sees a corner: placed by it)
    others = [0, 1, 3, 4, 5, 7]
    assert np.abs(pl.poses[others, :2] - truth[others, :2]).max() < 0.01
    assert np.abs(fuse.wrap(pl.poses[others, 2] - truth[others, 2])).max() < math.radians(0.5)


def test_a_feature_link_lets_a_photo_of_one_wall_be_placed():
    lays, links, lab, truth = _skipping_turn()
    ty, tt = fuse.relative(truth[0], truth[2])     # a true motion 0 -> 2 (placed first)
    pl = fuse.place(lays, links, lab, motions=[fuse.Link(0, 2, ty, 0.01, tuple(tt))])
    assert pl.reasons[pl.block[2]] is None
    assert abs(fuse.wrap(pl.poses[2, 2] - truth[2, 2])) < math.radians(1.0)


def test_the_half_turn_twin_of_a_symmetric_room_widens_the_spots_sigma_to_cover_it():
    # a 5 x 4 m room looks the same turned half round its centre: spot 1 at its twin
    # (x, z mirrored through the centre, turned 180 deg) scores 0.99 of the truth
    lays, links, lab, truth, _ = _session(RECT, SPOTS)
    pl = fuse.place(lays, links, lab)
    (d, r), = pl.alternatives[pl.block[8]]
    assert abs(abs(d[2]) - math.pi) < math.radians(1) and 0.9 < r <= 1.0
    # spot 1 at (1.8, 1.1) from spot 0, the room's centre at (0.8, 0.5): its twin at
    # 2 x (0.8, 0.5) - (1.8, 1.1) = (-0.2, -0.1), an offset of (-2.0, -1.2)
    twin = np.array([-2.0, -1.2])
    np.testing.assert_allclose(d[:2], twin, atol=0.1)
    assert not pl.alternatives[0]
    spread = np.array([plan_pose.spread(pl.alternatives[b]) for b in pl.block])
    plan = floorplan.build(lays, pl.poses, spot=pl.spot, links=links, spread=spread)
    s = plan.pose_sigma
    assert np.all(s[:8, 2] < math.radians(1.0))              # spot 0: no doubt
    # spot 1: the twin lies within 2 sigma of the stated pose, in yaw and in position
    assert np.all(math.pi <= 2 * s[8:, 2])
    assert np.all(np.hypot(*twin) <= 2 * np.hypot(s[8:, 0], s[8:, 1]))
    # the outline is the same room either way
    np.testing.assert_allclose(plan.area_m2, 20.0, rtol=0.01)


def test_alike_keeps_turned_final_states_by_the_blocks_share_of_the_shortfall():
    block = np.array([0, 1, 1])
    p0 = np.array([[0, 0, 0], [1, 0, 0.1], [1, 0, 0.6]], float)
    turned = p0.copy()
    turned[1:, 2] += math.pi / 2
    moved = p0.copy()
    moved[1:, 0] += 0.5                                   # not turned: not an alternative
    out = evidence.alike([100.0, 95.0, 99.0], [p0, turned, moved], [0.0, 50.0], block, 0.8)
    assert out[0] == ()
    (d, r), = out[1]
    np.testing.assert_allclose(d, [0, 0, math.pi / 2])
    assert r == pytest.approx((50 - 5) / 50)
    # a later block that disagrees with the turn more: below the share, dropped
    assert evidence.alike([100.0, 85.0], [p0, turned], [0.0, 50.0], block, 0.8) == [(), ()]
    # unplaced in the other state: nothing to compare
    gone = p0.copy()
    gone[1:] = np.nan
    assert evidence.alike([100.0, 99.0], [p0, gone], [0.0, 50.0], block, 0.8) == [(), ()]


def test_spread_is_the_mixtures_spread_about_the_chosen_pose():
    np.testing.assert_array_equal(plan_pose.spread(()), np.zeros(3))
    d = np.array([2.0, -1.0, math.pi])
    # ratio 1: an even mixture, sqrt(0.5) x the offset
    np.testing.assert_allclose(plan_pose.spread(((d, 1.0),)), np.abs(d) * math.sqrt(0.5))
    # a ratio above 1 (the search kept a pose this block alone scored lower) counts as 1
    np.testing.assert_allclose(plan_pose.spread(((d, 1.3),)), np.abs(d) * math.sqrt(0.5))
    # two alternatives, weights 1 : 0.9 : 0.8
    e = np.array([0.0, 0.5, -math.pi / 2])
    want = np.sqrt((0.9 * d ** 2 + 0.8 * e ** 2) / 2.7)
    np.testing.assert_allclose(plan_pose.spread(((d, 0.9), (e, 0.8))), want)


def test_a_spot_whose_first_photo_is_left_out_is_refined_from_its_placed_photos():
    # a block left out may hold a spot's first photo; the refinement then starts the spot
    # from a placed photo of it (it took the first one's NaN position: least_squares raised)
    lays, links, lab, truth, poly = _session(RECT, SPOTS)
    poses = truth.copy()
    poses[8] = np.nan
    plan = floorplan.build(lays, poses, spot=np.array(lab), links=links)
    assert np.all(np.isfinite(plan.pose_sigma[9:]))
    np.testing.assert_allclose(plan.poses[9:, :2], truth[9:, :2], atol=0.01)
    assert np.all(np.isnan(plan.poses[8]))
