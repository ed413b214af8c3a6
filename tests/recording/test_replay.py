"""``findme replay`` puts a recording back on the bus: every key as it was (a recorder
records the same messages again), or its inputs so the running services compute the rest."""

from __future__ import annotations

from services.runtime import bus
from services.pipeline.hypotheses import HypothesesHandler
from services.pipeline.measurement import MeasurementHandler
from services.recording.mcap_reader import read_recording
from services.recording.recorder import RecorderHandler
from services.runtime.service import Group

from findme.regression.diff import diff_messages

from .conftest import GOLDEN, PAIR, Arrivals, free_port

BAD = GOLDEN / "bad-input.mcap"


def _bus():
    port = free_port()
    session = bus.open_session(bus.BusConfig(listen=(f"tcp/127.0.0.1:{port}",)))
    return session, ["--mode", "peer", "--connect", f"tcp/127.0.0.1:{port}"]


def test_replay_all_keys_records_the_same_messages_again(tmp_path, cli):
    recs = read_recording(BAD)     # includes a corrupt frame and errors: bytes as they were
    session, link = _bus()
    group = Group(session)
    try:
        rec = group.add(RecorderHandler(tmp_path)).handler
        seen = Arrivals(session, "findme/*/**")
        rc, out, err = cli("replay", BAD, "--keys", "all", "--max", "--wait-for", "recorder",
                           *link)
        assert rc == 0, err
        assert f"replayed {len(recs)} messages" in out
        assert seen.wait_count(len(recs))
        assert rec.wait_recorded(len(recs)), rec.counters()
        seen.close()
    finally:
        group.stop()
        session.close()
    again = read_recording(rec.path_of("golden-bad-input"))
    assert [(r.key, r.payload) for r in again] == [(r.key, r.payload) for r in recs]


def test_replay_inputs_lets_the_services_recompute_under_a_new_session(cli):
    recs = {r.key: r.message() for r in read_recording(PAIR)}
    session, link = _bus()
    group = Group(session)
    try:
        group.add(HypothesesHandler())
        group.add(MeasurementHandler())
        seen = Arrivals(session, "findme/again/**")
        rc, out, err = cli("replay", PAIR, "--max", "--session", "again", *link,
                           "--wait-for", "hypotheses", "--wait-for", "measurement")
        assert rc == 0, err
        # frames 2 + selections 2 + the measurement asked again -> hypotheses 2, scenes 2
        assert seen.wait_count(9), [k for k, _ in seen.items]
        got = dict(seen.items)
        seen.close()
    finally:
        group.stop()
        session.close()
    import schemas
    for n in (0, 1):
        old = recs[f"findme/golden-examples-pair/hypotheses/{n}"]
        new = schemas.decode(schemas.HypothesisSet, got[f"findme/again/hypotheses/{n}"])
        assert new.session == "again"
        new.session = old.session
        assert diff_messages(old, new) == []
    new_frame = schemas.decode(schemas.Frame, got["findme/again/frame/0"])
    assert new_frame.image.frame_id == "again/camera/0"
    rep = schemas.decode(schemas.MeasureReply, got["findme/again/measured/0"])
    old = recs["findme/golden-examples-pair/measured/0"]
    rep.session = old.session
    assert diff_messages(old, rep) == []


def test_replay_refuses_bad_arguments(cli, tmp_path):
    rc, _, err = cli("replay", PAIR, "--rate", "0")
    assert rc == 2 and "--rate must be a positive number" in err
    rc, _, err = cli("replay", PAIR, "--session", "bad key")
    assert rc == 2 and "not a valid session id" in err
    rc, _, err = cli("replay", tmp_path / "none.mcap")
    assert rc == 2 and "no such recording" in err
