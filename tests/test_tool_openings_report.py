"""``tools/openings_report.py``: its length score against known stretches, and its two rules
on a plan of the closed rendered 5 x 4 m room where one photo's layout runs past a wall: the
rule before (any fan past the wall) says an opening there, the shipped vote does not."""

import sys
from pathlib import Path

import numpy as np
import pytest

from findme_core.plan import floorplan
from tests.core.plan.test_apertures import far_line_session

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import openings_report as orp  # noqa: E402


def test_score_counts_metres_said_and_found_within_a_tenth_of_a_metre():
    truth = [(np.array([0.0, 0.0]), np.array([1.0, 0.0]))]
    said = [(np.array([0.5, 0.05]), np.array([2.0, 0.05]))]   # half on the door, 1 m beside it
    s, ok, t, found = orp.score(said, truth)
    assert s == pytest.approx(1.5) and ok == pytest.approx(0.6, abs=0.03)
    assert t == pytest.approx(1.0) and found == pytest.approx(0.6, abs=0.03)
    assert orp.score([], truth) == (0.0, 0.0, 1.0, 0.0)


def test_the_two_rules_on_a_closed_room_with_one_far_line():
    lays, links, lab, pl = far_line_session()
    plan = floorplan.build(lays, pl.poses, spot=lab, links=links)
    said = orp.openings(plan, lays)
    assert said["now"] == [] and said["fans only"]
