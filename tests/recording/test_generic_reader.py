"""A recording is self-describing: a process with only the ``mcap`` package and its protobuf
decoder (mcap-protobuf-support) — none of our code, not even Foxglove's generated classes —
decodes every message of every channel from the schemas embedded in the file."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from services.recording.mcap_reader import read_recording

from tests.conftest import WITHOUT_PROJECT_CODE

from .conftest import GOLDENS

READER = WITHOUT_PROJECT_CODE + textwrap.dedent("""
    from google.protobuf.json_format import MessageToDict
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    out = {"channels": {}, "summary": {}, "first": {}}
    with open(sys.argv[1], "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        s = reader.get_summary()
        out["summary"] = {s.channels[c].topic: n for c, n in
                          s.statistics.channel_message_counts.items()}
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            d = MessageToDict(decoded, preserving_proto_field_name=True)
            c = out["channels"].setdefault(channel.topic, {"schema": schema.name, "n": 0,
                                                           "type": decoded.DESCRIPTOR.full_name})
            c["n"] += 1
            out["first"].setdefault(channel.topic, {k: v for k, v in d.items() if k != "data"}
                                    if "data" in d else d)
            if decoded.DESCRIPTOR.full_name == "foxglove.CompressedImage":
                c["jpeg"] = bytes(decoded.data[:3]) == b"\\xff\\xd8\\xff"
    out["leaked"] = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
    print(json.dumps(out))
""")


def _read_generically(path, cwd):
    r = subprocess.run([sys.executable, "-c", READER, str(path)], cwd=cwd, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


@pytest.mark.parametrize("path", [*GOLDENS, "full"], ids=lambda p: getattr(p, "stem", p))
def test_every_channel_decodes_without_our_code(path, full_recording, tmp_path):
    path = full_recording if path == "full" else path
    res = _read_generically(path, tmp_path)
    assert res["leaked"] == []
    chans = res["channels"]
    # every message of every channel was decoded (counts match the file's own statistics)
    assert {t: c["n"] for t, c in chans.items()} == res["summary"]
    for topic, c in chans.items():
        assert c["type"] == c["schema"], topic
    bus_msgs = read_recording(path)
    for r in bus_msgs:
        topic = r.topic
        assert chans[topic]["type"] == r.schema
    image = [c for t, c in chans.items() if t.endswith("/foxglove/image")]
    assert image and all(c["jpeg"] for c in image)


def test_full_recording_has_every_kind_and_the_foxglove_types(full_recording, tmp_path):
    res = _read_generically(full_recording, tmp_path)
    types = {c["type"] for c in res["channels"].values()}
    assert {"findme.v1.Frame", "findme.v1.HypothesisSet", "findme.v1.Selection",
            "findme.v1.Scene", "findme.v1.MeasureReply", "findme.v1.Motion", "findme.v1.Pose",
            "findme.v1.Trajectory", "findme.v1.Error", "foxglove.CompressedImage",
            "foxglove.CameraCalibration", "foxglove.ImageAnnotations", "foxglove.FrameTransform",
            "foxglove.PoseInFrame", "foxglove.PosesInFrame"} <= types
    sid = "golden-examples-pair"
    pose = res["first"][f"findme/{sid}/foxglove/pose"]
    assert pose["frame_id"] == f"{sid}/level/0"
    traj = res["first"][f"findme/{sid}/foxglove/trajectory"]
    assert len(traj["poses"]) >= 1 and traj["frame_id"] == f"{sid}/level/0"
    hyp = res["first"][f"findme/{sid}/foxglove/hypotheses"]
    assert [t["text"] for t in hyp["texts"]] == [str(i) for i in range(1, 11)]
