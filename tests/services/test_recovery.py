"""Crash recovery across processes: a service SIGKILLed mid-session and restarted picks up
what was published while it was down (held by the store), the trajectory continues, and no
frame is lost or answered twice. Frames come as plain puts from a client (a phone app of
someone else's making), not from our capture service. Waits on results and liveliness."""

import threading
import time

import pytest

import schemas
from services.runtime import bus
from tests.services.conftest import ProcBus, frame_of, walk_views


class Results:
    """Counts every message of a session by key (to see duplicates) and waits for keys."""

    def __init__(self, client, session):
        self.cv, self.count, self.last = threading.Condition(), {}, {}
        self.sub = client.declare_subscriber(f"findme/{session}/**", self._cb)

    def _cb(self, sample):
        k = str(sample.key_expr)
        with self.cv:
            self.count[k] = self.count.get(k, 0) + 1
            self.last[k] = sample.payload.to_bytes()
            self.cv.notify_all()

    def wait(self, keys, timeout=60):
        with self.cv:
            assert self.cv.wait_for(lambda: all(k in self.count for k in keys), timeout), \
                sorted(set(keys) - set(self.count))

    def trajectory(self, session, n, timeout=60):
        """The session's trajectory once it has n poses."""
        k = f"findme/{session}/trajectory"

        def full():
            return k in self.last and len(schemas.decode(schemas.Trajectory, self.last[k]).poses) >= n
        with self.cv:
            assert self.cv.wait_for(full, timeout), f"no trajectory of {n} poses"
            return schemas.decode(schemas.Trajectory, self.last[k])

    def once(self, kind):
        """{key: count} of a kind (e.g. "pose")."""
        with self.cv:
            return {k: c for k, c in self.count.items() if k.split("/")[2] == kind}


@pytest.fixture(scope="module")
def pipeline():
    pb = ProcBus()
    pb.serve("store", "st")
    pb.serve("hypotheses", "h1")
    pb.serve("selection", "sel", "--auto")
    pb.serve("odometry", "od1")
    yield pb
    codes = pb.close()
    assert all(c == 0 for n, c in codes.items() if n in ("st", "sel", "router")), codes


@pytest.fixture(scope="module")
def views():
    return walk_views(6)


def _send(pb, session, views, indices):
    for n in indices:
        bus.put(pb.client, f"findme/{session}/frame/{n}", schemas.encode(frame_of(views[n], session, n)))


def _poses(session, indices):
    return [f"findme/{session}/pose/{n}" for n in indices]


@pytest.mark.parametrize("victim", ["hypotheses", "odometry"])
def test_sigkill_and_restart_loses_no_frame_and_the_trajectory_continues(pipeline, views, victim):
    pb, s = pipeline, f"kill-{victim}"
    inst = {"hypotheses": "h1", "odometry": "od1"}[victim]
    res = Results(pb.client, s)
    _send(pb, s, views, range(3))
    res.wait(_poses(s, range(3)))
    pb.kill(victim, inst)
    _send(pb, s, views, range(3, 6))
    if victim == "odometry":   # everything odometry needs is on the bus before it comes back
        res.wait([f"findme/{s}/selection/{n}" for n in range(3, 6)])
    pb.serve(victim, inst)
    res.wait(_poses(s, range(6)) + [f"findme/{s}/motion/{n - 1}/{n}" for n in range(1, 6)])
    traj = res.trajectory(s, 6)
    res.sub.undeclare()
    assert set(res.once("pose").values()) == {1}, res.once("pose")         # each pose once
    assert set(res.once("hypotheses").values()) == {1}, res.once("hypotheses")
    assert res.once("error") == {}
    assert [p.index for p in traj.poses] == list(range(6))
    for n in range(1, 6):
        m = schemas.decode(schemas.Motion, res.last[f"findme/{s}/motion/{n - 1}/{n}"])
        assert not m.error and 0.05 < m.z_m < 0.2, m   # the walk: ~9 cm ahead a photo
    st = pb.status(victim, inst)   # the new instance handled exactly what it missed
    assert st.counters["recovered"] == 3, dict(st.counters)
    done = st.counters["hypothesis_sets"] if victim == "hypotheses" else st.counters["motions"]
    assert done == 3, dict(st.counters)


def test_odometry_chains_past_a_photo_never_selected_and_one_that_failed(views):
    """Photo 2 is never selected: after --gap-wait (1 s) photo 3 chains from photo 1 and the
    gap is reported as an Error naming selection/2. Photo 4's frame failed upstream (an Error
    about it): photo 5 chains from photo 3 at once, without waiting, and no gap is reported."""
    from services.pipeline.hypotheses import HypothesesHandler
    pb, s = ProcBus(), "gaps"
    try:
        pb.serve("store", "stg")           # odometry asks it for the selected photos' frames
        pb.serve("odometry", "odg", "--gap-wait", "1")
        res = Results(pb.client, s)
        hyp = HypothesesHandler()
        for n in range(6):
            f = frame_of(views[n], s, n)
            bus.put(pb.client, bus.key(s, "frame", n), schemas.encode(f))
            if n == 4:
                err = schemas.Error(session=s, key=bus.key(s, "frame", 4), message="bad image",
                                    code=schemas.ErrorCode.ERROR_CODE_BAD_IMAGE, service="hypotheses/x")
                bus.put(pb.client, bus.key(s, "error"), schemas.encode(err))
                continue
            (out,) = hyp.on_message(bus.key(s, "frame", n), f)
            bus.put(pb.client, out.key, schemas.encode(out.msg))
            if n != 2:
                sel = schemas.Selection(session=s, index=n, rank=1, by=schemas.SELECTED_BY_AUTO)
                bus.put(pb.client, bus.key(s, "selection", n), schemas.encode(sel))
        res.wait(_poses(s, (0, 1, 3, 5)) + [f"findme/{s}/motion/1/3", f"findme/{s}/motion/3/5"])
        traj = res.trajectory(s, 4)
        st = pb.status("odometry", "odg")
        res.sub.undeclare()
    finally:
        codes = pb.close()
    assert codes["odg"] == 0
    assert [p.index for p in traj.poses] == [0, 1, 3, 5]
    errs = [schemas.decode(schemas.Error, p) for k, p in res.last.items() if k.endswith("/error")]
    gap = schemas.decode(schemas.Error, res.last[f"findme/{s}/error"])
    assert gap.key == bus.key(s, "selection", 2) and "chains past it" in gap.message, errs
    assert st.counters["gaps"] == 1 and st.counters["motions"] == 3, dict(st.counters)
    assert res.once("pose") == {k: 1 for k in _poses(s, (0, 1, 3, 5))}


def test_a_selection_after_the_store_forgot_the_frames_still_gets_its_motion(views):
    """A sender without a cache (plain puts) and a user who chooses late: odometry asked for
    each frame when its hypotheses came, so selections made after the store's window (2 s
    here) has dropped the frames still get their motion, without asking again."""
    from services.pipeline.hypotheses import HypothesesHandler
    from services.runtime.bus import get_all
    pb, s = ProcBus(), "late"
    try:
        pb.serve("store", "stl", "--window", "2")
        pb.serve("odometry", "odl")
        res = Results(pb.client, s)
        hyp = HypothesesHandler()
        frames = [frame_of(views[n], s, n) for n in (0, 1)]
        # the hypotheses are computed first: sent right after its frame, each finds the
        # frame still in the store (computed in between, on a loaded machine, they took
        # longer than the store's window, and odometry found the frame gone)
        hsets = [hyp.on_message(bus.key(s, "frame", f.index), f)[0] for f in frames]
        for f, out in zip(frames, hsets):
            bus.put(pb.client, bus.key(s, "frame", f.index), schemas.encode(f))
            bus.put(pb.client, out.key, schemas.encode(out.msg))
        pb.wait_status("odometry", "odl", lambda st: st.counters["handled"] >= 2)
        # the store's window passes: asked (paced) until it no longer holds the frames
        deadline, pace = time.monotonic() + 30, threading.Event()
        while get_all(pb.client, f"findme/{s}/frame/*", 5):
            assert time.monotonic() < deadline, "the store kept the frames past its window"
            pace.wait(0.1)
        for n in (0, 1):
            sel = schemas.Selection(session=s, index=n, rank=1, by=schemas.SELECTED_BY_USER)
            bus.put(pb.client, bus.key(s, "selection", n), schemas.encode(sel))
        res.wait([f"findme/{s}/motion/0/1"])
        m = schemas.decode(schemas.Motion, res.last[f"findme/{s}/motion/0/1"])
        # a motion that failed comes without a pose: say why rather than wait for the pose
        assert not m.error, (m.error, dict(pb.status("odometry", "odl").counters))
        res.wait(_poses(s, (0, 1)))
        st = pb.status("odometry", "odl")
        res.sub.undeclare()
    finally:
        codes = pb.close()
    assert codes["odl"] == 0
    assert 0.05 < m.z_m < 0.2, m
    # the bus asked: the new session's poses once, then each frame once (none at selection)
    assert st.counters["fetches"] == 3 and st.counters["motions"] == 1, dict(st.counters)
    assert res.once("error") == {}
