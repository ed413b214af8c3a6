"""The key is the only authority (issue 11), on an in-process bus: every service refuses, on
every input and query, a payload whose session or photo numbers disagree with its key
(FORBIDDEN, naming both), a message it fetches from the bus is held to the key it asked
for, and nothing refused is filed anywhere. Waits on messages, never sleeps."""

from __future__ import annotations

import pytest

import schemas
from services.pipeline.hypotheses import HypothesesHandler
from services.pipeline.measurement import MeasurementHandler
from services.pipeline.odometry import OdometryHandler
from services.pipeline.selection import SelectionHandler
from services.runtime import authority
from services.runtime.authority import KeyAuthorityError, check, claimed_key
from services.runtime.handler import error_code
from services.runtime.service import Group
from tests.services.conftest import Collector, frame_of

CODE = schemas.ErrorCode
HANDLERS = {"hypotheses": HypothesesHandler, "selection": SelectionHandler,
            "measurement": MeasurementHandler, "odometry": OdometryHandler}


def messages(session="s1", n=2):
    """One message of every type with a key rule, as its owner would publish it."""
    return [schemas.Frame(session=session, index=n), schemas.HypothesisSet(session=session, index=n),
            schemas.Selection(session=session, index=n), schemas.Scene(session=session, index=n),
            schemas.Motion(session=session, index_a=n - 1, index_b=n),
            schemas.Pose(session=session, index=n), schemas.Trajectory(session=session),
            schemas.Error(session=session), schemas.MeasureReply(session=session, index=n),
            schemas.MeasureRequest(session=session, index=n)]


def test_check_accepts_the_own_key_and_refuses_any_other():
    for msg in messages():
        own = claimed_key(msg)
        check(own, msg)
        kind = own.split("/")[2]
        others = [own.replace("/s1/", "/bob-1/"), own.replace(f"/{kind}", "/frame", 1)
                  if kind != "frame" else own.replace("/frame", "/scene"), "findme/@errors"]
        if own[-1].isdigit():
            others += [own[:-1] + "7", own[:-1] + "02", own[:-1] + "-1", own + "/0"]
        for key in others:
            with pytest.raises(KeyAuthorityError) as e:
                check(key, msg)
            assert key in str(e.value) and (own in str(e.value) or "not a session key" in str(e.value))
            assert error_code(e.value) == CODE.ERROR_CODE_FORBIDDEN
    check("findme/s1/frame/0", b"raw bytes are the recorder's business")
    check("findme/s1/status", schemas.ServiceStatus(service="x"))
    assert claimed_key(schemas.Motion(session="s", index_a=3, index_b=4)) == "findme/s/motion/3/4"


def inputs_of(handler):
    return [(inp.key, inp.type) for inp in handler.inputs]


@pytest.mark.parametrize("name", sorted(HANDLERS))
def test_every_service_refuses_a_payload_of_another_key_on_every_input(name, zsession, level_view):
    """On each input key of the service, a valid message claiming bob-1 (or another photo)
    gives a FORBIDDEN Error on alice-1's error key naming both keys; a good message is
    handled after them, and the refused ones left no trace in the service's state."""
    group = Group(zsession)
    h = HANDLERS[name]()
    frame = frame_of(level_view, session="alice-1")
    (hs,) = HypothesesHandler().on_message("findme/alice-1/frame/0", frame)
    cache = {"findme/alice-1/frame/0": schemas.encode(frame),
             "findme/alice-1/hypotheses/0": schemas.encode(hs.msg)}
    svc = group.add(h)
    h.fetch = cache.get          # (after Service set its own)
    errors = Collector(zsession, "findme/alice-1/error")
    sent = []
    for key_expr, cls in inputs_of(h):
        kind = key_expr.split("/")[2]
        if kind == "error":
            continue   # no photo number; odometry reads only an Error naming its own session
        good = {"frame": frame, "hypotheses": hs.msg, "selection": schemas.Selection(
            session="alice-1", index=0, rank=1, by=schemas.SELECTED_BY_USER),
                "motion": schemas.Motion(session="alice-1", index_a=0, index_b=1, x_m=0.0,
                                         z_m=0.0, yaw_rad=0.1)}[kind]
        for session, n in (("bob-1", 0), ("alice-1", 5)):
            forged = cls()
            forged.CopyFrom(good)
            forged.session = session
            if kind == "motion":      # a motion's key names both its photos
                forged.index_a, forged.index_b = n, n + 1
                key, claimed = "findme/alice-1/motion/0/1", f"findme/{session}/motion/{n}/{n + 1}"
            else:
                forged.index = n
                key, claimed = f"findme/alice-1/{kind}/0", f"findme/{session}/{kind}/{n}"
            zsession.put(key, schemas.encode(forged))
            sent.append((key, claimed))
    errs = [schemas.decode(schemas.Error, p) for _, p in errors.wait(len(sent))]
    assert sorted((e.key, e.code) for e in errs) == sorted(
        (k, CODE.ERROR_CODE_FORBIDDEN) for k, _ in sent)
    for e in errs:
        assert any(e.key in e.message and claimed in e.message for _, claimed in sent), e.message
    assert svc.status().errors == len(sent)
    traces = {"measurement": lambda: (len(h.sessions),),
              "odometry": lambda: (len(h.sessions),), "hypotheses": lambda: (h.done,),
              "selection": lambda: (h.chosen,)}[name]()
    assert not any(traces), traces
    group.stop()


def test_measure_query_for_another_session_refused(zsession):
    group = Group(zsession)
    group.add(MeasurementHandler())
    req = schemas.MeasureRequest(session="bob-1", index=0)
    req.pixels.extend(schemas.pixels_to_msg([[1, 2]]))
    (r,) = list(zsession.get("findme/alice-1/measure", payload=schemas.encode(req), timeout=10))
    err = schemas.decode(schemas.Error, r.err.payload.to_bytes())
    assert err.code == CODE.ERROR_CODE_FORBIDDEN
    assert "findme/alice-1/measure" in err.message and "findme/bob-1/measure" in err.message
    group.stop()


def test_a_fetched_message_is_held_to_the_key_asked_for(level_view):
    """Whoever answers a fetch (any device may reply on its own keys) cannot hand a service
    another photo's or session's message: neither the hypotheses it asks for nor the frame
    it asks for when a set does not carry the frame's height."""
    (hs,) = HypothesesHandler().on_message("findme/t1/frame/0", frame_of(level_view))
    (other_hs,) = HypothesesHandler().on_message("findme/t1/frame/3",
                                                 frame_of(level_view, session="t1", index=3))
    without = schemas.HypothesisSet()
    without.CopyFrom(hs.msg)
    without.ClearField("frame_height")
    other = frame_of(level_view, session="t1", index=3)
    sel = schemas.Selection(session="t1", index=0, rank=1, by=schemas.SELECTED_BY_USER)
    for held, wrong in (({"findme/t1/hypotheses/0": schemas.encode(other_hs.msg)},
                         "findme/t1/hypotheses/3"),
                        ({"findme/t1/hypotheses/0": schemas.encode(without),
                          "findme/t1/frame/0": schemas.encode(other)}, "findme/t1/frame/3")):
        h = MeasurementHandler()
        h.fetch = held.get
        with pytest.raises(KeyAuthorityError, match=wrong):
            h.on_message("findme/t1/selection/0", sel)
        st = h.sessions.peek("t1")
        assert st is None or not st.scenes
    assert authority.KEY_RULES["findme.v1.Frame"] == ("frame", ("index",))
