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

    def until(self, done, timeout=60.0, what="messages"):
        """Block until ``done(items)`` ((key, payload) in arrival order); returns them."""
        with self.cv:
            assert self.cv.wait_for(lambda: done(self.items), timeout), \
                f"{what}: not within {timeout:.0f} s; seen {[k for k, _ in self.items]}"
            return list(self.items)

    def keys(self):
        with self.cv:
            return [k for k, _ in self.items]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def spawn_findme(*args, **popen):
    """Spawn ``findme ARGS`` (a new interpreter; ``popen``: more Popen arguments); its stderr
    lines are collected (and the pipe drained) by a thread into ``proc.lines``, announced on
    ``proc.new_line`` (Condition)."""
    proc = subprocess.Popen([sys.executable, "-m", "findme.cli", *map(str, args)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, **popen)
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


class ProcBus:
    """A router and services, each its own process (``findme router`` / ``findme serve``),
    and a client session for the test. Waits on log lines and liveliness, never sleeps."""

    def __init__(self):
        import zenoh  # noqa: F401 - the session below needs it loaded
        from services.runtime.bus import BusConfig, open_session
        self.ep = f"tcp/127.0.0.1:{free_port()}"
        self.router = spawn_findme("router", "--listen", self.ep)
        wait_logged(self.router, "listening on")
        self.procs: dict[str, subprocess.Popen] = {}
        self.client = open_session(BusConfig(mode="client", connect=(self.ep,)))

    def serve(self, name: str, instance: str, *args, wait: bool = True):
        """Start service ``name`` as instance ``instance`` (its liveliness token is the
        signal that it is up)."""
        import zenoh
        up = threading.Event()
        sub = self.client.liveliness().declare_subscriber(
            f"findme/@services/{name}/{instance}",
            lambda s: s.kind == zenoh.SampleKind.PUT and up.set(), history=True)
        self.procs[instance] = spawn_findme("serve", name, "--connect", self.ep,
                                            "--instance", instance, *args)
        try:
            if wait:
                assert up.wait(60), f"{name}/{instance} did not come up: " \
                                    f"{''.join(self.procs[instance].lines)[-2000:]}"
        finally:
            sub.undeclare()
        return self.procs[instance]

    def kill(self, name: str, instance: str) -> None:
        """SIGKILL an instance; returns once its liveliness token is gone."""
        import signal

        import zenoh
        gone = threading.Event()
        sub = self.client.liveliness().declare_subscriber(
            f"findme/@services/{name}/{instance}",
            lambda s: s.kind == zenoh.SampleKind.DELETE and gone.set())
        self.procs[instance].send_signal(signal.SIGKILL)
        self.procs[instance].wait(20)
        try:
            assert gone.wait(20), f"{name}/{instance}'s token did not go away"
        finally:
            sub.undeclare()

    def status(self, name: str, instance: str):
        from services.runtime.bus import get_all
        for _, p in get_all(self.client, f"findme/@services/{name}/{instance}/status", 10):
            return schemas.decode(schemas.ServiceStatus, p)
        raise AssertionError(f"no status from {name}/{instance}")

    def wait_status(self, name: str, instance: str, predicate, timeout: float = 30.0):
        """Ask for the instance's status until ``predicate(status)`` holds (each ask is a
        round trip to it, paced by a short wait for its reply); returns the status."""
        import time
        deadline, st = time.monotonic() + timeout, None
        pace = threading.Event()
        while time.monotonic() < deadline:
            st = self.status(name, instance)
            if predicate(st):
                return st
            pace.wait(0.05)
        raise AssertionError(f"{name}/{instance} status never matched: {st}")

    def close(self) -> dict:
        """Stop everything (SIGTERM); returns the exit codes."""
        import signal
        self.client.close()
        procs = {**self.procs, "router": self.router}
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        return {n: p.wait(20) for n, p in procs.items()}


def walk_views(n: int, width: int = 160, height: int = 120):
    """``n`` small rendered photos walking slowly through one room (successive photos
    overlap, so their motion can be estimated)."""
    from findme_core.synth.render import Pose, Room, render
    room = Room.rectangle(5.0, 6.0, floor_style="wood")
    return [render(room, Pose(-0.3 + 0.04 * i, -1.8 + 0.08 * i, 1.4, yaw_deg=10 - 2 * i,
                              pitch_deg=27), width, height, hfov_deg=70, seed=5) for i in range(n)]


COMPOSE = __import__("pathlib").Path(__file__).resolve().parents[2] / "compose"


def start_tls_router(tmp, users: dict[str, str]):
    """compose/router-tls.json5 for real on loopback: certificates made in ``tmp`` (needs
    the ``cryptography`` package), ``users`` {name: password}; returns (router process,
    endpoint, TLS settings for a client, path of a service config for the "server" user)."""
    pytest.importorskip("cryptography", reason="cryptography generates the test certificates")
    sys.path.insert(0, str(COMPOSE.parent / "tools"))
    from make_certs import local_configs, make_certs
    make_certs(tmp, ("localhost", "127.0.0.1"))
    (tmp / "users.txt").write_text("".join(f"{u}:{p}\n" for u, p in users.items()))
    endpoint = f"tls/127.0.0.1:{free_port()}"
    cfg = local_configs(tmp, connect=endpoint, listen=endpoint)   # as compose/README says
    (tmp / "router.json5").write_text(cfg["router"].read_text())
    (tmp / "service.json5").write_text(cfg["service"].read_text())
    proc = spawn_findme("router", "--config", tmp / "router.json5")
    wait_logged(proc, "listening on")
    return proc, endpoint, {"root_ca_certificate": str(tmp / "ca.pem")}, tmp / "service.json5"


def assert_example_motion(out: str, tol_m: float = 0.01, tol_deg: float = 0.2) -> None:
    """The bundled example pair's motion line in a run report (``findme run`` / ``send``)
    is the rendered truth (findme/examples/pair.json) within ``tol_m`` and ``tol_deg``."""
    import json
    import re
    from pathlib import Path
    truth = json.loads((Path(__file__).resolve().parents[2] / "findme" / "examples"
                        / "pair.json").read_text())["motion"]
    m = re.search(r"motion 0 -> 1: x ([+-][\d.]+) m, z ([+-][\d.]+) m, yaw ([+-][\d.]+) deg", out)
    assert m, out
    x, z, yaw = map(float, m.groups())
    assert abs(x - truth["x_m"]) < tol_m and abs(z - truth["z_m"]) < tol_m, (m.group(0), truth)
    assert abs(yaw - truth["yaw_deg"]) < tol_deg, (m.group(0), truth)
