"""A recording, read back: every bus message of it (``read_recording``: ``Recorded``, in
file = arrival order) and the session it is of (``recording_session``).

A bus channel's message gets its key back from its payload (``mcap_layout.key_of``), a
``bus-exact`` channel's from the topic; a channel of a foreign MCAP counts as bus-exact when
its topic is a bus key, and is skipped otherwise. View channels only on request. Log time:
when the recorder received the message (ns since the epoch). A file that is not MCAP, or
unfinished, raises ``findme_core.errors.RecordingError``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import schemas
from findme_core.errors import FindmeError, RecordingError

from ..runtime import bus
from .mcap_layout import CHANNEL, MCAP_MAGIC, key_of, parse


@dataclass(frozen=True)
class Recorded:
    """One message of a recording.

    key: the bus key it was on (for bus channels), else the view topic; topic: its channel;
    channel: "bus", "bus-exact" or "view"; schema: its schema name ("" if none);
    payload: the bytes as recorded; log_time: when the recorder received it (ns).
    """

    key: str
    topic: str
    channel: str
    schema: str
    payload: bytes
    log_time: int

    def message(self):
        """The decoded Find Me message (validated), or None for view / foreign channels."""
        if self.schema not in schemas.MESSAGE_TYPES:
            return None
        return schemas.decode(schemas.MESSAGE_TYPES[self.schema], self.payload, check=False)


def open_mcap(path):
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"{p}: no such recording")
    f = open(p, "rb")  # noqa: SIM115 - the caller's context closes it
    if f.read(8) != MCAP_MAGIC:
        f.close()
        raise RecordingError(f"{p}: not an MCAP file")
    f.seek(0)
    return f


def read_recording(path, views: bool = False) -> list[Recorded]:
    """Every bus message of a finished recording in file (= arrival) order; view channels
    too with ``views``.

    Raises:
        RecordingError: not MCAP, or unfinished (its recorder died: ``findme recover``).
    """
    from mcap.exceptions import McapError
    from mcap.stream_reader import StreamReader
    from mcap.records import Channel, Footer, Message, Schema
    out: list[Recorded] = []
    schema_names: dict[int, str] = {0: ""}
    channels: dict[int, Channel] = {}
    ended = False
    with open_mcap(path) as f:
        try:
            for r in StreamReader(f, validate_crcs=True).records:
                if isinstance(r, Schema):
                    schema_names[r.id] = r.name
                elif isinstance(r, Channel):
                    channels[r.id] = r
                elif isinstance(r, Message):
                    rec = _recorded(channels[r.channel_id], schema_names, r, views)
                    if rec is not None:
                        out.append(rec)
                elif isinstance(r, Footer):
                    ended = True
        except (McapError, struct.error, ValueError, KeyError, OSError) as e:
            raise RecordingError(
                f"{path}: the recording is unfinished or damaged ({type(e).__name__}: {e}); "
                f"salvage it with: findme recover {path} -o FIXED.mcap") from None
    if not ended:
        raise RecordingError(f"{path}: the recording has no end (its recorder died?); "
                             f"salvage it with: findme recover {path} -o FIXED.mcap")
    return out


def _recorded(ch, schema_names, m, views: bool) -> Recorded | None:
    kind = ch.metadata.get(CHANNEL, "")
    name = schema_names.get(ch.schema_id, "")
    if kind == "view":
        if not views:
            return None
        return Recorded(ch.topic, ch.topic, "view", name, m.data, m.log_time)
    key = ch.topic
    if kind == "bus":
        msg, _ = parse(m.data)
        try:
            session = bus.parse_key(ch.topic).session
        except FindmeError:
            return None
        key = key_of(session, msg) if msg is not None else None
        if key is None:
            return None
    elif kind != "bus-exact":  # a foreign MCAP: its topic is the key if it looks like one
        try:
            bus.parse_key(ch.topic)
        except FindmeError:
            return None
        kind = "bus-exact"
    return Recorded(key, ch.topic, kind, name, m.data, m.log_time)


def recording_session(path) -> str:
    """The session id a recording is of (its ``findme`` metadata, else its first key)."""
    from mcap.reader import make_reader
    with open_mcap(path) as f:
        try:
            for md in make_reader(f).iter_metadata():
                if md.name == "findme" and md.metadata.get("session"):
                    return md.metadata["session"]
        except Exception:  # noqa: BLE001 - fall back to the messages
            pass
    for r in read_recording(path):
        return bus.parse_key(r.key).session
    raise RecordingError(f"{path}: an empty recording (no Find Me messages)")

