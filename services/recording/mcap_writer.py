"""One session's recording file, written (``McapRecording``), and where it goes
(``recording_path``: never over an existing file).

A recording holds the bus messages exactly as they were plus the view channels
``services.foxglove_view`` derives from them (channels and topics: ``services.mcap_layout``).
Chunked MCAP (``COMPRESSIONS``); ``flush`` closes the open chunk and hands everything to the
OS, ``close`` writes the summary. Log and publish time of a message are the caller's
``log_time`` (ns since the epoch).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

import schemas

from ..runtime import bus
from .foxglove_view import FoxgloveView
from .mcap_layout import CHANNEL, KIND, VERSION, key_of, kind_topic, parse

log = logging.getLogger("findme.services.recorder")   # the recorder's: it writes these

COMPRESSIONS = {"none": CompressionType.NONE, "lz4": CompressionType.LZ4,
                "zstd": CompressionType.ZSTD}


def recording_path(out_dir: Path, session: str) -> Path:
    """``<out>/<session>.mcap``, or ``<session>~<k>.mcap`` when that exists: never overwrite."""
    p = out_dir / f"{session}.mcap"
    k = 2
    while p.exists():
        p = out_dir / f"{session}~{k}.mcap"
        k += 1
    return p



class _AppendFile:
    """The file under a Writer, open only while in use: ``suspend`` closes the handle (after
    a flush), the next write reopens it for appending. The recorder keeps one file per
    session however many sessions are live and holds handles for the busiest only."""

    def __init__(self, path: Path):
        self.path = path
        self._f = open(path, "wb")  # noqa: SIM115 - closed in close()/suspend()
        self._pos = 0

    def write(self, data) -> int:
        if self._f is None:
            self._f = open(self.path, "ab")  # noqa: SIM115 - closed in close()/suspend()
        n = self._f.write(data)
        self._pos += len(data)
        return n

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        if self._f is not None:
            self._f.flush()

    def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None

    @property
    def is_open(self) -> bool:
        return self._f is not None


class McapRecording:
    """One session's MCAP file: bus messages as they were, plus the view channels.

    Not thread-safe: the recorder calls it under its lock.
    """

    def __init__(self, path: Path, session: str, *, compression: str = "zstd",
                 chunk_size: int = 4 * 1024 * 1024, views: bool = True,
                 metadata: dict[str, str] | None = None):
        self.path, self.session = Path(path), session
        self.started_ns = time.time_ns()
        self._file = _AppendFile(self.path)
        self._w = Writer(self._file, chunk_size=chunk_size, compression=COMPRESSIONS[compression])
        self._w.start(profile="", library=VERSION)
        self._w.add_metadata("findme", {"session": session, "schema_version": schemas.VERSION,
                                        "recorder": VERSION, **(metadata or {})})
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[int, int] = {}
        self.view = FoxgloveView(session) if views else None
        self.messages = 0
        self.dirty = False
        self.last_write = time.monotonic()
        self.closed = False

    def _schema(self, cls) -> int:
        name = cls.DESCRIPTOR.full_name
        sid = self._schemas.get(name)
        if sid is None:
            sid = self._w.register_schema(name=name, encoding="protobuf",
                                          data=build_file_descriptor_set(cls).SerializeToString())
            self._schemas[name] = sid
        return sid

    def _channel(self, topic: str, cls, meta: dict[str, str]) -> int:
        cid = self._channels.get(topic)
        if cid is None:
            if cls is None:
                cid = self._w.register_channel(topic=topic, message_encoding="application/octet-stream",
                                               schema_id=0, metadata=meta)
            else:
                cid = self._w.register_channel(topic=topic, message_encoding="protobuf",
                                               schema_id=self._schema(cls), metadata=meta)
            self._channels[topic] = cid
        return cid

    def _add(self, cid: int, data: bytes, t: int) -> None:
        seq = self._seq.get(cid, 0)
        self._seq[cid] = seq + 1
        self._w.add_message(channel_id=cid, log_time=t, publish_time=t, data=data, sequence=seq)
        self.messages += 1

    def write(self, key: str, payload: bytes, log_time: int) -> None:
        """Record one bus message (and what the view channels derive from it)."""
        k = bus.parse_key(key)
        msg, name = parse(payload)
        if msg is not None and key_of(k.session, msg) == key:
            cid = self._channel(kind_topic(k.session, k.kind), type(msg),
                                {CHANNEL: "bus", KIND: k.kind})
        else:  # the key does not follow from the payload: keep the exact key as the topic
            cid = self._channel(key, type(msg) if msg is not None else None,
                                {CHANNEL: "bus-exact", KIND: k.kind})
        self._add(cid, payload, log_time)
        if msg is not None and self.view is not None:
            try:
                derived = self.view.derive(name, msg, log_time)
            except Exception as e:  # noqa: BLE001 - a view is optional; never lose the bus message
                log.warning("recorder: no view of %s: %s: %s", key, type(e).__name__, e)
                derived = []
            for topic, cls, data in derived:
                cid = self._channel(topic, cls, {CHANNEL: "view"})
                self._add(cid, data, log_time)
        self.dirty = True
        self.last_write = time.monotonic()

    def flush(self) -> None:
        """Close the open chunk and hand everything to the OS (survives SIGKILL, not power loss)."""
        if self.dirty and not self.closed:
            self._w.flush()
            self.dirty = False

    @property
    def suspended(self) -> bool:
        return not self._file.is_open

    @property
    def size(self) -> int:
        """Bytes written to the file so far."""
        return self._file.tell()

    def suspend(self) -> None:
        """Flush and close the file handle; the next flush (or a full chunk) reopens it, for
        appending to the same file."""
        if not self.closed:
            self._w.flush()
            self.dirty = False
            self._file.close()

    def close(self) -> None:
        """Write the summary (indexes, statistics) and close the file."""
        if self.closed:
            return
        self.closed = True
        try:
            self._w.finish()
        finally:
            self._file.close()

