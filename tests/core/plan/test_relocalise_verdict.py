"""When "find me" states a pose and when it gives only its candidates (``relocalise.verdict``)."""

import pytest

from findme_core.errors import GeometryError
from findme_core.plan.relocalise import FOUND_RATIO, verdict


def test_the_walls_alone_never_state_a_pose_even_a_lone_one():
    for scores in ([100.0], [100.0, 10.0], [100.0, 99.0]):
        for turn in (False, True):
            found, why = verdict(scores, with_photos=False, turn=turn)
            assert not found and "walls alone" in why and "--photos" in why


def test_a_turn_with_the_photos_and_a_clear_best_is_stated():
    assert verdict([300.0, 0.5 * 300.0], with_photos=True, turn=True) == (True, None)
    assert verdict([300.0], with_photos=True, turn=True) == (True, None)


def test_one_photo_gives_candidates_even_with_the_plans_photos():
    found, why = verdict([300.0, 0.5 * 300.0], with_photos=True, turn=False)
    assert not found and "one photo" in why and "all round" in why


def test_a_runner_up_near_the_best_gives_candidates():
    found, why = verdict([300.0, FOUND_RATIO * 300.0], with_photos=True, turn=True)
    assert not found and "80%" in why and "all round" in why


def test_a_best_that_contradicts_the_plan_more_than_it_fits_is_not_stated():
    for scores in ([-28.0, -30.0], [0.0]):
        found, why = verdict(scores, with_photos=True, turn=True)
        assert not found and "contradicts" in why


def test_no_candidate_is_an_error():
    with pytest.raises(GeometryError, match="no candidate"):
        verdict([], with_photos=True, turn=True)
