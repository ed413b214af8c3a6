"""``tools/unrelated_pairs.py``: which pairs it makes of photos that share nothing, and how it
calls an answer (the motions themselves come from the product's two-photo path)."""

from __future__ import annotations

import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tools"))
from unrelated_pairs import pairings, room_of, verdict  # noqa: E402

IDS = ["zpl_r01_p14_p15_t0", "zpl_r01_p14_p15_t1", "zpl_r06_p10_p11_t0",
       "zpl_r06_p11_p12_t1", "zpt_r10_p17_p22_t2"]


def test_room_of_reads_the_pair_id_and_refuses_another_kind():
    assert room_of("zpl_r06_p10_p11_t0") == "r06"
    assert room_of("zpt_r17_p7_p8_t2") == "r17"
    with pytest.raises(ValueError, match="tum_cab"):
        room_of("tum_cab_0000_0001")


def test_every_pairing_joins_two_rooms_the_same_way_each_run():
    got = pairings(IDS)
    assert [p for p, _ in got] == IDS
    assert all(room_of(p) != room_of(q) for p, q in got)
    assert got == pairings(list(IDS))
    # the k-th pair takes the (7 k)-th of the other rooms' pairs
    others0 = [q for q in IDS if room_of(q) != "r01"]
    assert got[0] == (IDS[0], others0[0]) and got[1] == (IDS[1], others0[7 % len(others0)])
    # one room only: nothing to pair with
    assert pairings(IDS[:2]) == []


def test_verdicts():
    truth = {"yaw_deg": 10.0}
    assert verdict(None, truth, 10.0) == "refused"
    assert verdict({"yaw_deg": 90.0, "sigma_yaw_deg": 40.0}, truth, 10.0) == "wide"
    assert verdict({"yaw_deg": 12.0, "sigma_yaw_deg": 1.0}, truth, 10.0) == "right"
    assert verdict({"yaw_deg": 14.0, "sigma_yaw_deg": 1.0}, truth, 10.0) == "wrong"
    # the yaw error wraps: 179 against -179 is 2 deg
    assert verdict({"yaw_deg": 179.0, "sigma_yaw_deg": 1.0}, {"yaw_deg": -179.0}, 10.0) == "right"
    assert verdict({"yaw_deg": 12.0, "sigma_yaw_deg": 1.0}, None, 10.0) == "tight"
