"""The viewer service: every session on the bus shown in Rerun as it happens.

    findme/<session>/**  ->  a Rerun recording per session (recording id = session id)

Where the recordings go (``Sink``): a viewer this process starts (``spawn``: the native
viewer, or ``web``: the web viewer), one already running (``connect``), or ``.rrd`` files
(``rrd``: ``<dir>/<session>.rrd``; the default when there is no display). Servers it
starts bind 127.0.0.1 unless another address is given (the Rerun CLI and SDK default to
0.0.0.0, i.e. every network the machine is on). What is drawn and where: ``findme_io.rerun_views``.
"""

from __future__ import annotations

import logging
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from findme_core.errors import FindmeError, InputError

from ..runtime import authority, bus
from .mcap_layout import parse
from ..runtime.handler import Handler, Input

log = logging.getLogger("findme.services.viewer")

APP_ID = "findme"
#: what Rerun keeps, never freed, per stream (recording or layout) and per photo drawn, MB
STREAM_MB, PHOTO_MB = 0.7, 0.05


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                or sys.platform in ("darwin", "win32"))


def _rerun_cli() -> list[str]:
    """The Rerun viewer/CLI binary of the installed wheel (not its Python wrapper, so the
    process we start is the server itself), else ``rerun`` on PATH."""
    try:
        import rerun_cli
        exe = Path(rerun_cli.__file__).with_name("rerun.exe" if sys.platform == "win32" else "rerun")
        if exe.exists():
            return [str(exe)]
    except ImportError:
        pass
    exe = shutil.which("rerun")
    return [exe] if exe else [sys.executable, "-m", "rerun_cli"]


def _free_port(bind: str) -> int:
    import socket
    with socket.socket() as s:
        s.bind((bind, 0))
        return s.getsockname()[1]


@dataclass
class Sink:
    """Where recordings go: mode "rrd" (``path``: a file, or a folder for one file per
    session), "connect" (``url``), "spawn" (native viewer) or "web" (web viewer); ``bind``
    and ``port`` for the servers this process starts."""

    mode: str = "rrd"
    path: str | None = None
    url: str | None = None
    bind: str = "127.0.0.1"
    port: int | None = None
    web_port: int | None = None
    _proc: subprocess.Popen | None = None

    @classmethod
    def default(cls, out_dir: str = "recordings") -> "Sink":
        return cls("spawn") if has_display() else cls("rrd", path=out_dir)

    def start(self) -> None:
        """Start the viewer process for spawn / web (once); sets ``url``."""
        if self.mode not in ("spawn", "web") or self._proc is not None:
            return
        port = self.port or _free_port(self.bind)
        wport = self.web_port or _free_port(self.bind)
        cmd = self.command(port, wport)
        env = dict(os.environ)
        self._proc = subprocess.Popen(cmd, env=env, stdin=subprocess.DEVNULL,
                                      start_new_session=True)
        self.url = f"rerun+http://{self.bind}:{port}/proxy"
        if self.mode == "web":
            print(f"Rerun web viewer: http://{self.bind}:{wport}/?url={self.url}", flush=True)
        log.info("viewer: started %s (pid %d)", " ".join(cmd), self._proc.pid)

    def command(self, port: int, web_port: int) -> list[str]:
        """The viewer process for spawn / web: gRPC (and web) servers on ``bind`` only."""
        cmd = [*_rerun_cli(), "--bind", self.bind, "--port", str(port)]
        if self.mode == "web":
            cmd += ["--serve-web", "--web-viewer-port", str(web_port)]
        return cmd

    def stop(self) -> None:
        """Stop the viewer process this sink started (a spawned native viewer is left
        running for the user: it is theirs to close)."""
        if self._proc is not None and self.mode == "web":
            self._proc.terminate()
            self._proc.wait(10)

    def attach(self, rec, session: str, blueprint=None) -> str:
        """Point a recording stream at this sink; returns where it goes (for the user).
        A session shown again after it was closed (idle) goes to ``<session>.<k>.rrd``
        beside the first file (Rerun merges the files of one recording id when opened)."""
        if self.mode == "rrd":
            p = Path(self.path or ".")
            if p.suffix != ".rrd":
                p.mkdir(parents=True, exist_ok=True)
                p = p / f"{session}.rrd"
                k = 1
                while p.exists():
                    p, k = p.with_name(f"{session}.{k}.rrd"), k + 1
            else:
                p.parent.mkdir(parents=True, exist_ok=True)
            rec.save(str(p), default_blueprint=blueprint)
            return str(p)
        if self.mode in ("spawn", "web"):
            self.start()
        elif self.mode != "connect":
            raise InputError(f"viewer sink must be rrd, connect, spawn or web, not {self.mode!r}")
        rec.connect_grpc(self.url, default_blueprint=blueprint)
        return self.url or "rerun+http://127.0.0.1:9876/proxy"


def new_recording(session: str):
    import rerun as rr
    return rr.RecordingStream(APP_ID, recording_id=session)


class ViewerHandler(Handler):
    """Shows every session's messages in Rerun (one recording per session).

    A session idle for ``idle_s`` is closed (its file finished), and beyond ``max_open`` the
    least recently used one is; it opens again (a new file part) if it comes back.

    Rerun never frees what a Python process made (rerun#2116): a recording stream or a
    layout sent (each a stream: ``rerun_session``) keeps 0.7 MB and a thread, and each photo
    drawn about 0.05 MB of entities (measured: 3,000 sessions 2.2 GB even when closed; 3,000
    photos of one session 147 MB). Closing finishes files but frees nothing, so ``max_open``
    defaults to no limit (with 64 the bus fuzz's 100 sessions coming and going made 1,000
    streams). The handler adds up that cost, and past ``budget_mb`` it calls ``on_full``
    once: ``findme serve viewer`` then stops cleanly (every file finished) for its
    supervisor to start it afresh, as gunicorn's ``max_requests`` does for a leaking worker.
    """

    name = "viewer"
    inputs = (Input(f"{bus.ROOT}/*/**", None),)
    drain_on_stop = True
    tick_s = 5.0

    def __init__(self, sink: Sink | None = None, clock=time.time_ns, idle_s: float = 600.0,
                 max_open: int | None = None, monotonic=time.monotonic,
                 budget_mb: float = 1024.0, on_full: Callable[[], None] | None = None):
        from findme_io.rerun_session import SessionView  # noqa: F401 - fail early
        max_open = 1 << 30 if max_open is None else max_open
        if idle_s <= 0 or max_open < 1:
            raise InputError(f"viewer: idle must be > 0 s and max_open >= 1, got {idle_s}, {max_open}")
        self.sink = sink or Sink.default()
        self.clock, self.monotonic = clock, monotonic
        self.idle_s, self.max_open = idle_s, max_open
        self.views: OrderedDict[str, object] = OrderedDict()   # least recently used first
        self._used: dict[str, float] = {}
        self.where: dict[str, str] = {}
        self.shown = self.handled = 0
        self.failed = 0
        self.closed = 0
        self.streams, self.photos, self.budget_mb, self.on_full = 0, 0, budget_mb, on_full
        self._lock = threading.Lock()
        self._seen = threading.Condition(self._lock)

    def wait_handled(self, n: int, timeout: float = 30.0) -> bool:
        """Block until at least ``n`` messages were handled (shown or not drawable; False on
        timeout): the signal to wait on before stopping, as the recorder's
        ``wait_recorded``: messages still in flight on the bus are not yet queued."""
        with self._seen:
            return self._seen.wait_for(lambda: self.handled >= n, timeout)

    def _view(self, session: str):
        v = self.views.get(session)
        if v is None:
            from findme_io.rerun_session import SessionView
            rec = new_recording(session)
            self.where[session] = self.sink.attach(rec, session)
            v = self.views[session] = SessionView(rec)
            log.info("viewer: session %s -> %s", session, self.where[session])
            self._made(1 + v.layouts, 0)
            while len(self.views) > self.max_open:
                self._close(next(iter(self.views)), "more than %d open" % self.max_open)
        self.views.move_to_end(session)
        self._used[session] = self.monotonic()
        return v

    def cost_mb(self) -> float:
        """What Rerun holds for this process and never frees, estimated (class docstring)."""
        return STREAM_MB * self.streams + PHOTO_MB * self.photos

    def _made(self, streams: int, photos: int) -> None:
        """Count Rerun streams and photos made; past the budget ask, once, to be restarted."""
        before = self.cost_mb()
        self.streams += streams
        self.photos += photos
        if before < self.budget_mb <= self.cost_mb() and self.on_full is not None:
            log.warning("viewer: about %.0f MB held by Rerun (%d streams, %d photos), which it "
                        "does not free: stopping so that the supervisor starts a fresh viewer",
                        self.cost_mb(), self.streams, self.photos)
            self.on_full()

    def _close(self, session: str, why: str) -> None:
        v = self.views.pop(session)
        self._used.pop(session, None)
        self.where.pop(session, None)
        self.closed += 1
        try:
            v.rec.flush()
            v.rec.disconnect()
        except Exception as e:  # noqa: BLE001 - closing one must not stop the others
            log.warning("viewer: closing session %s: %s", session, e)
        log.info("viewer: session %s closed (%s)", session, why)

    def tick(self, now):
        with self._lock:
            for session in [s for s in self.views if now - self._used[s] > self.idle_s]:
                self._close(session, f"idle for {self.idle_s:g} s")
        return []

    def on_message(self, key, payload):
        t = self.clock()
        try:
            self._show(key, payload, t)
        finally:
            with self._seen:
                self.handled += 1
                self._seen.notify_all()
        return []

    def _show(self, key, payload, t) -> None:
        try:
            session = bus.parse_key(key).session
        except FindmeError:
            return
        msg, _ = parse(payload)
        if msg is None:
            return
        with self._lock:
            try:
                authority.check(key, msg)   # drawn under its key's session and n only
                v = self._view(session)
                before = v.layouts, len(v.indices)
                if v.log(msg, t):
                    self.shown += 1
                self._made(v.layouts - before[0], len(v.indices) - before[1])
            except FindmeError as e:  # a message it cannot draw (bad camera, ...): skip it
                self.failed += 1
                log.warning("viewer: cannot show %s: %s", key, e)

    def close(self) -> None:
        with self._lock:
            for session in list(self.views):
                self._close(session, "service stopping")

    def counters(self):
        return {"shown": self.shown, "not_shown": self.failed, "sessions": len(self.views),
                "sessions_closed": self.closed, "rerun_streams": self.streams,
                "rerun_photos": self.photos, "rerun_mb": round(self.cost_mb(), 1)}


def make_viewer(args) -> ViewerHandler:
    """``findme serve viewer``: a viewer it spawns when there is a display, else ``.rrd``
    files in ``--out`` (default recordings/)."""
    out = getattr(args, "out", None)
    return ViewerHandler(Sink.default(out if out and out != "." else "recordings"),
                         idle_s=getattr(args, "idle", 600.0),
                         on_full=lambda: os.kill(os.getpid(), signal.SIGTERM))
