"""What a motion's line says about the gravities it rests on: an unsure or assumed gravity
is said; once the two photos agreed on gravity through their matches, the gravity the motion
used is said instead (sure: nothing; still unsure: its new sigma); photos that disagree are
said to."""

from __future__ import annotations

import math

import numpy as np
import pytest

import schemas
from findme_core.errors import SchemaError
from findme_core.motion.pair_gravity import PairGravity
from findme_io.convert import gravity_caveat
from findme_io.motion_msg import motion_gravity_text, set_motion_gravity

DEG = math.radians(1.0)


def _msg(pg=None):
    m = schemas.Motion(schema="findme.v1.Motion", session="s", index_a=0, index_b=1, x_m=0.0,
                       z_m=0.0, yaw_rad=0.0)
    set_motion_gravity(m, pg)
    schemas.validate(m)                       # raises SchemaError on a problem
    return m


def _pg(status, angle_deg, sa, sb, reason=None):
    g = np.array([0.0, 1.0, 0.0])
    return PairGravity(g, g, sa, sb, status, math.radians(angle_deg), 300 if angle_deg else 0,
                       reason)


def test_gravity_caveats_name_assumed_and_unsure_gravities_only():
    assert gravity_caveat("photo 1", "level", 10 * DEG) == "photo 1's gravity ASSUMED LEVEL (± 10 deg)"
    assert gravity_caveat("photo 1", "image", 25 * DEG) == \
        "photo 1's gravity from its lines, unsure (± 25 deg)"
    assert gravity_caveat("photo 1", "image", 2 * DEG) is None
    assert gravity_caveat("photo 1", "input", 25 * DEG) is None


def test_without_a_check_the_motion_rests_on_the_unsure_gravity():
    text = motion_gravity_text(_msg(), "photo 0", "photo 1", ("image", 1 * DEG),
                               ("image", 25 * DEG))
    assert text == ("; it rests on photo 1's gravity from its lines, unsure (± 25 deg), which "
                    "its figures allow for only as far as a tilt by that 1-sigma moves the motion")
    level = motion_gravity_text(_msg(), "photo 0", "photo 1", ("image", 1 * DEG),
                                ("level", 10 * DEG))
    assert level == ("; it rests on photo 1's gravity ASSUMED LEVEL (± 10 deg), which its "
                     "figures do not allow for")
    both = motion_gravity_text(_msg(), "photo 0", "photo 1", ("image", 25 * DEG),
                               ("level", 10 * DEG))
    assert both.endswith("which its figures allow for only as far as a tilt by that 1-sigma "
                         "moves the motion (not at all where level is assumed)")
    assert motion_gravity_text(_msg(), "photo 0", "photo 1", None, None) == ""


def test_agreed_photos_are_said_and_rest_on_the_gravity_the_motion_used():
    sure = motion_gravity_text(_msg(_pg("agreed", 21, 1 * DEG, 2.3 * DEG)), "photo 0",
                               "photo 1", ("image", 1 * DEG), ("image", 25 * DEG))
    assert sure == "; photo 0 and photo 1 agreed on gravity through their matches (their own " \
                   "were 21 deg apart)"
    # both photos unsure: combined, still unsure, and said with its new sigma; a photo assumed
    # level took the other's gravity, so it is no longer "assumed level"
    still = motion_gravity_text(_msg(_pg("agreed", 3, 9 * DEG, 9.2 * DEG)), "photo 0",
                                "photo 1", ("image", 12 * DEG), ("level", math.inf))
    assert still == ("; it rests on photo 0's gravity from its lines, unsure (± 9 deg) and "
                     "photo 1's gravity from its lines, unsure (± 9 deg), which its figures "
                     "allow for only as far as a tilt by that 1-sigma moves the motion")


def test_photos_that_disagree_are_said_and_keep_their_caveats():
    m = _msg(_pg("disagree", 20, 1 * DEG, math.inf, "one of them is wrong"))
    assert not m.gravity.HasField("sigma_b_rad")          # assumed level: no sigma to give
    text = motion_gravity_text(m, "photo 0", "photo 1", ("image", 1 * DEG),
                               ("level", 10 * DEG))
    assert text.startswith("; photo 0 and photo 1 DISAGREE on which way is down (one of them "
                           "is wrong); it rests on photo 1's gravity ASSUMED LEVEL")


def test_a_motion_gravity_with_an_unknown_status_or_negative_sigma_is_refused():
    m = _msg(_pg("agreed", 21, 1 * DEG, 2 * DEG))
    m.gravity.status = "maybe"
    m.gravity.sigma_a_rad = -1.0
    with pytest.raises(SchemaError) as e:
        schemas.validate(m)
    assert "gravity.status 'maybe'" in str(e.value) and "gravity.sigma_a_rad" in str(e.value)
