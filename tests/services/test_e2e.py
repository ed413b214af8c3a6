"""End to end across processes: a router and every service in its own process over
loopback; a two-photo session goes capture -> hypotheses -> auto selection -> measure query
-> odometry, and the numbers equal what the command line computes for the same photos.
Waits on liveliness tokens and results, never sleeps."""

import json
import math
import signal
import threading
from importlib import resources

import numpy as np
import pytest
import zenoh

import schemas
from services.runtime.bus import BusConfig, open_session, wait_alive
from tests.cli.conftest import run_findme
from tests.services.conftest import free_port, spawn_findme, wait_logged

SERVICES = ("hypotheses", "selection", "measurement", "odometry")
PIXELS = [[247, 378], [495, 276]]


def _example(name):
    base = resources.files("findme") / "examples"
    meta = json.loads((base / f"{name}.json").read_text())
    k = meta["intrinsics"]
    return (str(base / f"{name}.jpg"), f"{k['fx']},{k['fy']},{k['cx']},{k['cy']}",
            ",".join(map(str, meta["gravity_cam"])), meta["camera_height_m"])


@pytest.fixture
def deployment():
    ep = f"tcp/127.0.0.1:{free_port()}"
    procs = {"router": spawn_findme("router", "--listen", ep)}
    wait_logged(procs["router"], "listening on")   # the router is up before anyone connects
    for name in SERVICES:
        procs[name] = spawn_findme("serve", name, "--connect", ep, *(["--auto"] if name == "selection" else []))
    client = open_session(BusConfig(mode="client", connect=(ep,)))
    yield ep, client, procs
    client.close()
    for p in procs.values():
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    codes = {n: p.wait(20) for n, p in procs.items()}
    assert all(c == 0 for n, c in codes.items() if n != "measurement"), codes  # clean SIGTERM


def test_two_photo_session_across_processes(deployment):
    ep, client, procs = deployment
    for name in SERVICES:
        wait_alive(client, name, 60)
    got, cv = {}, threading.Condition()

    def cb(sample):
        with cv:
            got[str(sample.key_expr)] = sample.payload.to_bytes()
            cv.notify_all()

    sub = client.declare_subscriber("findme/e2e/**", cb)
    a, b = _example("room_a"), _example("room_b")
    capture = spawn_findme("serve", "capture", "--connect", ep, "--session", "e2e",
                      *sum((["--wait-for", s] for s in SERVICES), []), a[0], b[0])
    try:
        with cv:
            assert cv.wait_for(lambda: "findme/e2e/trajectory" in got and len(schemas.decode(
                schemas.Trajectory, got["findme/e2e/trajectory"]).poses) == 2, 120), sorted(got)
        # measure query on photo 0
        req = schemas.MeasureRequest(session="e2e", index=0)
        req.pixels.extend(schemas.pixels_to_msg(PIXELS))
        (rep,) = [schemas.decode(schemas.MeasureReply, r.ok.payload.to_bytes())
                  for r in client.get("findme/e2e/measure", payload=schemas.encode(req), timeout=10)
                  if r.ok]
        motion = schemas.decode(schemas.Motion, got["findme/e2e/motion/0/1"])
    finally:
        capture.send_signal(signal.SIGTERM)
        capture.wait(20)
        sub.undeclare()
    # the same numbers from the command line, same photos and inputs
    loc = json.loads(run_findme("locate", a[0], "--intrinsics", a[1], "--gravity", a[2],
                                "--camera-height", a[3], *sum((["--point", f"{u},{v}"] for u, v in PIXELS), []),
                                "--json").stdout)
    for p, q in zip(rep.points, loc["points"]):
        assert np.allclose(schemas.msg_to_vec3(p.xyz), q["xyz_m"], atol=1e-5)
    assert rep.distances[0].distance_m == pytest.approx(loc["distances_m"][0], abs=1e-5)
    mo = json.loads(run_findme("motion", a[0], b[0], "--intrinsics", a[1], "--gravity-a", a[2],
                               "--gravity-b", b[2], "--camera-height", a[3], "--json").stdout)
    assert (motion.x_m, motion.z_m) == pytest.approx((mo["x_m"], mo["z_m"]), abs=1e-5)
    assert math.degrees(motion.yaw_rad) == pytest.approx(mo["yaw_deg"], abs=1e-4)
    assert (motion.inliers, motion.matches) == (mo["inliers"], mo["matches"])
    # status lists every service; one killed with SIGKILL disappears (liveliness DELETE)
    st = json.loads(run_findme("status", "--connect", ep, "--json").stdout)
    assert set(SERVICES) <= {s["service"] for s in st}
    gone = threading.Event()
    lsub = client.liveliness().declare_subscriber(
        "findme/@services/measurement/*", lambda s: s.kind == zenoh.SampleKind.DELETE and gone.set())
    procs["measurement"].send_signal(signal.SIGKILL)
    assert gone.wait(10), "the killed service's liveliness token did not go away"
    lsub.undeclare()
    st = json.loads(run_findme("status", "--connect", ep, "--json").stdout)
    assert "measurement" not in {s["service"] for s in st}


def _measure(client, session: str, pixels) -> schemas.MeasureReply:
    req = schemas.MeasureRequest(session=session, index=0)
    req.pixels.extend(schemas.pixels_to_msg(pixels))
    replies = list(client.get(f"findme/{session}/measure", payload=schemas.encode(req),
                              timeout=10))
    ok = [schemas.decode(schemas.MeasureReply, r.ok.payload.to_bytes()) for r in replies if r.ok]
    assert len(ok) == 1, [r.err.payload.to_bytes() for r in replies if not r.ok]
    return ok[0]


def test_a_restarted_measurement_answers_from_the_photos_scene_message():
    """Measurement SIGKILLed and started again after the photo's frame has left the bus (the
    store holds frames 1 ms here, small results 15 min; the sender is gone): the measure
    query is answered from the photo's Scene message, the same reply as before the kill."""
    ep = f"tcp/127.0.0.1:{free_port()}"
    procs = {"router": spawn_findme("router", "--listen", ep)}
    wait_logged(procs["router"], "listening on")
    names = ("hypotheses", "selection", "measurement", "store")
    extra = {"selection": ["--auto"], "store": ["--window", "0.001"]}
    for name in names:
        procs[name] = spawn_findme("serve", name, "--connect", ep, *extra.get(name, []))
    client = open_session(BusConfig(mode="client", connect=(ep,)))
    try:
        for name in names:
            wait_alive(client, name, 60)
        got, cv = set(), threading.Condition()

        def cb(sample):
            with cv:
                got.add(str(sample.key_expr))
                cv.notify_all()

        sub = client.declare_subscriber("findme/rs/scene/*", cb)
        a = _example("room_a")
        capture = spawn_findme("serve", "capture", "--connect", ep, "--session", "rs",
                               *sum((["--wait-for", s] for s in names), []), a[0])
        with cv:
            assert cv.wait_for(lambda: "findme/rs/scene/0" in got, 120), got
        sub.undeclare()
        capture.send_signal(signal.SIGTERM)
        capture.wait(20)
        before = _measure(client, "rs", PIXELS)
        assert len(before.points) == 2 and not before.points[0].error
        gone = threading.Event()
        lsub = client.liveliness().declare_subscriber(
            "findme/@services/measurement/*",
            lambda s: s.kind == zenoh.SampleKind.DELETE and gone.set())
        procs["measurement"].send_signal(signal.SIGKILL)
        assert gone.wait(10)
        lsub.undeclare()
        assert not [r for r in client.get("findme/rs/frame/0", timeout=5) if r.ok]
        procs["measurement"] = spawn_findme("serve", "measurement", "--connect", ep)
        wait_alive(client, "measurement", 60)
        after = _measure(client, "rs", PIXELS)
        assert schemas.encode(after) == schemas.encode(before)
    finally:
        client.close()
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in procs.values():
            p.wait(20)
