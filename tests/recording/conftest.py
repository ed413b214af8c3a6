"""Shared helpers of the recording tests: golden recordings, a recording with every message
kind, MCAP rewriting, the CLI in-process, free ports."""

from __future__ import annotations

import math
import os
import socket
import threading
from pathlib import Path

import pytest

# Rerun's anonymous usage analytics stay off in tests (re_analytics skips them under CI);
# set before rerun is imported here or in any subprocess the tests start.
os.environ.setdefault("CI", "1")

import schemas  # noqa: E402
from services.runtime import bus  # noqa: E402
from services.recording.mcap_reader import read_recording  # noqa: E402
from services.recording.mcap_writer import McapRecording  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = ROOT / "recordings" / "golden"
GOLDENS = sorted(GOLDEN.glob("*.mcap"))
PAIR = GOLDEN / "examples-pair.mcap"


def rewrite(src: Path, dst: Path, change=None, extra=()) -> Path:
    """Copy a recording's bus messages to ``dst`` (views derived again), with
    ``change(key, msg)`` applied to each decodable message (it may edit the message in place)
    and ``extra`` (key, message, log_time) appended."""
    recs = read_recording(src)
    session = bus.parse_key(recs[0].key).session
    out = McapRecording(dst, session)
    for r in recs:
        payload = r.payload
        msg = r.message()
        if change is not None and msg is not None:
            change(r.key, msg)
            payload = msg.SerializeToString(deterministic=True)
        out.write(r.key, payload, r.log_time)
    t = recs[-1].log_time
    for key, msg, dt in extra:
        out.write(key, schemas.encode(msg), t + dt)
    out.close()
    return dst


def odometry_messages(session: str, t0: int):
    """Motion, poses and a trajectory for the two photos of the example pair, at their true
    values (findme/examples/pair.json), as an odometry service would publish them."""
    x, z, yaw = 0.3851, 0.593, math.radians(-18.0)
    k = lambda *p: bus.key(session, *p)  # noqa: E731
    poses = [schemas.Pose(session=session, index=0, time_ns=t0),
             schemas.Pose(session=session, index=1, x_m=x, z_m=z, yaw_rad=yaw, time_ns=t0 + 1,
                          sigma_x_m=0.05, sigma_z_m=0.05, sigma_yaw_rad=0.02)]
    motion = schemas.Motion(session=session, index_a=0, index_b=1, x_m=x, z_m=z, yaw_rad=yaw,
                            sigma_x_m=0.05, sigma_z_m=0.05, sigma_yaw_rad=0.02, inliers=80,
                            matches=120, method="test", time_ns=t0 + 2)
    traj = schemas.Trajectory(session=session, time_ns=t0 + 3)
    for p in poses:
        q = traj.poses.add()
        q.CopyFrom(p)
        q.schema, q.session = "", ""
    err = schemas.Error(session=session, key=k("selection", 7),
                        code=schemas.ErrorCode.Value("ERROR_CODE_NO_SUCH_HYPOTHESIS"),
                        message="photo 7 has no hypothesis set", time_ns=t0 + 4,
                        service="selection/test")
    return [(k("motion", 0, 1), motion, 10), (k("pose", 0), poses[0], 11),
            (k("pose", 1), poses[1], 12), (k("trajectory"), traj, 13), (k("error"), err, 14)]


@pytest.fixture(scope="session")
def full_recording(tmp_path_factory) -> Path:
    """The example pair golden plus whatever kinds it lacks among motion, poses, a trajectory
    and an error: every kind."""
    dst = tmp_path_factory.mktemp("full") / "full.mcap"
    recs = read_recording(PAIR)
    session = bus.parse_key(recs[0].key).session
    kinds = {bus.parse_key(r.key).kind for r in recs}
    extra = [e for e in odometry_messages(session, recs[-1].log_time)
             if bus.parse_key(e[0]).kind not in kinds]
    return rewrite(PAIR, dst, extra=extra)


@pytest.fixture
def cli(capsys):
    """Run ``findme ARGS`` in this process: (exit status, stdout, stderr)."""
    from findme.cli import main

    def run(*args):
        import logging
        handlers = logging.root.handlers[:]   # commands configure logging to the captured
        try:                                  # stderr: undo it, that stream closes
            rc = main([str(a) for a in args])
        finally:
            logging.root.handlers[:] = handlers
        out = capsys.readouterr()
        return rc, out.out, out.err
    return run


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Arrivals:
    """Counts messages under a key expression on a Zenoh session; wait on it, no polling."""

    def __init__(self, session, keyexpr: str):
        self.cv = threading.Condition()
        self.items: list[tuple[str, bytes]] = []
        self.sub = session.declare_subscriber(keyexpr, self._cb)

    def _cb(self, sample) -> None:
        with self.cv:
            self.items.append((str(sample.key_expr), sample.payload.to_bytes()))
            self.cv.notify_all()

    def wait_count(self, n: int, timeout: float = 30.0) -> bool:
        with self.cv:
            return self.cv.wait_for(lambda: len(self.items) >= n, timeout)

    def close(self) -> None:
        self.sub.undeclare()


def wait_service(session, name: str, timeout: float = 60.0) -> None:
    """Until a liveliness token of service ``name`` is on the bus."""
    bus.wait_alive(session, name, timeout)


