"""Which lower photos a selected photo waits for (``odometry_session.blockers``): pure, no
images. A photo waits only for a lower one that could still become its anchor."""

from types import SimpleNamespace

from findme_core.motion.trajectory import PlanarPose
from services.pipeline.odometry_session import LOOK_BACK, OdometrySession

SELECTED = SimpleNamespace(rank=1)


def _selected(st, *ns):
    for n in ns:
        st.photo(n, 0.0).selection = SELECTED


def test_an_unheard_number_between_the_first_photo_and_n_is_waited_for():
    st = OdometrySession()
    st.adopt({0: PlanarPose(0.0, 0.0, 0.0, 0.0)}, {})
    _selected(st, 3)
    st.photo(1, 0.0)                   # its hypotheses came, no selection yet
    assert st.blockers(3) == [1, 2]    # 1 open; 2 not heard of: in flight


def test_before_the_origin_every_lower_number_is_waited_for():
    """A session's photos are numbered from 0: photo 2's hypotheses came first (another
    worker), photos 0 and 1 are in flight. Photo 0, not 2, becomes the origin."""
    st = OdometrySession()
    _selected(st, 2)
    assert st.blockers(2) == [0, 1]
    _selected(st, 0)
    assert st.blockers(0) == []


def test_an_unheard_number_below_the_nearest_posed_photo_is_not_waited_for():
    """After a restart, photos 0 and 5 are posed on the bus; 1-4 (failed before it) are not
    heard of. Photo 7 chains from 5 whatever they do: it waits for 6 only."""
    st = OdometrySession()
    st.adopt({0: PlanarPose(0.0, 0.0, 0.0, 0.0), 5: PlanarPose(1.0, 0.0, 0.0, 0.0)}, {})
    _selected(st, 7)
    assert st.blockers(7) == [6]


def test_resolved_numbers_are_not_waited_for():
    st = OdometrySession()
    st.adopt({0: PlanarPose(0.0, 0.0, 0.0, 0.0)}, {})
    st.close(1, "dead")                # refused upstream: never selected
    st.close(2, "failed")              # its motion failed
    _selected(st, 3, 4)                # 3 selected, not posed yet: 4 does not wait for it
    assert st.blockers(4) == []


def test_a_hostile_photo_number_waits_for_at_most_look_back_numbers():
    st = OdometrySession()
    st.adopt({0: PlanarPose(0.0, 0.0, 0.0, 0.0)}, {})
    n = 10 ** 12
    _selected(st, n)
    assert st.blockers(n) == list(range(n - LOOK_BACK, n))
