"""A recording, read back: every bus message of it (``read_recording``: ``Recorded``, in
file = arrival order), as much of it as is complete while its recorder still writes it
(``read_available``: the messages and ``Extent``, how far it got), and the session it is
of (``recording_session``).

A bus channel's message gets its key back from its payload (``mcap_layout.key_of``), a
``bus-exact`` channel's from the topic; a channel of a foreign MCAP counts as bus-exact when
its topic is a bus key, and is skipped otherwise. View channels only on request. Log time:
when the recorder received the message (ns since the epoch). A file that is not MCAP
raises ``findme_core.errors.RecordingError``; so does an unfinished one, except for
``read_available``. The recorder closes a chunk every half second, so a file being written
is whole chunks followed by at most one being written: what is complete is every message
of the whole chunks.
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


@dataclass(frozen=True)
class Extent:
    """How much of a recording was read.

    complete: it has its end (its recorder finished it); reason: why reading stopped
    before the end ("" when complete); bytes_read: the bytes of whole records read;
    size: the file's size when it was read; messages: bus messages read; last_time: the
    log time of the last one (ns since the epoch, 0 if none).
    """

    complete: bool
    reason: str
    bytes_read: int
    size: int
    messages: int
    last_time: int

    def describe(self, path) -> str:
        """One line for the user: how far an unfinished recording got (or that it is
        complete)."""
        if self.complete:
            return f"{path}: complete, {self.messages} messages"
        import datetime as dt
        last = (dt.datetime.fromtimestamp(self.last_time / 1e9).strftime("%H:%M:%S")
                if self.last_time else "none yet")
        return (f"{path} is not finished (still being written, or its recorder stopped "
                f"without finishing it): read the {self.messages} messages complete so far "
                f"(the last at {last}), {self.bytes_read / 1e3:.0f} of "
                f"{self.size / 1e3:.0f} kB")


def read_available(path, views: bool = False) -> tuple[list[Recorded], Extent]:
    """Every bus message of a recording that is complete (all of a finished one; of one
    still being written, or cut short, the messages of its whole chunks), in file order,
    and how far that is. View channels too with ``views``.

    Raises:
        RecordingError: not an MCAP file.
    """
    from mcap.exceptions import McapError
    from mcap.stream_reader import StreamReader
    from mcap.records import Channel, Footer, Message, Schema
    out: list[Recorded] = []
    schema_names: dict[int, str] = {0: ""}
    channels: dict[int, Channel] = {}
    ended, reason, good = False, "", 8
    with open_mcap(path) as f:
        size = Path(path).stat().st_size
        try:
            for r in StreamReader(f, validate_crcs=True, record_size_limit=size).records:
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
                good = f.tell()
        except (McapError, struct.error, ValueError, KeyError, OSError) as e:
            reason = _why(e, good, size)
    if not ended and not reason:
        reason = "it has no end yet"
    n = sum(r.channel != "view" for r in out)
    return out, Extent(ended, "" if ended else reason, good, size, n,
                       out[-1].log_time if out else 0)


def _why(e: Exception, at: int, size: int) -> str:
    """Why reading stopped, for the user (an MCAP reader's EndOfFile has no message)."""
    text = str(e).strip()
    if type(e).__name__ == "EndOfFile" and at >= size:
        return "it has no end yet"
    if type(e).__name__ == "EndOfFile" or not text:
        return f"the file ends inside a record, after byte {at} of {size}"
    return f"{type(e).__name__}: {text} (after byte {at} of {size})"


def read_recording(path, views: bool = False) -> list[Recorded]:
    """Every bus message of a finished recording in file (= arrival) order; view channels
    too with ``views``.

    Raises:
        RecordingError: not MCAP, or unfinished (its recorder is still writing it, or died:
            ``findme recover``), with the reason.
    """
    out, extent = read_available(path, views)
    if not extent.complete:
        raise RecordingError(
            f"{path}: the recording is not finished ({extent.reason}): it is still being "
            f"written (wait until its recorder closes it) or its recorder died (salvage it "
            f"with: findme recover {path} -o FIXED.mcap)")
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

