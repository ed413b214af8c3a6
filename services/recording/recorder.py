"""The recorder service: every key of every session into ``<out>/<session>.mcap``.

    findme/<session>/**  ->  <out>/<session>.mcap   (one file per session)

What a recording holds: bus channels (``services.mcap_layout``) and the Foxglove view
channels (``services.foxglove_view``); recordings/README.md has the full table. The file is
written by ``services.mcap_writer``, read by ``services.mcap_reader`` and salvaged by
``services.mcap_recover``.

Durability: chunked MCAP; a flusher thread closes the open chunk and flushes the file every
``flush_s`` (0.5 s), so a recorder killed with SIGKILL loses at most the last
``FLUSH_BOUND_S`` = 1 s (flush period + queueing); ``findme recover`` salvages such a file.
A file that exists is never overwritten: the next one is ``<session>~2.mcap``.

One file per session, however many sessions are live: the recorder keeps file handles for
the ``max_open`` (64) most recently written sessions; a quieter one is flushed and its
handle closed, and reopened for appending when its next message comes (never a new file).
A new file for a session comes only when asked for, and is logged: ``rotate_bytes`` /
``rotate_s`` (off by default) finish a file that has grown that large or old, and a session
quiet for ``idle_close_s`` (600 s, ``findme serve recorder --idle``) has its file finished
(summary written, memory freed); if it speaks again it continues in ``<session>~2.mcap``.

Log time of a message = when the recorder received it (ns since the epoch). Write failures
(disk full) are logged and counted, never published as bus errors (the recorder would
record its own errors in a loop).
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path

from collections import OrderedDict

from findme_core.errors import FindmeError, InputError

from ..runtime import bus
from .mcap_writer import COMPRESSIONS, McapRecording, recording_path
from ..runtime.handler import Handler, Input

log = logging.getLogger("findme.services.recorder")

#: A recorder killed with SIGKILL loses at most the messages it received in this many
#: seconds before it died (flush period + queueing); tested in tests/recording.
FLUSH_BOUND_S = 1.0
FLUSH_S = 0.5


class RecorderHandler(Handler):
    """Writes every message of every session to ``<out>/<session>.mcap``."""

    name = "recorder"
    background = True    # not on the way from a photo to its pose (``Handler.background``)
    inputs = (Input(f"{bus.ROOT}/*/**", None),)
    queue_depth = 4096        # a session's burst waits here (64 MB a session at most)
    drain_on_stop = True
    report_overload = False   # its own errors would be recorded: logged and counted instead

    def __init__(self, out_dir: str | Path = "recordings", *, flush_s: float = FLUSH_S,
                 compression: str = "zstd", chunk_size: int = 4 * 1024 * 1024,
                 views: bool = True, max_open: int = 64, idle_close_s: float | None = 600.0,
                 rotate_bytes: int | None = None, rotate_s: float | None = None,
                 clock=time.time_ns):
        if compression not in COMPRESSIONS:
            raise InputError(f"compression {compression!r} is not one of {sorted(COMPRESSIONS)}")
        if max_open < 1:
            raise InputError(f"max_open must be at least 1, got {max_open}")
        self.out = Path(out_dir)
        self.flush_s, self.compression, self.chunk_size = flush_s, compression, chunk_size
        self.views, self.max_open, self.idle_close_s = views, max_open, idle_close_s
        self.rotate_bytes, self.rotate_s = rotate_bytes, rotate_s
        self.clock = clock
        self.files: dict[str, McapRecording] = {}
        self.handles: OrderedDict[str, McapRecording] = OrderedDict()   # open file handles, LRU
        self.paths: dict[str, list[Path]] = {}     # session -> every file written for it
        self.recorded = 0
        self.write_errors = 0
        self.suspends = self.rotations = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._flusher: threading.Thread | None = None
        self.opened = threading.Condition(self._lock)  # notified when a file is opened
        self.wrote = threading.Condition(self._lock)   # notified after each recorded message

    # ------------------------------------------------------------------ files
    def path_of(self, session: str) -> Path | None:
        """The file a session is being (or was last) recorded to."""
        with self._lock:
            p = self.paths.get(session)
            return p[-1] if p else None

    def _open(self, session: str) -> McapRecording:
        self.out.mkdir(parents=True, exist_ok=True)
        path = recording_path(self.out, session)
        rec = McapRecording(path, session, compression=self.compression,
                            chunk_size=self.chunk_size, views=self.views,
                            metadata={"flush_s": f"{self.flush_s:g}",
                                      "started_ns": str(self.clock())})
        self.files[session] = rec
        self.paths.setdefault(session, []).append(path)
        log.info("recorder: session %s -> %s", session, path)
        self.opened.notify_all()
        if self._flusher is None:
            self._flusher = threading.Thread(target=self._flush_loop, name="recorder-flush",
                                             daemon=True)
            self._flusher.start()
        return rec

    def _close(self, session: str) -> None:
        rec = self.files.pop(session, None)
        self.handles.pop(session, None)
        if rec is not None:
            try:
                rec.close()
            except OSError as e:
                self.write_errors += 1
                log.error("recorder: cannot finish %s: %s", rec.path, e)

    def _flush_loop(self) -> None:
        while not self._stop.wait(self.flush_s):
            self.flush()

    def flush(self) -> None:
        """Flush every open file (the flusher thread does this every ``flush_s``)."""
        now = time.monotonic()
        with self._lock:
            for session, rec in list(self.files.items()):
                try:
                    rec.flush()
                except OSError as e:
                    self.write_errors += 1
                    log.error("recorder: cannot flush %s: %s", rec.path, e)
                if self.idle_close_s is not None and now - rec.last_write > self.idle_close_s:
                    log.info("recorder: session %s quiet for %.0f s: %s finished (a later "
                             "message starts a new file)", session, now - rec.last_write, rec.path)
                    self._close(session)

    # ------------------------------------------------------------------ handler
    def on_message(self, key, payload):
        t = self.clock()
        try:
            session = bus.parse_key(key).session
        except FindmeError as e:
            log.warning("recorder: not recorded: %s", e)
            return []
        with self._lock:
            try:
                rec = self.files.get(session)
                if rec is not None and self._rotate_due(rec):
                    self.rotations += 1
                    log.info("recorder: rotating %s (%.1f MB, %.0f s old; rotate_bytes=%s, "
                             "rotate_s=%s)", rec.path, rec.size / 1e6,
                             (t - rec.started_ns) / 1e9, self.rotate_bytes, self.rotate_s)
                    self._close(session)
                    rec = None
                rec = rec or self._open(session)
                rec.write(key, payload, t)
                self._hold(session, rec)
                self.recorded += 1
                self.wrote.notify_all()
            except (OSError, ValueError) as e:
                self.write_errors += 1
                log.error("recorder: cannot record %s: %s", key, e)
        return []

    def _rotate_due(self, rec: McapRecording) -> bool:
        return ((self.rotate_bytes is not None and rec.size >= self.rotate_bytes) or
                (self.rotate_s is not None and self.clock() - rec.started_ns >= self.rotate_s * 1e9))

    def _hold(self, session: str, rec: McapRecording) -> None:
        """(under the lock) ``session`` holds a file handle now; the least recently written
        beyond ``max_open`` give theirs up (flushed; reopened for appending when needed)."""
        self.handles[session] = rec
        self.handles.move_to_end(session)
        while len(self.handles) > self.max_open:
            _, old = self.handles.popitem(last=False)
            try:
                old.suspend()
                self.suspends += 1
            except OSError as e:
                self.write_errors += 1
                log.error("recorder: cannot flush %s: %s", old.path, e)

    def wait_recorded(self, n: int, timeout: float = 30.0) -> bool:
        """Block until at least ``n`` messages have been recorded since the start (False on
        timeout): the signal to wait on before stopping, since messages still in flight on
        the bus are not yet queued."""
        with self._lock:
            return self.wrote.wait_for(lambda: self.recorded >= n, timeout)

    def close(self) -> None:
        """Finish every file (summary and indexes): they are then valid without recovery."""
        self._stop.set()
        if self._flusher is not None:
            self._flusher.join(5.0)
        with self._lock:
            for session in list(self.files):
                self._close(session)

    def counters(self):
        with self._lock:
            return {"recorded": self.recorded, "open_files": len(self.files),
                    "open_handles": len(self.handles), "suspends": self.suspends,
                    "rotations": self.rotations, "write_errors": self.write_errors}


def make_recorder(args) -> RecorderHandler:
    """``findme serve recorder --out DIR``: recordings go to DIR (default: recordings/)."""
    out = getattr(args, "out", None)
    return RecorderHandler(out if out and out != "." else "recordings",
                           idle_close_s=getattr(args, "idle", 600.0))
