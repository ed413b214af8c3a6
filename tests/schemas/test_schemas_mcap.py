"""A recorded channel carries a self-contained schema: a process without our code (and
without foxglove_schemas_protobuf) decodes an MCAP of our messages with the mcap library's
generic protobuf decoder."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

from google.protobuf.json_format import MessageToDict
from mcap.writer import Writer
from mcap_protobuf.schema import build_file_descriptor_set, register_schema

import schemas as S
from tests.conftest import WITHOUT_PROJECT_CODE

READER = WITHOUT_PROJECT_CODE + textwrap.dedent("""
    from google.protobuf.json_format import MessageToDict
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    out = []
    with open(sys.argv[1], "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            out.append({"topic": channel.topic, "schema": schema.name,
                        "type": decoded.DESCRIPTOR.full_name,
                        "log_time": message.log_time,
                        "value": MessageToDict(decoded, preserving_proto_field_name=True)})
    leaked = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
    print(json.dumps({"messages": out, "leaked": leaked}))
""")


def test_mcap_decodes_without_our_code(tmp_path: Path, samples):
    path = tmp_path / "session.mcap"
    written = []
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="", library="findme-test")
        schema_ids: dict[str, int] = {}
        for i, (variant, msg) in enumerate(sorted(samples.items())):
            name = msg.DESCRIPTOR.full_name
            if name not in schema_ids:
                schema_ids[name] = register_schema(w, type(msg))
            channel = w.register_channel(topic=f"findme/test/{variant}", message_encoding="protobuf",
                                         schema_id=schema_ids[name])
            w.add_message(channel, log_time=1000 + i, publish_time=1000 + i, data=S.encode(msg))
            written.append((f"findme/test/{variant}", name, msg))
        w.finish()

    r = subprocess.run([sys.executable, "-c", READER, str(path)], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    result = json.loads(r.stdout)
    assert result["leaked"] == []
    got = {m["topic"]: m for m in result["messages"]}
    assert sorted(got) == sorted(t for t, _, _ in written)
    for topic, name, msg in written:
        assert got[topic]["schema"] == name
        assert got[topic]["type"] == name
        assert got[topic]["value"] == MessageToDict(msg, preserving_proto_field_name=True), topic


def test_frame_schema_includes_foxglove_and_well_known_files():
    fds = build_file_descriptor_set(S.Frame)
    names = [f.name for f in fds.file]
    assert names[-1] == "schemas/v1/frame.proto"
    assert {"foxglove/CompressedImage.proto", "google/protobuf/timestamp.proto",
            "schemas/v1/common.proto"} <= set(names)
    assert len(names) == len(set(names))
