"""The pure parts of delivery, driven directly: per-session round-robin queues and their
bounds, how long a message may wait (a burst vs a standing queue), bounded expiring session
state, the store's window and listing, the output cache's listing, and rendezvous sharding."""

import threading

import pytest

import schemas
from services.runtime import inbox as inbox_mod
from services.runtime.cache import CacheServer, OutputCache
from services.runtime.handler import Handler, Input
from services.runtime.inbox import Inbox
from services.runtime.intake import Intake, Item
from services.runtime.peers import owner
from services.runtime.sessions import SessionTable
from services.runtime.store import StoreHandler


def item(session, n, size=10, i=0):
    return Item(i, f"findme/{session}/frame/{n}", b"x" * size, session)


def test_sessions_are_served_round_robin():
    q = Intake(session_depth=8)
    for n in range(4):
        assert q.offer(item("a", n))[0]
    assert q.offer(item("b", 0))[0]
    order = [(x.session, x.key.rsplit("/", 1)[1]) for x in iter(q.pop, None)]
    assert order == [("a", "0"), ("b", "0"), ("a", "1"), ("a", "2"), ("a", "3")]
    assert len(q) == 0 and q.nbytes == 0 and q.sessions == 0


def test_a_full_session_is_refused_and_says_why_others_still_fit():
    q = Intake(session_depth=2, session_bytes=100, total_bytes=250)
    assert q.offer(item("a", 0))[0] and q.offer(item("a", 1))[0]
    ok, _, why = q.offer(item("a", 2))
    assert not ok and "'a' already has 2 messages waiting" in why
    assert q.offer(item("b", 0, size=150))[0]           # alone, larger than a session's bytes
    ok, _, why = q.offer(item("b", 1, size=20))
    assert not ok and "MB waiting (at most" in why       # but not beside another
    ok, _, why = q.offer(item("c", 0, size=90))
    assert not ok and "in all sessions" in why           # nor over the total


def test_latest_pushes_out_the_oldest_of_its_kind_only():
    q = Intake(session_depth=8)
    q.offer(item("a", 0, i=1))                           # another input of the session
    for n in range(3):
        ok, gone, _ = q.offer(item("a", 10 + n), latest=2)
        assert ok
    assert [g.key for g in gone] == ["findme/a/frame/10"]
    assert [x.key for x in iter(q.pop, None)] == ["findme/a/frame/0", "findme/a/frame/11",
                                                  "findme/a/frame/12"]


class _Clock:
    t = 100.0

    def __call__(self):
        return self.t


class _FirstStage(Handler):
    name = "first"
    inputs = (Input("findme/*/frame/*", schemas.Frame),)
    fresh_wait_s, standing_s = 1.0, 5.0


def _taken(box, clock, at):
    clock.t = at
    with box.cv:
        got = box.take()
    return None if got is None else got.key.rsplit("/", 1)[1]


@pytest.mark.parametrize("fresh", [True, False])
def test_a_standing_queue_serves_fresh_messages_and_refuses_old_ones_at_once(monkeypatch,
                                                                           fresh):
    clock = _Clock()
    monkeypatch.setattr(inbox_mod.time, "monotonic", clock)
    h = _FirstStage()
    if not fresh:
        h.fresh_wait_s = None          # the default: only max_wait_s
    box = Inbox(h, "first/x", session_depth=64, max_wait_s=10.0)
    for n in range(4):                 # a burst at t = 100
        assert box.offer(0, f"findme/a/frame/{n}", b"")
    assert _taken(box, clock, 103.0) == "0"     # waited 3 s: a burst, under 10 s
    clock.t = 105.5
    assert box.offer(0, "findme/a/frame/4", b"")
    # the queue has not emptied since t = 100: at 106 it stands (6 s > 5 s); the photos
    # that waited 6 s are refused at once, the one that waited 0.5 s is served
    assert _taken(box, clock, 106.0) == ("4" if fresh else "1")
    if fresh:
        assert box.more["shed"] == 3 and "expired" not in box.more
        key, err = box.reports[0]
        assert key == "findme/a/frame/1" and type(err).__name__ == "Overloaded"
        assert "waited 6.0 s in first's queue, which has not emptied for 6 s" in str(err)
        assert "(at most 1 s)" in str(err)
    # t = 106: the queue emptied (fresh) or still holds 2, 3, 4; a new burst at 107
    for n in range(5, 7):
        clock.t = 107.0
        box.offer(0, f"findme/a/frame/{n}", b"")
    if fresh:                          # emptied at 106: a burst again, 3 s of waiting is fine
        assert _taken(box, clock, 110.0) == "5"
    else:                              # > max_wait_s is refused with or without
        assert _taken(box, clock, 116.5) == "5" and box.more["expired"] == 3
        assert not box.more.get("shed")


def test_session_table_expires_idle_sessions_and_keeps_at_most_max():
    now = [0.0]
    made = []
    t = SessionTable(lambda s: made.append(s) or {"s": s}, idle_s=10, max_sessions=2,
                     clock=lambda: now[0])
    t.get("a"), t.get("b")
    now[0] = 5
    t.get("a")                                  # used again: b is the least recent
    t.get("c")                                  # over max: b goes
    assert "b" not in t and "a" in t and t.evicted == 1
    now[0] = 8
    t.get("a")
    now[0] = 16
    assert t.expire() == ["c"] and t.expire() == []      # idle 11 s > 10: c goes, a stays
    assert t.get("b") == {"s": "b"} and made == ["a", "b", "c", "b"]   # rebuilt when back
    with pytest.raises(ValueError):
        SessionTable(dict, idle_s=0)


class Params(dict):
    def get(self, k, default=None):
        return super().get(k, default)


def test_store_holds_a_window_latches_small_state_and_lists():
    now = [1_000_000_000_000]
    st = StoreHandler(window_s=60, latch_s=900, latch_bytes=100, clock=lambda: now[0])
    st.on_message("findme/s/frame/0", b"F" * 500)
    st.on_message("findme/s/hypotheses/0", b"H")
    st.on_message("findme/s/error", b"E1")
    st.on_message("findme/s/error", b"E2")              # every Error kept
    st.on_message("findme/s/hypotheses/0", b"H2")       # latest per key
    assert st.cached("findme/s/frame/0", None) == [("findme/s/frame/0", b"F" * 500)]
    assert [p for _, p in st.cached("findme/s/error", None)] == [b"E1", b"E2"]
    assert [p for _, p in st.cached("findme/*/hypotheses/*", None)] == [b"H2"]
    listing = st.cached("findme/s/**", Params(meta=""))
    assert sorted(k for k, _ in listing) == ["findme/s/error", "findme/s/error", "findme/s/frame/0",
                                            "findme/s/hypotheses/0"]
    assert all(p.split()[0] == str(now[0]).encode() for _, p in listing)
    assert st.cached("findme/s/**", Params(since=str(now[0] + 1))) == []
    now[0] += 61_000_000_000                             # past the window
    assert st.cached("findme/s/frame/0", None) == []    # frames are not latched
    assert st.cached("findme/s/hypotheses/0", None) == [("findme/s/hypotheses/0", b"H2")]
    assert st.cached("findme/s/error", None) == []
    now[0] += 900_000_000_000
    assert st.cached("findme/s/**", None) == []


def test_output_cache_lists_with_times_and_keeps_its_bytes_bound():
    now = [5]
    c = OutputCache(max_bytes=10, clock=lambda: now[0])
    c.put("findme/s/pose/0", b"aaaa")
    now[0] = 6
    c.put("findme/s/pose/1", b"bbbb")
    assert c.lookup("findme/s/pose/*", Params(meta="")) == [("findme/s/pose/0", b"5 4"),
                                                           ("findme/s/pose/1", b"6 4")]
    assert c.lookup("findme/s/pose/*", Params(since="6")) == [("findme/s/pose/1", b"bbbb")]
    c.put("findme/s/pose/2", b"cccc")                    # 12 bytes > 10: the oldest goes
    assert c.get("findme/s/pose/0") is None and len(c) == 2


def test_rendezvous_moves_only_the_work_of_the_instance_that_left():
    keys = [f"findme/s{i}/frame/{j}" for i in range(20) for j in range(10)]
    three = {k: owner(k, {"a", "b", "c"}) for k in keys}
    two = {k: owner(k, {"a", "b"}) for k in keys}
    assert set(three.values()) == {"a", "b", "c"}
    assert all(two[k] == three[k] for k in keys if three[k] != "c")   # a's and b's stay
    assert owner("x", ["a"]) == "a"


def test_output_cache_forgets_what_is_older_than_its_age():
    now = [0]
    c = OutputCache(max_age_s=10, clock=lambda: now[0])
    c.put("findme/s/pose/0", b"a")
    now[0] = 11_000_000_000
    c.put("findme/s/pose/1", b"b")
    assert c.get("findme/s/pose/0") is None and c.get("findme/s/pose/1") == b"b"


class _Query:
    """A stand-in for zenoh.Query: its key expression, its replies, whether it was closed."""

    def __init__(self, key):
        self.key_expr, self.parameters, self.replies, self.dropped = key, {}, [], False

    def reply(self, key, payload):
        self.replies.append((key, payload))

    def drop(self):
        self.dropped = True


def test_cache_scans_waiting_are_bounded_and_counted():
    """Wildcard queries wait for the scan thread; beyond ``max_scans`` one is closed at once
    with no reply from this service and counted, while exact keys are still answered in the
    callback and the waiting scans are answered when the thread runs."""
    cache = OutputCache()
    cache.put("findme/s/scene/0", b"x")
    server = CacheServer(cache, Handler(), "t", max_scans=2)
    scans = [_Query("findme/s/**") for _ in range(3)]
    for q in scans:
        server.on_query(q)
    assert [q.dropped for q in scans] == [False, False, True] and server.refused == 1
    exact = _Query("findme/s/scene/0")
    server.on_query(exact)
    assert exact.replies == [("findme/s/scene/0", b"x")] and exact.dropped
    stop = threading.Event()
    t = threading.Thread(target=server.run, args=(stop,))
    t.start()
    stop.set()
    server.wake()
    t.join(10)
    assert all(q.replies == [("findme/s/scene/0", b"x")] and q.dropped for q in scans[:2])
