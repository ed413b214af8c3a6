"""Tests of findme_core.motion.alternatives: the distinct best candidates, the rival turned
away and whether the photos prefer the answer to it, the motions at another distance along the answer's baseline (``along``) and the
mixture's spread over them (``spread_over``), on candidate sets whose answer is known."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from findme_core.errors import MotionError
from findme_core.motion.alternatives import (along, as_scored, distinct, distinct_top,
                                             looks_more_alike, more_agree, rival, same,
                                             spread_over, turned, turns)
from findme_core.motion.model import PlanarMotion

BEST = PlanarMotion(x=0.6, z=0.8, yaw=math.radians(20.0), dy=0.0, sigma_x=0.03, sigma_z=0.04,
                    sigma_yaw=math.radians(0.5), inliers=np.ones(10, bool), n_scale=5,
                    method="findme", score=50.0)
BEST_DIR = math.degrees(math.atan2(0.6, 0.8))   # 36.87 deg from +z; the baseline is 1.0 m


def candidates(*rows):
    """(yaw (C,) rad, t (C, 3) m) from rows (yaw deg, direction deg from +z towards +x,
    baseline m)."""
    r = np.array(rows, float)
    d = np.radians(r[:, 1])
    return np.radians(r[:, 0]), np.column_stack([r[:, 2] * np.sin(d), np.zeros(len(r)),
                                                 r[:, 2] * np.cos(d)])


def kept(cy, ct, found):
    """The motions ``along`` found, as the estimator keeps them (no matches of their own)."""
    none = np.zeros(10, bool)
    return tuple(as_scored(BEST, cy[i], ct[i], share, none, none, none, None)
                 for i, share in found)


def lengths(found, ct):
    return [round(math.hypot(ct[i, 0], ct[i, 2]), 2) for i, _ in found]


def evidence_of(lengths, values):
    """An ``evidence(yaw, t)`` that sees only the baseline's length: piecewise linear through
    (lengths, values); the answer's 1.0 m must be among them."""
    def evidence(yaw, t):
        assert len(yaw) == len(t)
        return np.interp(np.hypot(t[:, 0], t[:, 2]), lengths, values)
    return evidence


# the answer's distance scores 10, twice as far 7 (a wall taken 1 m behind the true one)
TWO = evidence_of([0.0, 1.0, 1.5, 2.0, 3.0, 9.0], [0.0, 10.0, 2.0, 7.0, 0.0, 0.0])


def test_a_second_distance_along_the_baseline_is_an_alternative():
    cy, ct = candidates((20.0, BEST_DIR, 1.0), (20.5, BEST_DIR + 1.0, 2.0),
                        (20.0, BEST_DIR, 1.02))
    (o,) = kept(cy, ct, along(BEST, (), cy, ct, TWO, 0.5, 3))
    assert math.hypot(o.x, o.z) == pytest.approx(2.0)
    assert o.yaw == pytest.approx(math.radians(20.5))
    # the answer's relative sigmas at the new distance; its evidence's share of the score
    assert o.sigma_x == pytest.approx(2.0 * BEST.sigma_x)
    assert o.sigma_z == pytest.approx(2.0 * BEST.sigma_z)
    assert o.score == pytest.approx(0.7 * BEST.score) and o.alternatives == ()
    # its own evidence, not the answer's
    assert o.n_inliers == 0 and o.n_scale == 0 and o.layout is None
    assert o.appearance[1] == 0


def test_only_candidates_at_the_answers_yaw_and_direction_with_enough_evidence():
    cy, ct = candidates((20.0, BEST_DIR, 1.0),
                        (20.0, BEST_DIR, 1.5),           # evidence 2 of 10: too little
                        (24.0, BEST_DIR, 2.0),           # turned 4 deg
                        (20.0, BEST_DIR + 4.0, 2.0),     # another direction
                        (20.0, BEST_DIR + 180.0, 2.0))   # the way back
    assert along(BEST, (), cy, ct, TWO, 0.5, 3) == []
    found = along(BEST, (), cy, ct, TWO, 0.2, 3)
    assert lengths(found, ct) == [1.5] and found[0][1] == pytest.approx(0.2)


def test_distances_alike_count_once_and_at_most_k():
    flat = evidence_of([0.0, 1.0, 4.0], [10.0, 10.0, 7.0])   # every distance alike
    cy, ct = candidates((20.0, BEST_DIR, 1.0), (20.0, BEST_DIR, 1.5), (20.0, BEST_DIR, 1.52),
                        (20.0, BEST_DIR, 2.5), (20.0, BEST_DIR, 0.5), (20.0, BEST_DIR, 3.5))
    out = along(BEST, (), cy, ct, flat, 0.5, 3)
    assert lengths(out, ct) == [0.5, 1.5, 2.5]
    # one already among the answer's alternatives is not added again
    again = along(BEST, kept(cy, ct, out[:1]), cy, ct, flat, 0.5, 3)
    assert lengths(again, ct) == [1.5, 2.5, 3.5]


def test_without_evidence_of_the_distance_nothing_is_added():
    cy, ct = candidates((20.0, BEST_DIR, 1.0), (20.0, BEST_DIR, 2.0))
    none = evidence_of([0.0, 9.0], [0.0, 0.0])   # the matches alone: every distance scores 0
    assert along(BEST, (), cy, ct, none, 0.3, 3) == []
    # nothing near: the answer keeps its sigmas
    far, _ = candidates((60.0, BEST_DIR, 2.0))
    assert along(BEST, (), far, ct[1:], TWO, 0.3, 3) == []
    assert spread_over(BEST) is BEST


def test_the_spread_over_another_distance_lies_along_the_baseline():
    even = evidence_of([0.0, 1.0, 1.5, 2.0, 3.0], [0.0, 10.0, 0.0, 10.0, 0.0])
    cy, ct = candidates((20.0, BEST_DIR, 1.0), (20.0, BEST_DIR, 2.0))
    alts = kept(cy, ct, along(BEST, (), cy, ct, even, 0.3, 3))
    m = spread_over(replace(BEST, alternatives=alts))
    # two distances with equal evidence: half the weight 1 m further along (0.6, 0.8)
    assert m.sigma_x == pytest.approx(math.sqrt(0.03 ** 2 + 0.5 * 0.6 ** 2))
    assert m.sigma_z == pytest.approx(math.sqrt(0.04 ** 2 + 0.5 * 0.8 ** 2))
    assert m.sigma_yaw == pytest.approx(BEST.sigma_yaw)
    # the truth twice as far lies within 2 sigma on both axes
    assert abs(1.2 - m.x) / m.sigma_x < 2.0 and abs(1.6 - m.z) / m.sigma_z < 2.0


def test_an_alternative_turned_a_quarter_turn_widens_the_direction_of_travel():
    # a symmetric room: the same walls fit photo B turned 90 deg, B at the same place; the
    # truth (B 1.0 m away at 0 deg, turned 20 deg) is the answer's position turned by 36.87 deg
    other = replace(BEST, yaw=BEST.yaw + math.pi / 2, score=45.0)
    m = spread_over(replace(BEST, alternatives=(other,)))
    s = math.sqrt(45.0 / 95.0) * math.pi / 2          # the alternatives' spread in yaw
    assert m.sigma_yaw == pytest.approx(math.hypot(BEST.sigma_yaw, s))
    sx, sz = turned(0.6, 0.8, s)
    assert m.sigma_x == pytest.approx(math.hypot(0.03, sx))
    assert m.sigma_z == pytest.approx(math.hypot(0.04, sz))
    # without the turn's share the truth is 20 and 5 sigma off on x and z; with it, within 1
    assert abs(0.0 - m.x) / m.sigma_x < 1.0 and abs(1.0 - m.z) / m.sigma_z < 1.0
    assert abs(0.0 - m.x) / math.hypot(0.03, 0.0) > 10.0


def test_turned_spread_of_a_position():
    # nothing turned, or nothing to turn: no spread
    assert turned(0.6, 0.8, 0.0) == (0.0, 0.0)
    assert turned(0.0, 0.0, 1.0) == (0.0, 0.0)
    # forward 2 m turned +-90 deg: +-2 m sideways, 2 m back; a half turn counts as a quarter
    assert turned(0.0, 2.0, math.pi / 2) == pytest.approx((2.0, 2.0))
    assert turned(0.0, 2.0, math.pi) == pytest.approx((2.0, 2.0))
    # small turns: sideways s * z, along (s^2 / 2) * z; either sign alike
    assert turned(0.0, 2.0, 0.01) == pytest.approx((0.02, 1e-4), rel=1e-3)
    assert turned(0.0, 2.0, -0.01) == turned(0.0, 2.0, 0.01)


def test_same_motion():
    assert same(0.0, (0.0, 1.0), np.radians(2.9), (0.0, 1.19))
    assert not same(0.0, (0.0, 1.0), np.radians(3.1), (0.0, 1.0))
    assert not same(0.0, (0.0, 1.0), 0.0, (0.0, 1.21))        # 0.1 m + 10 % of 1 m
    assert same(np.radians(179.0), (0.0, 0.0), np.radians(-179.0), (0.05, 0.0))


def test_rival_and_distinct_top():
    cy = np.radians([0.0, 1.0, 90.0, 180.0])
    ct = np.array([[0, 0, 1.0], [0, 0, 1.0], [1.0, 0, 0], [0, 0, -1.0]])
    total = np.array([10.0, 9.0, 8.0, 8.0])
    assert rival(cy, total, 0.0, math.radians(30.0)) == 2     # a tie: the first
    assert rival(cy[:2], total[:2], 0.0, math.radians(30.0)) is None
    dup = np.vstack([ct, ct[:1]])
    assert list(distinct_top(np.r_[cy, cy[0]], dup, np.r_[total, 10.0], 3)) == [0, 1, 2]


@pytest.mark.parametrize("n_best,n_other,preferred", [
    (11, 8, False),    # zpl_r06_p10_p11_t1: 3 apart, the standard error 4.4
    (19, 18, False),   # one match apart decides nothing
    (8, 8, False), (0, 0, False),
    (30, 12, True),    # 18 apart > sqrt(42) = 6.5
    (100, 60, True),
    (8, 11, False),    # the other has more
])
def test_counts_within_their_standard_error_do_not_prefer_a_motion(n_best, n_other, preferred):
    assert more_agree(n_best, n_other) is preferred


def test_counts_exactly_one_standard_error_apart_are_not_more():
    """10 against 6: 4 apart, sqrt(16) = 4, exactly (integers and one square root: the same
    on every machine); 10 against 5 are more."""
    assert not more_agree(10, 6) and more_agree(10, 5)


@pytest.mark.parametrize("best,other,preferred", [
    ((0.05, 533), (0.03, 1582), False),   # 0.02 apart, standard error 0.05
    ((0.40, 4000), (0.02, 4000), True),   # 0.38 apart, standard error 0.022
    ((0.02, 4000), (0.40, 4000), False),  # the other looks more alike
    ((0.10, 0), (0.00, 900), True),       # nothing seen by the answer: the layouts decide
    ((0.10, 900), (0.00, 0), True),
])
def test_the_appearance_prefers_a_motion_beyond_its_standard_error(best, other, preferred):
    assert looks_more_alike(best, other) is preferred


def test_distinct_keeps_the_first_of_each_motion_and_answers_the_first_determined():
    twin = replace(BEST, x=0.62, sigma_x=5.6, score=49.0)            # the same motion
    turned = replace(BEST, yaw=BEST.yaw + math.pi / 2, score=40.0)   # another one
    assert distinct([BEST, twin, turned], [None, None, None]) == ([0, 2], 0)
    why = MotionError("not fixed")
    assert distinct([BEST, turned], [why, None]) == ([0, 1], 1)     # the next one answers


def test_a_determined_refinement_replaces_its_undetermined_twin():
    """Two refinements of one motion: the first (best scored) weighed one lifted point and
    states its scale at +-13 m, which the evidence does not fix; the second, the same
    motion at +-0.03 m, answers, and the motion is not lost to the next distinct one."""
    loose = replace(BEST, sigma_x=5.6, sigma_z=13.1, score=108.9)
    tight = replace(BEST, x=0.61, score=108.7)
    turned = replace(BEST, yaw=BEST.yaw + math.pi, score=60.0)
    why = MotionError("the best motion puts them 1.00 apart at +-14.21")
    assert distinct([loose, tight, turned], [why, None, None]) == ([1, 2], 0)
    # an undetermined twin never replaces a determined one
    assert distinct([tight, loose, turned], [None, why, None]) == ([0, 2], 0)


def test_distinct_refuses_with_the_best_motions_reason():
    first, second = MotionError("first"), MotionError("second")
    turned = replace(BEST, yaw=BEST.yaw + math.pi / 2)
    with pytest.raises(MotionError, match="first"):
        distinct([BEST, turned], [first, second])


def test_turns_gives_each_turn_once_best_first():
    # the answer at 0 deg; a half turn (and a copy of it 2 deg on), two quarter turns, a
    # candidate near the answer: each turn once, best-scoring first, at most k
    cy = np.radians([0.0, 180.0, 90.0, 178.0, -90.0, 2.0])
    total = np.array([10.0, 9.0, 8.0, 8.5, 7.0, 9.5])
    sep = math.radians(45.0)
    assert turns(cy, total, 0.0, sep) == [1, 2, 4]
    assert turns(cy, total, 0.0, sep, k=1) == [1] == [rival(cy, total, 0.0, sep)]
    assert turns(cy[[0, 5]], total[[0, 5]], 0.0, sep) == []
