"""Salvage of a recording whose writer died (``recover``; ``findme recover``).

A recorder killed with SIGKILL leaves no summary and maybe a torn last chunk; ``recover``
copies every whole chunk (CRC-checked), schemas, channels, metadata and attachments into a
new, finished MCAP and reports what it kept (``Salvage``). Messages keep their log and
publish times (ns since the epoch); the source is only read.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

from mcap.writer import CompressionType, Writer

from findme_core.errors import RecordingError

from .mcap_layout import CHANNEL, VERSION
from .mcap_reader import open_mcap


@dataclass
class Salvage:
    """What ``recover`` kept: messages and chunks copied, whether the source was complete,
    and how many bytes at its end could not be used (an incomplete chunk)."""

    messages: int = 0
    bus_messages: int = 0     # of those, on bus channels (the rest: view channels)
    chunks: int = 0
    complete: bool = False
    dropped_bytes: int = 0
    reason: str = ""


def recover(src, dst) -> Salvage:
    """Rewrite the readable part of ``src`` (e.g. a recording whose writer was killed: no
    summary, a torn last chunk) into a valid, finished MCAP ``dst``: every whole chunk
    (CRC-checked), schemas, channels, metadata. Streams; memory ~ one chunk.

    Raises:
        RecordingError: ``src`` is not MCAP.
    """
    from mcap.exceptions import McapError
    from mcap.records import (Attachment, Channel, Chunk, DataEnd, Footer, Header, Message,
                              Metadata, Schema)
    from mcap.stream_reader import StreamReader, breakup_chunk
    src, dst = Path(src), Path(dst)
    if src.resolve() == dst.resolve():
        raise RecordingError("recover writes a new file: give another -o path")
    out = Salvage()
    size = src.stat().st_size
    with open_mcap(src) as f, open(dst, "wb") as g:
        w = Writer(g, compression=CompressionType.ZSTD, chunk_size=4 * 1024 * 1024)
        started = False
        sids: dict[int, int] = {0: 0}
        cids: dict[int, int] = {}
        on_bus: set[int] = set()
        good_end = 8

        def take(r) -> None:
            if isinstance(r, Schema):
                if r.id not in sids:
                    sids[r.id] = w.register_schema(name=r.name, encoding=r.encoding, data=r.data)
            elif isinstance(r, Channel):
                if r.id not in cids and r.schema_id in sids:
                    if r.metadata.get(CHANNEL) != "view":
                        on_bus.add(r.id)
                    cids[r.id] = w.register_channel(topic=r.topic, message_encoding=r.message_encoding,
                                                    schema_id=sids[r.schema_id],
                                                    metadata=dict(r.metadata))
            elif isinstance(r, Message):
                if r.channel_id in cids:
                    w.add_message(channel_id=cids[r.channel_id], log_time=r.log_time,
                                  publish_time=r.publish_time, data=r.data, sequence=r.sequence)
                    out.messages += 1
                    out.bus_messages += r.channel_id in on_bus

        reader = StreamReader(f, emit_chunks=True, record_size_limit=size)
        it = iter(reader.records)
        while True:
            try:
                r = next(it)
            except StopIteration:
                out.complete = True
                break
            except (McapError, struct.error, ValueError, OSError, MemoryError) as e:
                out.reason = f"{type(e).__name__}: {e}" if str(e) else type(e).__name__
                break
            if isinstance(r, Header):
                w.start(profile=r.profile, library=r.library or VERSION)
                started = True
            elif not started:
                raise RecordingError(f"{src}: no MCAP header")
            elif isinstance(r, Chunk):
                try:
                    inner = breakup_chunk(r, validate_crc=True)
                except Exception as e:  # noqa: BLE001 - a torn or corrupt chunk ends the salvage
                    out.reason = f"damaged chunk ({type(e).__name__}: {e})"
                    break
                for x in inner:
                    take(x)
                out.chunks += 1
            elif isinstance(r, Metadata):
                w.add_metadata(r.name, dict(r.metadata))
            elif isinstance(r, Attachment):
                w.add_attachment(create_time=r.create_time, log_time=r.log_time, name=r.name,
                                 media_type=r.media_type, data=r.data)
            elif isinstance(r, (DataEnd, Footer)):
                pass  # the summary is rebuilt
            else:
                take(r)
            good_end = f.tell()
        if not started:
            w.start(profile="", library=VERSION)
        w.finish()
    out.dropped_bytes = 0 if out.complete else max(0, size - good_end)
    return out
