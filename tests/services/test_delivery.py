"""Delivery across processes (router + services as subprocesses): a burst into a slow service
loses nothing silently and no transport is closed; a session that floods is answered
OVERLOADED while another session is served in turn; status and sharding see every live
instance every time. Waits on results, errors, liveliness and log lines, never sleeps."""

import threading

import pytest

import schemas
from findme.cli.status import service_statuses
from findme_core.synth.render import Pose, Room, render
from services.runtime import bus
from tests.cli.conftest import run_findme
from tests.services.conftest import ProcBus, frame_of

OVERLOADED = schemas.ErrorCode.ERROR_CODE_OVERLOADED


class Answers:
    """Every answer to a session's frames: hypotheses/<n> or an Error naming frame/<n>,
    in arrival order."""

    def __init__(self, client, session):
        self.cv, self.items = threading.Condition(), []
        self.subs = [client.declare_subscriber(f"findme/{session}/hypotheses/*", self._hyp),
                     client.declare_subscriber(f"findme/{session}/error", self._err)]

    def _hyp(self, sample):
        with self.cv:
            self.items.append(("hypotheses", bus.parse_key(str(sample.key_expr)).index(), None))
            self.cv.notify_all()

    def _err(self, sample):
        err = schemas.decode(schemas.Error, sample.payload.to_bytes())
        with self.cv:
            self.items.append(("error", bus.parse_key(err.key).index(), err))
            self.cv.notify_all()

    def wait(self, n, timeout=60):
        with self.cv:
            assert self.cv.wait_for(lambda: len(self.items) >= n, timeout), \
                f"{len(self.items)} of {n} answers"
            return list(self.items)

    def close(self):
        for s in self.subs:
            s.undeclare()


@pytest.fixture(scope="module")
def slow_bus():
    """A router and one hypotheses service that takes 4 messages per session at most."""
    pb = ProcBus()
    pb.serve("hypotheses", "h1", "--queue-depth", "4")
    yield pb
    codes = pb.close()
    assert "Closing transport" not in "".join(pb.router.lines), "the router closed a transport"
    assert codes["h1"] == 0, "".join(pb.procs["h1"].lines)[-3000:]


@pytest.fixture(scope="module")
def vga_frame():
    v = render(Room.rectangle(5.0, 6.0, floor_style="wood"), Pose(0.0, -1.5, 1.45, yaw_deg=5,
                                                                  pitch_deg=25), 640, 480, seed=3)
    return v


def test_a_burst_into_a_slow_service_is_answered_frame_by_frame(slow_bus, vga_frame):
    """300 BLOCK puts as fast as the client can into a service that needs ~70 ms a frame
    (the old runtime's callback blocked here until the router closed the link: 290 of 300
    arrived and nothing said so). Every frame is answered exactly once, by its hypotheses or
    an OVERLOADED error naming it, the counters agree, and the router closes nothing."""
    pb, n = slow_bus, 300
    answers = Answers(pb.client, "burst")
    before = pb.status("hypotheses", "h1")
    for i in range(n):
        bus.put(pb.client, f"findme/burst/frame/{i}", schemas.encode(frame_of(vga_frame, "burst", i)))
    got = answers.wait(n)
    answers.close()
    by_frame = {}
    for kind, i, err in got:
        assert i not in by_frame, f"frame {i} answered twice"
        by_frame[i] = (kind, err)
    assert sorted(by_frame) == list(range(n))
    errors = [e for kind, e in by_frame.values() if kind == "error"]
    assert errors and all(e.code == OVERLOADED and "burst" in e.message for e in errors)
    handled = n - len(errors)
    assert handled >= 4
    st = pb.status("hypotheses", "h1")
    assert st.frames_in - before.frames_in == n
    assert st.dropped - before.dropped == len(errors)
    assert st.counters["error_overloaded"] - before.counters.get("error_overloaded", 0) == len(errors)
    assert st.counters["hypothesis_sets"] - before.counters.get("hypothesis_sets", 0) == handled
    assert "Closing transport" not in "".join(pb.router.lines)
    # what a user sees: the errors by code in `findme status`
    text = run_findme("status", "--connect", pb.ep).stdout
    assert f"errors: overloaded {st.counters['error_overloaded']}" in text, text


def test_a_flooding_session_does_not_delay_another(slow_bus, vga_frame):
    """Session A sends 30 large photos at once (~0.3 s each here); once all have reached the
    service (A's overflow answered OVERLOADED, its queue full), session B sends one: B is
    handled before A's queue has drained (round-robin), so A results still come after B's.
    With one FIFO, B would come after every A photo queued before it."""
    import cv2
    pb = slow_bus
    big = schemas.Frame()
    big.CopyFrom(frame_of(vga_frame, "flood", 0))
    big.image.data = cv2.imencode(".jpg", cv2.resize(vga_frame.image, (1600, 1200)))[1].tobytes()
    big.intrinsics.fx, big.intrinsics.fy = 2.5 * big.intrinsics.fx, 2.5 * big.intrinsics.fy
    big.intrinsics.cx, big.intrinsics.cy = 2.5 * big.intrinsics.cx, 2.5 * big.intrinsics.cy
    big.intrinsics.width, big.intrinsics.height = 1600, 1200
    a, b = Answers(pb.client, "flood"), Answers(pb.client, "calm")
    order, cv = [], threading.Condition()

    def seen(sample):
        with cv:
            order.append(bus.parse_key(str(sample.key_expr)).session)
            cv.notify_all()
    sub = pb.client.declare_subscriber("findme/*/hypotheses/*", seen)
    before = pb.status("hypotheses", "h1").frames_in
    for i in range(30):
        big.index, big.image.frame_id = i, f"flood/camera/{i}"
        bus.put(pb.client, f"findme/flood/frame/{i}", schemas.encode(big))
    pb.wait_status("hypotheses", "h1", lambda st: st.frames_in - before >= 30)   # all arrived
    bus.put(pb.client, "findme/calm/frame/0", schemas.encode(frame_of(vga_frame, "calm", 0)))
    got_a, got_b = a.wait(30), b.wait(1)
    with cv:
        assert cv.wait_for(lambda: order.count("flood") == sum(k == "hypotheses" for k, *_ in got_a), 60)
    sub.undeclare()
    a.close(), b.close()
    assert got_b[0][0] == "hypotheses"
    # 2 worker threads: at most 2 in progress and 4 waiting, the rest refused at once
    assert sum(k == "error" and e.code == OVERLOADED for k, _, e in got_a) >= 30 - 8
    assert order[order.index("calm") + 1:].count("flood") >= 1, order


def test_status_and_sharding_see_every_instance_every_time():
    """Two hypotheses instances and a store: 30 status calls in a row on one long-lived
    client session list all three (liveliness queries in a row came back empty about half
    the time), and each hypotheses instance counts the other as its peer."""
    pb = ProcBus()
    try:
        for inst in ("ha", "hb"):
            pb.serve("hypotheses", inst)
        pb.serve("store", "s1")
        for _ in range(30):
            assert {(s.service, s.instance) for s in service_statuses(pb.client)} == \
                {("hypotheses", "ha"), ("hypotheses", "hb"), ("store", "s1")}
        for inst in ("ha", "hb"):
            st = pb.status("hypotheses", inst)
            assert st.counters["peers"] == 2, (inst, dict(st.counters))
    finally:
        codes = pb.close()
    assert all(c == 0 for c in codes.values()), codes
