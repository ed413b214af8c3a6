"""Services on an in-process Zenoh session: errors on the error key, no crash, flow control,
status, liveliness, the output cache and sharding. Waits on messages, never sleeps."""

import threading

import pytest
import zenoh

import schemas
from findme_core.errors import BusError
from services.pipeline.hypotheses import HypothesesHandler
from services.pipeline.measurement import MeasurementHandler
from services.pipeline.odometry import OdometryHandler
from services.runtime.handler import Handler, Input, Output
from services.runtime.service import Group, Service
from services.pipeline.selection import SelectionHandler
from tests.services.conftest import Collector, frame_of

GOOD_SELECTION = schemas.Selection(session="t1", index=0, rank=1, by=schemas.SELECTED_BY_USER)


@pytest.mark.parametrize("handler,key,good", [
    ("hypotheses", "findme/t1/frame/0", "frame"),
    ("selection", "findme/t1/hypotheses/0", "hset"),
    ("measurement", "findme/t1/selection/0", "selection"),
    ("odometry", "findme/t1/selection/0", "selection"),
])
def test_malformed_then_good(handler, key, good, zsession, level_view):
    """Garbage, a wrong type and a valid message in the wrong place each give an Error on
    findme/t1/error; the service then still answers a good message."""
    group = Group(zsession)
    frame = frame_of(level_view)
    (hs,) = HypothesesHandler().on_message("findme/t1/frame/0", frame)
    cache = {"findme/t1/frame/0": schemas.encode(frame), "findme/t1/hypotheses/0": schemas.encode(hs.msg)}
    h = {"hypotheses": HypothesesHandler, "selection": SelectionHandler,
         "measurement": MeasurementHandler, "odometry": OdometryHandler}[handler]()
    svc = group.add(h)
    h.fetch = cache.get
    errors = Collector(zsession, "findme/t1/error")
    outs = Collector(zsession, {"hypotheses": "findme/t1/hypotheses/*",
                                "selection": "findme/t1/selection/*",
                                "measurement": "findme/t1/scene/*",
                                "odometry": "findme/t1/pose/*"}[handler])
    zsession.put(key, b"\x00garbage")
    zsession.put(key, schemas.encode(schemas.Error(session="t1", key="k", code=1, message="m")))
    wrong_place = {"frame": frame_of(level_view, index=5), "hset": schemas.HypothesisSet(
        session="t1", index=0, width=640, height=480, reason="none"),
        "selection": schemas.Selection(session="t1", index=0, rank=42,
                                       by=schemas.SELECTED_BY_USER)}[good]
    zsession.put(key, schemas.encode(wrong_place))
    errs = [schemas.decode(schemas.Error, p) for _, p in errors.wait(3)]
    codes = sorted(e.code for e in errs)       # (hypotheses handles 2 at once: any order)
    assert schemas.ErrorCode.ERROR_CODE_WRONG_TYPE in codes
    assert codes.count(schemas.ErrorCode.ERROR_CODE_MALFORMED) >= 1
    assert all(e.key == key and e.session == "t1" and e.message for e in errs)
    good_msg = {"frame": frame, "hset": hs.msg, "selection": GOOD_SELECTION}[good]
    zsession.put(key, schemas.encode(good_msg))
    assert len(outs.wait(1)) == 1
    assert svc.status().errors == 3
    group.stop()


class Gate(Handler):
    """Test handler: blocks on an event, counts what it handled."""

    name = "gate"

    def __init__(self, policy="all", depth=1, shard=False):
        self.inputs = (Input("t/in/*", schemas.Selection, policy, depth),)
        self.shard = shard
        self.release = threading.Event()
        self.handled = []

    def on_message(self, key, msg):
        self.release.wait(30)
        self.handled.append(key)
        return [Output(key.replace("t/in", "t/out"), msg)]


def test_latest_policy_counts_every_drop(zsession):
    g = Gate("latest", depth=1)
    svc = Service(g, zsession).start()
    outs = Collector(zsession, "t/out/*")
    for i in range(6):
        zsession.put(f"t/in/{i}", schemas.encode(GOOD_SELECTION))
    with svc._cv:  # all six arrived (counted on arrival)
        assert svc._cv.wait_for(lambda: svc.counters.frames_in == 6, 10)
    g.release.set()
    handled = len(outs.wait(1))
    assert svc.wait_idle(10)
    st = svc.status()
    assert st.dropped >= 4 and len(g.handled) + st.dropped == 6   # nothing vanishes uncounted
    assert handled >= 1
    svc.stop()


def test_all_policy_never_drops_silently(zsession):
    """A session's full queue answers OVERLOADED for each message it cannot take (never
    blocking the sender, never silent); with room, all are handled and none dropped."""
    g = Gate("all")
    svc = Service(g, zsession, fifo_depth=2).start()
    outs = Collector(zsession, "t/out/*")
    errors = Collector(zsession, "findme/@errors")
    for i in range(40):
        zsession.put(f"t/in/{i}", schemas.encode(GOOD_SELECTION))
    with svc._cv:
        assert svc._cv.wait_for(lambda: svc.counters.frames_in == 40, 10)
    st = svc.status()
    errs = [schemas.decode(schemas.Error, p) for _, p in errors.wait(st.dropped)]
    g.release.set()
    handled = outs.wait(40 - st.dropped)
    assert svc.wait_idle(10)
    assert 0 < st.dropped <= 38 and len(handled) + st.dropped == 40
    assert {e.code for e in errs} == {schemas.ErrorCode.ERROR_CODE_OVERLOADED}
    assert {e.key for e in errs}.isdisjoint(k.replace("t/out", "t/in") for k, _ in handled)
    assert svc.status().counters["overloaded"] == st.dropped
    svc.stop()
    roomy = Gate("all")
    roomy.release.set()
    svc = Service(roomy, zsession, fifo_depth=64).start()
    outs = Collector(zsession, "t/out/*")
    for i in range(40):
        zsession.put(f"t/in/x{i}", schemas.encode(GOOD_SELECTION))
    assert len(outs.wait(40)) >= 40 and svc.status().dropped == 0
    svc.stop()


def test_size_limit_refuses_loudly(zsession):
    svc = Service(Gate(), zsession, max_message_bytes=100).start()
    big = schemas.Frame(session="t1", index=0)
    big.image.data = b"\xff\xd8\xff" + b"0" * 1000
    big.image.format = "jpeg"
    with pytest.raises(BusError, match="over the 0 MB limit"):
        svc.publish(Output("findme/t1/frame/0", big))
    svc.stop()


def test_status_liveliness_and_cache(zsession):
    g = Gate()
    g.cache_keys = ("t/out/*",)
    g.release.set()
    svc = Service(g, zsession, instance="abc").start()
    tokens = [str(r.ok.key_expr) for r in zsession.liveliness().get("findme/@services/**", timeout=2)]
    assert tokens == ["findme/@services/gate/abc"]
    outs = Collector(zsession, "t/out/*")
    zsession.put("t/in/1", schemas.encode(GOOD_SELECTION))
    outs.wait(1)
    cached = [r.ok.payload.to_bytes() for r in zsession.get("t/out/1", timeout=2) if r.ok]
    assert schemas.decode(schemas.Selection, cached[0]).rank == 1
    (st,) = [schemas.decode(schemas.ServiceStatus, r.ok.payload.to_bytes())
             for r in zsession.get("findme/@services/gate/abc/status", timeout=2) if r.ok]
    assert (st.service, st.instance, st.frames_in, st.results_out) == ("gate", "abc", 1, 1)
    gone = threading.Event()
    sub = zsession.liveliness().declare_subscriber(
        "findme/@services/gate/*", lambda s: s.kind == zenoh.SampleKind.DELETE and gone.set())
    svc.stop()
    assert gone.wait(5)
    sub.undeclare()


def test_sharded_instances_split_the_work(zsession):
    a, b = Gate(shard=True), Gate(shard=True)
    a.release.set(), b.release.set()
    sa, sb = Service(a, zsession, instance="a").start(), Service(b, zsession, instance="b").start()
    # each sees the other's liveliness token before work starts
    assert sa._peers.wait_for(lambda live: live == {"a", "b"}, 5)
    assert sb._peers.wait_for(lambda live: live == {"a", "b"}, 5)
    outs = Collector(zsession, "t/out/*")
    for i in range(30):
        zsession.put(f"t/in/{i}", schemas.encode(GOOD_SELECTION))
    outs.wait(30)
    assert sorted(a.handled + b.handled) == sorted(f"t/in/{i}" for i in range(30))
    assert a.handled and b.handled
    sa.stop(), sb.stop()


def test_stop_lets_go_of_a_sweep_waiting_on_a_silent_store(zsession):
    """A store that holds a query and never answers (a router going down with the rest):
    stop() cancels the sweep's query and joins every thread of the service, so none is
    inside Zenoh when the process exits (a C++/Rust abort at exit, seen in CI)."""
    held, asked = [], threading.Event()

    def silent(q):
        held.append(q)      # never replied to, never finalised until the test ends
        asked.set()

    store = zsession.declare_queryable("findme/*/error", silent)
    g = Gate()
    g.inputs = (Input("findme/*/selection/*", schemas.Selection,
                      answers=("findme/{session}/pose/{n}",)),)
    svc = Service(g, zsession, sweep_s=60.0).start()
    try:
        assert asked.wait(10), "the first sweep never asked the store"
        svc.stop(timeout=0.2)
        assert [t.name for t in svc._threads if t.is_alive()] == []
    finally:
        store.undeclare()
        held.clear()


class AskGate(Handler):
    """Test handler with a query (a MeasureRequest on findme/<s>/measure) that blocks on an
    event: at most 2 of a session's queries wait, each at most 400 bytes."""

    name = "askgate"
    inputs = ()
    queries = (Input("findme/*/measure", schemas.MeasureRequest, depth=2, max_bytes=400),)

    def __init__(self):
        self.entered, self.release = threading.Event(), threading.Event()

    def on_query(self, key, req):
        self.entered.set()
        self.release.wait(30)
        return schemas.MeasureReply(session=req.session, index=req.index)


def test_queries_are_bounded_per_session_and_in_size(zsession):
    """A query over its size limit, and one more of a session than may wait, are answered at
    once (TOO_LARGE, OVERLOADED) while the worker is busy; another session's query still
    waits its turn and is answered, as are the session's queries that were let in; each
    refusal is counted."""
    svc = Service(AskGate(), zsession).start()
    g = svc.handler
    answers: dict = {}
    done = {}
    arrived = threading.Condition()

    def ask(name, session, pixels):
        done[name] = threading.Event()
        req = schemas.MeasureRequest(session=session, index=0,
                                     pixels=schemas.pixels_to_msg([[1.0, 2.0]] * pixels))

        def run():
            for r in zsession.get(f"findme/{session}/measure", payload=schemas.encode(req),
                                  timeout=30):
                answers[name] = ("ok" if r.ok is not None else
                                 schemas.decode(schemas.Error, r.err.payload.to_bytes()).code)
            with arrived:
                done[name].set()
                arrived.notify_all()
        threading.Thread(target=run, daemon=True).start()

    ask("first", "qa", 1)
    assert g.entered.wait(10)                 # the worker holds it: none of qa's waits
    for name in ("a1", "a2", "a3"):
        ask(name, "qa", 1)
    ask("big", "qb", 40)                      # 40 pixels: ~800 bytes
    ask("other", "qb", 1)
    assert done["big"].wait(10) and answers["big"] == schemas.ErrorCode.ERROR_CODE_TOO_LARGE
    # one of a1-a3 is refused at once: two may wait
    with svc._cv:
        assert svc._cv.wait_for(lambda: svc.inbox.more.get("queries_overloaded") == 1, 10)
    with arrived:
        assert arrived.wait_for(lambda: any(done[n].is_set() for n in ("a1", "a2", "a3")), 10)
        refused = [n for n in ("a1", "a2", "a3") if done[n].is_set()]
    assert [answers[n] for n in refused] == [schemas.ErrorCode.ERROR_CODE_OVERLOADED]
    assert not done["other"].is_set()        # qb's query waits its turn, not refused
    g.release.set()
    for n in ("first", "other", *(n for n in ("a1", "a2", "a3") if n not in refused)):
        assert done[n].wait(10) and answers[n] == "ok", (n, answers)
    st = svc.status()
    assert st.counters["queries_too_large"] == 1 and st.counters["queries_overloaded"] == 1
    svc.stop()
