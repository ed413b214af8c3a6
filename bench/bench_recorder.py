"""Recorder cost: 30 VGA frames/s with their results, for a minute.

    python bench/bench_recorder.py [--seconds 60] [--fps 30] [--json OUT.json]

A publisher (this process, a Zenoh peer on 127.0.0.1) sends per frame what a live session
would: ``frame/<n>`` (a distinct 640x480 JPEG, ~60 kB), ``hypotheses/<n>`` (10 ranked
hypotheses), ``selection/<n>``, ``scene/<n>``, ``motion/<n-1>/<n>``, ``pose/<n>``, and a
``trajectory`` once a second (growing). Measured, one after the other in the same run:

* **recorder**: ``findme serve recorder`` in its own process, linked to the publisher over
  TCP: every message to MCAP with the view channels (image, calibration, annotations, poses,
  transforms), zstd chunks, flushed every 0.5 s;
* **baseline: raw mcap writer**: the same messages written by ``mcap.writer.Writer`` alone
  (bus channels only, same compression and flushing, no Zenoh, no view channels) in its own
  process, paced by its own clock;
* **baseline: Zenoh subscriber**: a process that only receives the same stream (the bus'
  share of the recorder's cost).

Reported: CPU of each process per second of the run (% of one core: median, p10/p90, IQR,
from /proc/<pid>/stat; start-up excluded), frames published vs frames in the MCAP (dropped;
goal 0) and the publisher's lateness. Goal: recorder CPU at most 10 % of one core.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.common import fmt, stats  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")
SESSION = "bench-rec"


# ------------------------------------------------------------------------------ the stream
def jpeg_frames(k: int = 30) -> list[bytes]:
    """k distinct VGA JPEGs (the bundled photos, shifted and with fresh noise)."""
    import cv2
    from findme_io.imageio import encode_jpeg
    base = [cv2.imread(str(ROOT / "findme" / "examples" / f"room_{x}.jpg")) for x in "ab"]
    rng = np.random.default_rng(0)
    out = []
    for i in range(k):
        img = np.roll(base[i % 2], 3 * i, axis=1).astype(np.int16)
        img += rng.normal(0, 3, img.shape).astype(np.int16)
        out.append(encode_jpeg(np.clip(img, 0, 255).astype(np.uint8), 90))
    return out


class Stream:
    """The messages of frame n, as (key, payload) (deterministic)."""

    def __init__(self, fps: int):
        import schemas
        from findme_core.single.methods import hypothesize
        from findme_io.convert import camera_msg, hypothesis_set_msg, make_frame
        from findme_io.frame_photo import frame_inputs
        self.S, self.fps = schemas, fps
        self.jpegs = jpeg_frames()
        meta = json.loads((ROOT / "findme" / "examples" / "room_a.json").read_text())
        k = meta["intrinsics"]
        self.intr = (k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"])
        self.gravity = meta["gravity_cam"]
        f0 = make_frame(SESSION, 0, self.jpegs[0], intrinsics=self.intr, gravity=self.gravity,
                        camera_height_m=1.42, time_ns=1)
        image, cam = frame_inputs(f0)
        hs = hypothesize(image, cam, "findme", 10)
        self.hset = hypothesis_set_msg(SESSION, 0, hs, "findme/findme.v1")
        self.cam = camera_msg(cam)
        self.make_frame = make_frame
        self.poses: list = []

    def messages(self, n: int, t_ns: int) -> list[tuple[str, bytes]]:
        S = self.S
        key = lambda *p: "/".join(["findme", SESSION, *map(str, p)])  # noqa: E731
        f = self.make_frame(SESSION, n, self.jpegs[n % len(self.jpegs)], intrinsics=self.intr,
                            gravity=self.gravity, camera_height_m=1.42, device="bench",
                            time_ns=t_ns)
        hs = S.HypothesisSet()
        hs.CopyFrom(self.hset)
        hs.index = n
        h = hs.hypotheses[0]
        sel = S.Selection(session=SESSION, index=n, rank=1, by=S.SELECTED_BY_AUTO, time_ns=t_ns)
        sc = S.Scene(session=SESSION, index=n, rank=1, camera=self.cam, camera_height_m=1.42,
                     camera_height_sigma_m=0.03, metric=True, polyline=h.polyline, time_ns=t_ns)
        pose = S.Pose(session=SESSION, index=n, x_m=0.01 * n, z_m=0.02 * n, yaw_rad=0.001 * n,
                      time_ns=t_ns)
        out = [(key("frame", n), S.encode(f)), (key("hypotheses", n), S.encode(hs)),
               (key("selection", n), S.encode(sel)), (key("scene", n), S.encode(sc))]
        if n > 0:
            mo = S.Motion(session=SESSION, index_a=n - 1, index_b=n, x_m=0.01, z_m=0.02,
                          yaw_rad=0.001, sigma_x_m=0.01, sigma_z_m=0.01, sigma_yaw_rad=0.001,
                          inliers=100, matches=200, method="bench", time_ns=t_ns)
            out.append((key("motion", n - 1, n), S.encode(mo)))
        out.append((key("pose", n), S.encode(pose)))
        self.poses.append(S.Pose(index=n, x_m=pose.x_m, z_m=pose.z_m, yaw_rad=pose.yaw_rad,
                                 time_ns=t_ns))
        if n % self.fps == self.fps - 1:
            out.append((key("trajectory"), S.encode(S.Trajectory(session=SESSION, poses=self.poses,
                                                                time_ns=t_ns))))
        return out


def precompute(fps: int, seconds: float) -> list[list[tuple[str, bytes]]]:
    st = Stream(fps)
    t0 = time.time_ns()
    return [st.messages(n, t0 + n * 1_000_000_000 // fps) for n in range(int(fps * seconds))]


# ------------------------------------------------------------------------------ measuring
def cpu_ticks(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as f:
        parts = f.read().rsplit(")", 1)[1].split()
    return int(parts[11]) + int(parts[12])   # utime + stime (fields 14, 15)


class CpuSampler:
    """Per-second CPU (% of one core) of a process, sampled by a timer thread."""

    def __init__(self, pid: int):
        self.pid, self.samples = pid, []
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)

    def start(self):
        self._t.start()
        return self

    def _run(self):
        last_c, last_t = cpu_ticks(self.pid), time.monotonic()
        due = last_t + 1.0
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            try:
                c = cpu_ticks(self.pid)
            except (FileNotFoundError, ProcessLookupError):
                return
            t = time.monotonic()
            self.samples.append(100.0 * (c - last_c) / TICK / (t - last_t))
            last_c, last_t, due = c, t, due + 1.0

    def stop(self) -> list[float]:
        self._stop.set()
        self._t.join()
        return self.samples


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def publish(session, frames, fps) -> dict:
    from services.runtime import bus
    t0 = time.monotonic()
    pace = threading.Event()
    late = []
    for n, msgs in enumerate(frames):
        due = t0 + n / fps
        now = time.monotonic()
        if now < due:
            pace.wait(due - now)
        late.append(max(0.0, time.monotonic() - due) * 1e3)
        for k, p in msgs:
            bus.put(session, k, p)
    return {"frames": len(frames), "seconds": time.monotonic() - t0, "late_ms": stats(late)}


def run_recorder(frames, fps, tmp: Path) -> dict:
    from services.runtime import bus
    port = free_port()
    session = bus.open_session(bus.BusConfig(listen=(f"tcp/127.0.0.1:{port}",)))
    out = tmp / "rec"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "findme.cli", "serve", "recorder", "--out",
                             str(out), "--mode", "peer", "--connect", f"tcp/127.0.0.1:{port}"],
                            env=env, stderr=subprocess.DEVNULL)
    try:
        bus.wait_alive(session, "recorder")
        cpu = CpuSampler(proc.pid).start()
        c0, w0 = cpu_ticks(proc.pid), time.monotonic()
        pub = publish(session, frames, fps)
        status = _status(session, "recorder")
        c1, w1 = cpu_ticks(proc.pid), time.monotonic()
        samples = cpu.stop()
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(60)
        session.close()
    path = out / f"{SESSION}.mcap"
    recorded, size = count_frames(path)
    return {"cpu": samples, "cpu_total": 100.0 * (c1 - c0) / TICK / (w1 - w0), "publish": pub,
            "frames_recorded": recorded, "mcap_mb": size / 1e6, "status": status}


def _status(session, name):
    import schemas
    for r in session.liveliness().get(f"findme/@services/{name}/*", timeout=5):
        if r.ok is None:
            continue
        for q in session.get(str(r.ok.key_expr) + "/status", timeout=5):
            if q.ok is not None:
                s = schemas.decode(schemas.ServiceStatus, q.ok.payload.to_bytes())
                return {"frames_in": s.frames_in, "dropped": s.dropped,
                        "queue_depth": s.queue_depth, **dict(s.counters)}
    return {}


def count_frames(path: Path) -> tuple[int, int]:
    from mcap.reader import make_reader
    with open(path, "rb") as f:
        s = make_reader(f).get_summary()
    ids = [c.id for c in s.channels.values() if c.topic == f"findme/{SESSION}/frame"]
    return sum(s.statistics.channel_message_counts.get(i, 0) for i in ids), path.stat().st_size


def run_child(role: str, frames, fps, tmp: Path) -> dict:
    """A baseline in its own process; it reports ready on stdout, then runs."""
    from services.runtime import bus
    port = free_port()
    session = None
    if role == "subscriber":
        session = bus.open_session(bus.BusConfig(listen=(f"tcp/127.0.0.1:{port}",)))
    proc = subprocess.Popen([sys.executable, __file__, "--role", role, "--port", str(port),
                             "--fps", str(fps), "--seconds", str(len(frames) / fps),
                             "--tmp", str(tmp)], stdout=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)))
    try:
        assert proc.stdout.readline().strip() == "ready"
        cpu = CpuSampler(proc.pid).start()
        c0, w0 = cpu_ticks(proc.pid), time.monotonic()
        lines = []
        if role == "subscriber":
            publish(session, frames, fps)
        else:
            for line in proc.stdout:          # its result, then "done"
                if line.strip() == "done":
                    break
                lines.append(line)
        c1, w1 = cpu_ticks(proc.pid), time.monotonic()
        samples = cpu.stop()
    finally:
        if role == "subscriber" and proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        tail = proc.communicate(timeout=60)[0]
        if session is not None:
            session.close()
    res = {"cpu": samples, "cpu_total": 100.0 * (c1 - c0) / TICK / (w1 - w0)}
    for line in lines + (tail or "").splitlines():
        if line.startswith("{"):
            res.update(json.loads(line))
    return res


# ------------------------------------------------------------------------------ the baselines
def child_mcap_writer(args) -> None:
    from mcap.writer import CompressionType, Writer
    from mcap_protobuf.schema import build_file_descriptor_set

    import schemas
    frames = precompute(args.fps, args.seconds)
    path = Path(args.tmp) / "baseline.mcap"
    f = open(path, "wb")
    w = Writer(f, chunk_size=4 * 1024 * 1024, compression=CompressionType.ZSTD)
    w.start()
    channels: dict = {}
    print("ready", flush=True)
    t0 = time.monotonic()
    pace = threading.Event()
    last_flush = t0
    for n, msgs in enumerate(frames):
        due = t0 + n / args.fps
        now = time.monotonic()
        if now < due:
            pace.wait(due - now)
        for k, p in msgs:
            parts = k.split("/")
            topic = "/".join(parts[:3])
            cid = channels.get(topic)
            if cid is None:
                cls = schemas.MESSAGE_TYPES[schemas.schema_of(p)]
                sid = w.register_schema(cls.DESCRIPTOR.full_name, "protobuf",
                                        build_file_descriptor_set(cls).SerializeToString())
                cid = channels[topic] = w.register_channel(topic, "protobuf", sid)
            t = time.time_ns()
            w.add_message(cid, log_time=t, publish_time=t, data=p)
        if time.monotonic() - last_flush >= 0.5:
            w.flush()
            last_flush = time.monotonic()
    w.finish()
    f.close()
    print(json.dumps({"mcap_mb": path.stat().st_size / 1e6, "frames_recorded": len(frames)}),
          flush=True)
    print("done", flush=True)


def child_subscriber(args) -> None:
    import zenoh

    from services.runtime import bus
    session = bus.open_session(bus.BusConfig(connect=(f"tcp/127.0.0.1:{args.port}",)))
    got = {"n": 0, "frames": 0}
    lock = threading.Condition()

    def cb(s):
        data = s.payload.to_bytes()  # what the recorder's callback does too
        with lock:
            got["n"] += 1
            got["frames"] += "/frame/" in str(s.key_expr)
            lock.notify_all()
            del data
    sub = session.declare_subscriber("findme/*/**", cb)
    session.liveliness().declare_token("findme/@services/bench-subscriber/0")
    print("ready", flush=True)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    stop.wait(args.seconds + 120)
    with lock:   # the last messages may still be in flight when the publisher is done
        lock.wait_for(lambda: got["frames"] >= int(args.fps * args.seconds), 5.0)
    sub.undeclare()
    print(json.dumps({"messages": got["n"], "frames_recorded": got["frames"]}), flush=True)


# ------------------------------------------------------------------------------ main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--fps", type=int, default=30)
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--role", choices=("mcap-writer", "subscriber"), help=argparse.SUPPRESS)
    ap.add_argument("--port", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--tmp", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.role == "mcap-writer":
        child_mcap_writer(a)
        return 0
    if a.role == "subscriber":
        child_subscriber(a)
        return 0
    print(f"preparing {int(a.fps * a.seconds)} frames ({a.fps} fps x {a.seconds:g} s) ...",
          flush=True)
    frames = precompute(a.fps, a.seconds)
    per = sum(len(p) for _, p in frames[1]) / 1e3
    print(f"{len(frames[1])} messages per frame, {per:.0f} kB per frame, "
          f"{per * a.fps / 1e3:.2f} MB/s; {os.cpu_count()} cores", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        results = {"recorder (findme serve recorder)": run_recorder(frames, a.fps, tmp),
                   "baseline: raw mcap writer": run_child("mcap-writer", frames, a.fps, tmp),
                   "baseline: Zenoh subscriber only": run_child("subscriber", frames, a.fps, tmp)}
    n = len(frames)
    print(f"\nCPU per second of the run, % of one core ({a.seconds:g} s, {a.fps} frames/s):")
    for name, r in results.items():
        s = stats(r["cpu"])
        print(fmt(name, s, "%") + f"   whole run {r['cpu_total']:.1f} %")
    print("\nframes:")
    for name, r in results.items():
        got = r.get("frames_recorded", 0)
        extra = f", {r['mcap_mb']:.0f} MB MCAP" if "mcap_mb" in r else ""
        print(f"  {name:34s} {got}/{n} recorded, dropped {n - got}{extra}")
    rec = results["recorder (findme serve recorder)"]
    print(f"  recorder status: {rec['status']}")
    print(f"  publisher lateness: {fmt('', rec['publish']['late_ms'])}")
    if a.json:
        Path(a.json).write_text(json.dumps({"fps": a.fps, "seconds": a.seconds, "frames": n,
                                            "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
