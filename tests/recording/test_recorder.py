"""The recorder: channels per key kind with their schemas, exact keys when the payload does
not say them, the view channels, never overwriting, a finished file when it stops."""

from __future__ import annotations

import threading

import pytest
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from mcap.reader import make_reader

import schemas
from findme_core.errors import InputError, RecordingError
from services.runtime import bus
from services.recording.mcap_layout import key_of
from services.recording.mcap_reader import read_recording
from services.recording.mcap_writer import McapRecording, recording_path
from services.recording.recorder import FLUSH_BOUND_S, RecorderHandler
from services.runtime.service import Group

from .conftest import PAIR, Arrivals, odometry_messages


def _summary(path):
    with open(path, "rb") as f:
        return make_reader(f).get_summary()


def test_key_follows_from_every_kind_of_payload():
    s = "s1"
    for key, msg, _ in odometry_messages(s, 1):
        assert key_of(s, msg) == key
    assert key_of(s, schemas.Frame(index=3)) == "findme/s1/frame/3"
    assert key_of(s, schemas.HypothesisSet(index=2)) == "findme/s1/hypotheses/2"
    assert key_of(s, schemas.MeasureReply(index=1)) == "findme/s1/measured/1"
    assert key_of(s, schemas.ServiceStatus()) is None


def test_channels_per_kind_carry_schemas_and_exact_keys_survive(tmp_path):
    recs = read_recording(PAIR)
    frame = recs[0]
    assert frame.key.endswith("/frame/0")
    path = tmp_path / "s.mcap"
    rec = McapRecording(path, "golden-examples-pair")
    sid = "golden-examples-pair"
    rec.write(frame.key, frame.payload, 1)
    rec.write(f"findme/{sid}/frame/5", frame.payload, 2)           # key says 5, payload 0
    rec.write(f"findme/{sid}/frame/6", b"\x00garbage", 3)           # not protobuf at all
    rec.write(f"findme/{sid}/frame/7", b'{"json": true}', 4)        # a foreign payload
    rec.write(f"findme/{sid}/future/1", frame.payload, 5)           # an unknown kind
    rec.close()
    s = _summary(path)
    topics = {c.topic: c for c in s.channels.values()}
    bus_frame = topics[f"findme/{sid}/frame"]
    assert bus_frame.metadata["findme.channel"] == "bus"
    assert s.schemas[bus_frame.schema_id].name == "findme.v1.Frame"
    assert s.schemas[bus_frame.schema_id].encoding == "protobuf"
    for k in (5, 6, 7):
        assert topics[f"findme/{sid}/frame/{k}"].metadata["findme.channel"] == "bus-exact"
    assert topics[f"findme/{sid}/frame/6"].schema_id == 0
    assert topics[f"findme/{sid}/future/1"].metadata["findme.channel"] == "bus-exact"
    back = read_recording(path)
    assert [(r.key, r.payload) for r in back] == [
        (frame.key, frame.payload), (f"findme/{sid}/frame/5", frame.payload),
        (f"findme/{sid}/frame/6", b"\x00garbage"), (f"findme/{sid}/frame/7", b'{"json": true}'),
        (f"findme/{sid}/future/1", frame.payload)]


def test_view_channels_image_and_numbered_hypotheses(tmp_path):
    recs = read_recording(PAIR, views=True)
    by_topic = {}
    for r in recs:
        by_topic.setdefault(r.topic, []).append(r)
    sid = "golden-examples-pair"
    frame = schemas.decode(schemas.Frame, by_topic[f"findme/{sid}/frame"][0].payload)
    img = CompressedImage.FromString(by_topic[f"findme/{sid}/foxglove/image"][0].payload)
    assert img.data == frame.image.data and img.format == "jpeg"
    assert img.frame_id == frame.image.frame_id
    hs = schemas.decode(schemas.HypothesisSet, by_topic[f"findme/{sid}/hypotheses"][0].payload)
    ann = ImageAnnotations.FromString(by_topic[f"findme/{sid}/foxglove/hypotheses"][0].payload)
    assert len(ann.points) == len(hs.hypotheses) == 10
    assert [t.text for t in ann.texts] == [str(h.rank) for h in hs.hypotheses]
    first = hs.hypotheses[0].polyline.points[0]
    # bus pixels are centred on the pixel, Foxglove's on its corner: +0.5
    assert ann.points[0].points[0].x == pytest.approx(first.u + 0.5)
    assert ann.points[0].points[0].y == pytest.approx(first.v + 0.5)
    views = {r.topic.rsplit("/", 1)[1] for r in recs if r.channel == "view"}
    assert {"image", "calibration", "tf", "hypotheses", "boundary", "measured"} <= views


def test_unknown_compression_is_refused_by_name(tmp_path):
    with pytest.raises(InputError, match="compression 'gzip' is not one of"):
        RecorderHandler(tmp_path, compression="gzip")


def test_never_overwrites_a_recording(tmp_path):
    (tmp_path / "s.mcap").write_bytes(b"an earlier recording")
    assert recording_path(tmp_path, "s").name == "s~2.mcap"
    (tmp_path / "s~2.mcap").write_bytes(b"another")
    assert recording_path(tmp_path, "s").name == "s~3.mcap"


def test_unfinished_recording_is_refused_with_advice(tmp_path):
    recs = read_recording(PAIR)
    path = tmp_path / "s.mcap"
    rec = McapRecording(path, "golden-examples-pair")
    for r in recs:
        rec.write(r.key, r.payload, r.log_time)
    rec.flush()   # on disk, but no summary: as after a SIGKILL
    with pytest.raises(RecordingError, match="findme recover"):
        read_recording(path)
    rec.close()
    assert len(read_recording(path)) == len(recs)
    (tmp_path / "x.mcap").write_bytes(b"not mcap at all")
    with pytest.raises(RecordingError, match="not an MCAP file"):
        read_recording(tmp_path / "x.mcap")


def test_recorder_service_records_the_bus_and_finishes_on_stop(tmp_path):
    recs = read_recording(PAIR)
    session = bus.open_session(bus.BusConfig())
    group = Group(session)
    try:
        svc = group.add(RecorderHandler(tmp_path))
        seen = Arrivals(session, "findme/*/**")
        for r in recs:
            bus.put(session, r.key, r.payload)
        assert seen.wait_count(len(recs))
        assert svc.handler.wait_recorded(len(recs)), svc.handler.counters()
        seen.close()
    finally:
        group.stop()      # drains the recorder's queue, then finishes the file
        session.close()
    path = svc.handler.path_of("golden-examples-pair")
    assert path == tmp_path / "golden-examples-pair.mcap"
    back = read_recording(path)
    assert [(r.key, r.payload) for r in back] == [(r.key, r.payload) for r in recs]
    s = _summary(path)
    assert s.statistics.message_count == len(read_recording(path, views=True))
    assert svc.handler.counters()["write_errors"] == 0
    status = svc.status()
    assert status.frames_in == len(recs) and status.dropped == 0


def test_flusher_bounds_what_is_only_in_memory(tmp_path):
    """The flusher thread runs every flush_s (< the 1 s bound): after one tick, everything
    written is in the file (a reader without the summary sees it)."""
    assert FLUSH_BOUND_S >= 2 * 0.5
    h = RecorderHandler(tmp_path, flush_s=0.05)
    recs = read_recording(PAIR)
    flushed = threading.Event()
    orig = h.flush

    def flush():
        orig()
        flushed.set()
    h.flush = flush
    for r in recs:
        h.on_message(r.key, r.payload)
    flushed.clear()
    assert flushed.wait(5)           # a full flush tick after the last write
    from services.recording.mcap_recover import recover
    s = recover(tmp_path / "golden-examples-pair.mcap", tmp_path / "fixed.mcap")
    assert not s.complete
    assert len(read_recording(tmp_path / "fixed.mcap")) == len(recs)
    h.close()


def test_trajectory_view_equals_the_plain_encoding():
    """The trajectory view concatenates cached encoded poses; it must decode to exactly the
    PosesInFrame built field by field."""
    from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame

    from services.recording.foxglove_view import FoxgloveView
    view = FoxgloveView("s")
    tr = schemas.Trajectory(session="s", time_ns=5)
    for i in range(200):
        tr.poses.add(index=i, x_m=0.01 * i, z_m=-0.02 * i, yaw_rad=0.003 * i)
    ref = PosesInFrame(frame_id="s/level/0", timestamp=schemas.ns_to_timestamp(5))
    for p in tr.poses:
        ref.poses.append(schemas.pose_to_foxglove(p, "s").pose)
    for _ in range(2):   # cold and cached
        (topic, cls, data), = view.derive("findme.v1.Trajectory", tr, 1)
        assert topic == "findme/s/foxglove/trajectory" and cls is PosesInFrame
        assert PosesInFrame.FromString(data) == ref


def test_more_live_sessions_than_handles_keep_one_file_each(tmp_path):
    """With handles for 3 sessions and 5 sessions written in turn, quiet ones are suspended
    and reopened for appending: one complete file per session, never a ~2 file."""
    recs = read_recording(PAIR)
    h = RecorderHandler(tmp_path, max_open=3, views=False)
    sessions = [f"s{i}" for i in range(5)]
    for r in recs:
        for s in sessions:
            h.on_message(r.key.replace("golden-examples-pair", s), r.payload)
        h.flush()
    c = h.counters()
    assert c["suspends"] > 0 and c["open_handles"] == 3 and c["open_files"] == 5
    h.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{s}.mcap" for s in sessions]
    for s in sessions:
        back = read_recording(tmp_path / f"{s}.mcap")
        assert [r.payload for r in back] == [r.payload for r in recs]


def test_rotation_only_when_asked_and_said(tmp_path, caplog):
    recs = read_recording(PAIR)
    h = RecorderHandler(tmp_path, views=False, rotate_bytes=1)
    with caplog.at_level("INFO", logger="findme.services.recorder"):
        for r in recs[:2]:
            h.on_message(r.key, r.payload)
            h.flush()
    h.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["golden-examples-pair.mcap",
                                                         "golden-examples-pair~2.mcap"]
    assert "rotating" in caplog.text and h.counters()["rotations"] == 1
