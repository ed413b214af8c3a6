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
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from findme_core.errors import FindmeError, InputError

from ..runtime import authority, bus
from .mcap_layout import parse
from ..runtime.handler import Handler, Input

log = logging.getLogger("findme.services.viewer")

APP_ID = "findme"


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
        """Point a recording stream at this sink; returns where it goes (for the user)."""
        if self.mode == "rrd":
            p = Path(self.path or ".")
            if p.suffix != ".rrd":
                p.mkdir(parents=True, exist_ok=True)
                p = p / f"{session}.rrd"
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
    """Shows every session's messages in Rerun (one recording per session)."""

    name = "viewer"
    inputs = (Input(f"{bus.ROOT}/*/**", None),)
    drain_on_stop = True

    def __init__(self, sink: Sink | None = None, clock=time.time_ns):
        from findme_io.rerun_views import SessionView  # noqa: F401 - fail early if rerun is missing
        self.sink = sink or Sink.default()
        self.clock = clock
        self.views: dict[str, object] = {}
        self.where: dict[str, str] = {}
        self.shown = 0
        self.failed = 0
        self._lock = threading.Lock()

    def _view(self, session: str):
        v = self.views.get(session)
        if v is None:
            from findme_io.rerun_views import SessionView
            rec = new_recording(session)
            self.where[session] = self.sink.attach(rec, session)
            v = self.views[session] = SessionView(rec)
            log.info("viewer: session %s -> %s", session, self.where[session])
        return v

    def on_message(self, key, payload):
        t = self.clock()
        try:
            session = bus.parse_key(key).session
        except FindmeError:
            return []
        msg, _ = parse(payload)
        if msg is None:
            return []
        with self._lock:
            try:
                authority.check(key, msg)   # drawn under its key's session and n only
                if self._view(session).log(msg, t):
                    self.shown += 1
            except FindmeError as e:  # a message it cannot draw (bad camera, ...): skip it
                self.failed += 1
                log.warning("viewer: cannot show %s: %s", key, e)
        return []

    def close(self) -> None:
        with self._lock:
            for v in self.views.values():
                try:
                    v.rec.flush()
                    v.rec.disconnect()
                except Exception as e:  # noqa: BLE001 - closing must not fail the stop
                    log.warning("viewer: closing a recording: %s", e)
            self.views.clear()

    def counters(self):
        return {"shown": self.shown, "not_shown": self.failed, "sessions": len(self.views)}


def make_viewer(args) -> ViewerHandler:
    """``findme serve viewer``: a viewer it spawns when there is a display, else ``.rrd``
    files in ``--out`` (default recordings/)."""
    out = getattr(args, "out", None)
    return ViewerHandler(Sink.default(out if out and out != "." else "recordings"))
