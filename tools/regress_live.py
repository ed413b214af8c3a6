"""``findme regress`` on live recordings: no false failures, and a real change still fails.

    python tools/regress_live.py [--sessions 20] [--keep DIR]

Starts ``findme up`` (router, store, one hypotheses worker, selection, measurement,
odometry, the mapper, the recorder) on a free port, sends ``--sessions`` sessions with
``findme send`` in turn (the bundled example pair, four photos turning at one spot of a
rendered room, two photos of a rendered L-shaped room, one photo of a rendered room with a
cabinet: each with its camera, gravity and height), waits after each for the mapper's plan of
all its photos, stops ``findme up`` (the recorder finishes every file), then runs
``findme regress`` on each recording. Then one recording is copied with its photo 0's best
boundary moved 5 px, and regress must fail naming it.

Prints each regress's verdict and a summary (false failures out of N; the changed copy
caught), and exits 1 when a recording fails or the change is not caught. Writes only into a
temporary directory (``--keep DIR``: there).
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def render_photos(out: Path) -> dict[str, tuple[list[str], list[str]]]:
    """The rendered sessions' photos (JPEG files) and their ``findme send`` camera flags:
    {kind: (files, flags)}; the example pair is ``findme send``'s default (no files)."""
    import cv2

    from findme_core.synth.room import Box, Pose, Room
    from findme_core.synth.render import render
    out.mkdir(parents=True, exist_ok=True)

    def shoot(name, room, poses, hfov=70.0):
        files, flags = [], []
        for k, p in enumerate(poses):
            v = render(room, p, 640, 480, hfov_deg=hfov, seed=k)
            f = out / f"{name}-{k}.jpg"
            cv2.imwrite(str(f), v.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
            files.append(str(f))
            g = v.camera.gravity
            flags = ["--hfov", f"{hfov:g}", "--gravity", ",".join(f"{x:.6f}" for x in g),
                     "--camera-height", f"{p.height:g}"]
        return files, flags

    rect = Room.rectangle(4.5, 3.5)
    box = Room.rectangle(5.0, 6.0, floor_style="wood",
                         boxes=(Box(0.2, 1.2, 0.8, 0.5, 0.7, yaw_deg=15.0),))
    return {
        "example": ([], []),
        "turn": shoot("turn", rect, [Pose(0.3, -0.2, 1.4, float(y), 28.0, 0.0)
                                     for y in (0, 60, 120, 180)]),
        "lroom": shoot("lroom", Room.l_shape(), [Pose(-1.5, -1.5, 1.5, 30.0, 20.0, 0.0),
                                                 Pose(-1.0, -1.2, 1.5, 55.0, 20.0, 0.0)]),
        "box": shoot("box", box, [Pose(0.4, -1.8, 1.4, 20.0, 20.0, 3.0)]),
    }


class Plans:
    """The latest plan of every session on the bus (a client of the router)."""

    def __init__(self, endpoint: str):
        import schemas
        from services.runtime import bus
        self.schemas, self.bus = schemas, bus
        self.session = bus.open_session(bus.BusConfig(mode="client", connect=(endpoint,)))
        self.cv, self.latest = threading.Condition(), {}
        self.sub = self.session.declare_subscriber(f"{bus.ROOT}/*/plan", self._cb)

    def _cb(self, sample):
        k = self.bus.parse_key(str(sample.key_expr))
        msg = self.schemas.decode(self.schemas.Plan, sample.payload.to_bytes(), check=False)
        with self.cv:
            self.latest[k.session] = msg
            self.cv.notify_all()

    def wait(self, session: str, n: int, timeout: float) -> bool:
        """Until the session's plan took in all its ``n`` photos (or says why it cannot)."""
        def done():
            p = self.latest.get(session)
            return p is not None and len(p.poses) >= n and p.photos >= n
        with self.cv:
            return self.cv.wait_for(done, timeout)

    def close(self):
        self.sub.undeclare()
        self.session.close()


def start_up(port: int, out: Path, log: Path) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "findme.cli", "up", "--listen", f"tcp/127.0.0.1:{port}",
           "--hypotheses", "1", "--out", str(out), "--quiet"]
    f = open(log, "w")
    p = subprocess.Popen(cmd, cwd=ROOT, stdout=f, stderr=subprocess.STDOUT,
                         env={**os.environ, "PYTHONPATH": str(ROOT)}, start_new_session=True)
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        if p.poll() is not None:
            raise SystemExit(f"findme up exited ({p.returncode}): see {log}")
        if "ready" in log.read_text():
            return p
        time.sleep(0.5)
    stop(p)
    raise SystemExit(f"findme up did not say ready within 180 s: see {log}")


def stop(p: subprocess.Popen) -> None:
    if p.poll() is None:
        os.killpg(p.pid, signal.SIGINT)
        try:
            p.wait(60)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def moved_copy(src: Path, dst: Path, dv: float = 5.0) -> Path:
    """``src`` with photo 0's best boundary (its hypotheses' rank 1) moved ``dv`` px down at
    its second vertex: what a real regression of the boundary looks like."""
    from services.recording.mcap_reader import read_recording
    from services.recording.mcap_writer import McapRecording
    from services.runtime import bus
    recs = read_recording(src)
    out = McapRecording(dst, bus.parse_key(recs[0].key).session)
    for r in recs:
        payload, msg = r.payload, r.message()
        if msg is not None and bus.parse_key(r.key).kind == "hypotheses" and msg.index == 0:
            msg.hypotheses[0].polyline.points[1].v += dv
            payload = msg.SerializeToString(deterministic=True)
        out.write(r.key, payload, r.log_time)
    out.close()
    return dst


def regress(path: Path) -> tuple[bool, str, float]:
    """``findme regress`` in a subprocess: (passed, its report, CPU seconds)."""
    t0 = os.times()
    r = subprocess.run([sys.executable, "-m", "findme.cli", "regress", str(path)], cwd=ROOT,
                       capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    t1 = os.times()
    cpu = (t1.children_user + t1.children_system) - (t0.children_user + t0.children_system)
    return r.returncode == 0, r.stdout + r.stderr, cpu


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sessions", type=int, default=20)
    ap.add_argument("--keep", type=Path, help="keep the photos, recordings and logs here")
    ap.add_argument("--timeout", type=float, default=240.0,
                    help="seconds to wait for one session's results and plan (240)")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = a.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        rec_dir = work / "recordings"
        kinds = render_photos(work / "photos")
        order = list(kinds)
        port = free_port()
        endpoint = f"tcp/127.0.0.1:{port}"
        up = start_up(port, rec_dir, work / "up.log")
        sessions = []
        try:
            plans = Plans(endpoint)
            for i in range(a.sessions):
                kind = order[i % len(order)]
                files, flags = kinds[kind]
                sid = f"live-{i:02d}-{kind}"
                n = len(files) or 2
                t = time.monotonic()
                r = subprocess.run([sys.executable, "-m", "findme.cli", "send", *files, *flags,
                                    "--session", sid, "--connect", endpoint, "--quiet",
                                    "--timeout", str(a.timeout)], cwd=ROOT,
                                   capture_output=True, text=True,
                                   env={**os.environ, "PYTHONPATH": str(ROOT)})
                planned = plans.wait(sid, n, a.timeout)
                print(f"sent {sid}: {n} photo(s), send exit {r.returncode}, plan of all "
                      f"{'in' if planned else 'NOT in'} ({time.monotonic() - t:.0f} s)",
                      flush=True)
                if r.returncode:
                    print(r.stdout[-1500:] + r.stderr[-1500:])
                sessions.append(sid)
            plans.close()
        finally:
            stop(up)
        fails, cpu = [], []
        for sid in sessions:
            path = rec_dir / f"{sid}.mcap"
            if not path.exists():
                fails.append(sid)
                print(f"{sid}: no recording at {path}")
                continue
            ok, text, c = regress(path)
            cpu.append(c)
            head = text.splitlines()[0] if text else ""
            notes = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("note:")]
            print(f"{sid}: {'PASS' if ok else 'FAIL'} - {head}")
            for ln in notes:
                print(f"    {ln}")
            if not ok:
                fails.append(sid)
                print(text)
        bad = moved_copy(rec_dir / f"{sessions[0]}.mcap", work / "moved.mcap")
        ok, text, _ = regress(bad)
        caught = (not ok and re.search(r"hypotheses\[0\]\.polyline\.points\[1\]: .*moved 5\.00 px",
                                       text) is not None)
        print(f"changed copy ({sessions[0]}, photo 0's boundary moved 5 px): "
              f"{'FAILED as it must' if caught else 'NOT CAUGHT'}")
        print("\n".join("    " + ln for ln in text.splitlines() if "hypotheses" in ln)[:1500])
        print(f"false failures: {len(fails)} of {len(sessions)} recordings"
              + (f" ({', '.join(fails)})" if fails else "")
              + f"; regress CPU per recording median {sorted(cpu)[len(cpu) // 2]:.1f} s"
              if cpu else "")
        return 0 if not fails and caught else 1


if __name__ == "__main__":
    sys.exit(main())
