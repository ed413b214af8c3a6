import socket
import subprocess
import sys
import threading

import cv2
import pytest

import schemas
from services.runtime.bus import BusConfig, open_session
from findme_io.convert import make_frame


@pytest.fixture
def zsession():
    """An in-process Zenoh session (no network)."""
    s = open_session(BusConfig())
    yield s
    s.close()


def jpeg(image) -> bytes:
    return cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()


def frame_of(view, session="t1", index=0, height=True):
    c = view.camera
    return make_frame(session, index, jpeg(view.image),
                      intrinsics=(c.fx, c.fy, c.cx, c.cy, c.width, c.height),
                      gravity=c.gravity, camera_height_m=view.camera_height if height else None)


class Collector:
    """Subscribes to a key expression; ``wait(n)`` blocks until n messages arrived."""

    def __init__(self, session, key):
        self.items, self.cv = [], threading.Condition()
        self.sub = session.declare_subscriber(key, self._cb)

    def _cb(self, sample):
        with self.cv:
            self.items.append((str(sample.key_expr), sample.payload.to_bytes()))
            self.cv.notify_all()

    def wait(self, n=1, timeout=30.0):
        with self.cv:
            assert self.cv.wait_for(lambda: len(self.items) >= n, timeout), \
                f"only {len(self.items)} of {n} messages arrived"
            return list(self.items)

    def decoded(self, cls, n=1):
        return [schemas.decode(cls, p) for _, p in self.wait(n)]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def spawn_findme(*args):
    """Spawn ``findme ARGS`` (a new interpreter); its stderr lines are collected (and the pipe
    drained) by a thread into ``proc.lines``, announced on ``proc.new_line`` (Condition)."""
    proc = subprocess.Popen([sys.executable, "-m", "findme.cli", *map(str, args)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    proc.lines, proc.new_line = [], threading.Condition()

    def drain():
        for line in proc.stderr:
            with proc.new_line:
                proc.lines.append(line)
                proc.new_line.notify_all()
    threading.Thread(target=drain, daemon=True).start()
    return proc


def wait_logged(proc, text: str, timeout: float = 60.0) -> None:
    """Block until ``proc`` logs a line containing ``text`` (its readiness signal)."""
    with proc.new_line:
        assert proc.new_line.wait_for(lambda: any(text in x for x in proc.lines), timeout), \
            f"no {text!r} from {proc.args[3:]} in {timeout:.0f} s: {''.join(proc.lines)[-2000:]}"
