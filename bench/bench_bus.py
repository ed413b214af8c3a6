"""Round trip photo -> hypothesis set over the bus, embedded and multi-process.

    python bench/bench_bus.py [--n 120] [--json OUT.json]

A 640x480 JPEG frame is published on findme/<s>/frame/<n>; the time until
findme/<s>/hypotheses/<n> arrives back is the round trip. Next to it: the hypotheses
service's own handling time for that photo (decode + core, reported in its timing_ms) and
the core alone in this process. The bus and serialisation cost per photo is round trip -
handling time. Goal: at most 5 ms at p50.

Modes: embedded (the service in this process, one Zenoh session) and multi-process (a
router and `findme serve hypotheses` in their own processes; this process is a client).
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import threading
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import schemas  # noqa: E402
from bench.common import EVAL_DIR, dev_views  # noqa: E402
from findme.evaluation.views import view_inputs  # noqa: E402
from findme_io.imageio import decode_image  # noqa: E402
from findme_core.single.methods import hypothesize  # noqa: E402
from services.runtime.bus import BusConfig, open_session, wait_alive  # noqa: E402
from findme_io.convert import make_frame  # noqa: E402
from services.pipeline.hypotheses import HypothesesHandler  # noqa: E402
from services.runtime.service import Service  # noqa: E402


def photos(n):
    views = dev_views()
    out = []
    if views:
        for vid, meta in views[:n]:
            cam, h, _ = view_inputs(meta)
            data = cv2.imencode(".jpg", cv2.imread(str(EVAL_DIR / "views" / meta["image"])),
                                [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
            out.append((data, cam, h))
        return out
    from findme_core.synth.render import Pose, Room, render
    room = Room.rectangle(5.0, 6.0)
    for i in range(n):
        v = render(room, Pose(0.2, -1.5, 1.45, yaw_deg=-60 + 7 * i, pitch_deg=5 * (i % 5)), 640, 480,
                   hfov_deg=75.0, seed=i)
        out.append((cv2.imencode(".jpg", v.image)[1].tobytes(), v.camera, v.camera_height))
    return out


def round_trips(session, items, tag):
    """(round trip ms, handler ms) per photo: publish, wait for the reply (an event)."""
    got, cv = {}, threading.Condition()

    def cb(sample):
        m = schemas.decode(schemas.HypothesisSet, sample.payload.to_bytes())
        with cv:
            got[m.index] = (time.perf_counter(), m.timing_ms["handler_total"])
            cv.notify_all()

    sub = session.declare_subscriber(f"findme/{tag}/hypotheses/*", cb)
    rt, handler = [], []
    for i, (data, cam, h) in enumerate(items):
        f = make_frame(tag, i, data, intrinsics=(cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height),
                       gravity=cam.gravity, camera_height_m=h)
        payload = schemas.encode(f)
        t0 = time.perf_counter()
        session.put(f"findme/{tag}/frame/{i}", payload)
        with cv:
            if not cv.wait_for(lambda: i in got, 60):
                raise RuntimeError(f"no hypotheses for frame {i}")
        rt.append(1e3 * (got[i][0] - t0))
        handler.append(got[i][1])
    sub.undeclare()
    return np.array(rt), np.array(handler)


def pct(a, q):
    return float(np.percentile(a, q))


def report(name, rt, handler, core):
    over = rt - handler
    print(f"{name:14s} round trip p50 {pct(rt, 50):7.2f} p99 {pct(rt, 99):7.2f} ms | handler p50 "
          f"{pct(handler, 50):7.2f} | core alone p50 {pct(core, 50):7.2f} | bus + serialisation "
          f"p50 {pct(over, 50):5.2f} p99 {pct(over, 99):6.2f} ms")
    return {"round_trip_ms": {"p50": pct(rt, 50), "p99": pct(rt, 99)},
            "handler_ms": {"p50": pct(handler, 50), "p99": pct(handler, 99)},
            "core_ms": {"p50": pct(core, 50), "p99": pct(core, 99)},
            "overhead_ms": {"p50": pct(over, 50), "p99": pct(over, 99), "median_abs": float(np.median(over))}}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=120)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    cv2.setNumThreads(1)
    items = photos(a.n)
    core = []
    for data, cam, _ in items:  # the core alone, same photos, this process
        t0 = time.perf_counter()
        hypothesize(decode_image(data), cam)
        core.append(1e3 * (time.perf_counter() - t0))
    core = np.array(core)
    res = {}
    # embedded
    s = open_session(BusConfig())
    svc = Service(HypothesesHandler(), s).start()
    round_trips(s, items[:5], "warm")
    rt, hd = round_trips(s, items, "emb")
    res["embedded"] = report("embedded", rt, hd, core)
    svc.stop()
    s.close()
    # multi-process: router + service in their own processes
    with socket.socket() as so:
        so.bind(("127.0.0.1", 0))
        port = so.getsockname()[1]
    ep = f"tcp/127.0.0.1:{port}"
    env = dict(os.environ, OPENCV_NUM_THREADS="1")
    procs = [subprocess.Popen([sys.executable, "-m", "findme.cli", "router", "--listen", ep],
                              stderr=subprocess.DEVNULL, env=env),
             subprocess.Popen([sys.executable, "-m", "findme.cli", "serve", "hypotheses", "--connect", ep],
                              stderr=subprocess.DEVNULL, env=env)]
    try:
        c = open_session(BusConfig(mode="client", connect=(ep,)))
        wait_alive(c, "hypotheses")
        round_trips(c, items[:5], "warm2")
        rt, hd = round_trips(c, items, "mp")
        res["multi_process"] = report("multi-process", rt, hd, core)
        c.close()
    finally:
        for p in procs:
            p.terminate()
            p.wait(10)
    print(f"({len(items)} photos, 640x480 JPEG q90, one round trip at a time)")
    if a.json:
        json.dump(res, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
