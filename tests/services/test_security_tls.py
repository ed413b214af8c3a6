"""The phone + server deployment for real (issue 11): compose/router-tls.json5 (TLS, passwords,
per-device ACL) and the compose file's replicas, each service in its own process as the
"server" user: 2 hypotheses, 2 odometry, 1 measurement and the store (odometry asks it for
a selected photo's frame).

* Under that ACL the services see each other's liveliness tokens and answer status queries,
  so ``findme status`` lists all six and the replicas split the work: every result is
  published once.
* Cross-session poisoning: device alice publishes, on a key her ACL allows, a Frame whose
  payload says session bob-1 (camera 9 m high, fx 200). The service that takes frames in
  (the hypotheses) refuses it (FORBIDDEN, naming both keys) and bob's measurement is
  unchanged.

Waits on liveliness, replies and messages, never sleeps. "Nothing more is coming from an
instance" is a signal too: each instance handles its inputs in order and publishes from one
session, so once it has answered a later message (a sentinel it must refuse), everything it
published before has arrived.
"""

from __future__ import annotations

import json
import signal
import threading
import time
from importlib import resources

import pytest
import zenoh

import schemas
from findme_io.convert import make_frame
from services.runtime.bus import BusConfig, open_session, put
from tests.cli.conftest import run_findme
from tests.services.conftest import Collector, spawn_findme, start_tls_router

pytestmark = pytest.mark.timeout(240)

INSTANCES = {"hypotheses": ("h1", "h2"), "odometry": ("o1", "o2"), "measurement": ("m1",),
             "store": ("s1",)}
PIXELS = [[247, 378], [495, 276]]
EXAMPLES = resources.files("findme") / "examples"
CODE = schemas.ErrorCode


def example_frame(session, n, name, **override):
    meta = json.loads((EXAMPLES / f"{name}.json").read_text())
    k = {**meta["intrinsics"], **override.pop("intrinsics", {})}
    kw = {"gravity": meta["gravity_cam"], "camera_height_m": meta["camera_height_m"], **override}
    return make_frame(session, n, (EXAMPLES / f"{name}.jpg").read_bytes(),
                      intrinsics=(k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"]),
                      **kw)


class Seen(Collector):
    """Every put on a key expression, in arrival order, and the Errors among them."""

    def errors(self):
        with self.cv:
            return [schemas.decode(schemas.Error, p) for k, p in self.items if k.endswith("/error")]


def wait_tokens(session, expected: set[str], timeout=90.0):
    """Until a liveliness token of every ``service/instance`` in ``expected`` is seen."""
    seen, cv = set(), threading.Condition()

    def cb(s):
        with cv:
            if s.kind == zenoh.SampleKind.PUT:
                seen.add("/".join(str(s.key_expr).split("/")[-2:]))
                cv.notify_all()

    sub = session.liveliness().declare_subscriber("findme/@services/**", cb, history=True)
    with cv:
        ok = cv.wait_for(lambda: expected <= seen, timeout)
    sub.undeclare()
    assert ok, f"services seen {sorted(seen)}, expected {sorted(expected)}"


def until_every_instance_answered(server, prefix: str, services=("hypotheses", "odometry")):
    """Sentinels: garbage on frame and selection keys of fresh sessions until every instance
    of ``services`` has answered one with an Error (see the module docstring)."""
    seen = Seen(server, f"findme/{prefix}-$*/error")
    want = {f"{s}/{i}" for s in services for i in INSTANCES[s]}
    for i in range(40):   # sharding may send one sentinel to one instance only
        put(server, f"findme/{prefix}-{i}/frame/0", b"\x00sentinel")
        put(server, f"findme/{prefix}-{i}/selection/0", b"\x00sentinel")
    seen.until(lambda items: want <= {schemas.decode(schemas.Error, p).service
                                      for _, p in items}, what="sentinel errors")
    seen.sub.undeclare()


@pytest.fixture(scope="module")
def deployment(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("tls")
    router, ep, tls, svc_cfg = start_tls_router(
        tmp, {"server": "change-me-server", "alice": "change-me-alice"})
    procs = [router] + [spawn_findme("serve", name, "--config", svc_cfg, "--instance", inst)
                        for name, insts in INSTANCES.items() for inst in insts]
    server = open_session(BusConfig(mode="client", connect=(ep,), tls=tls, user="server",
                                    password="change-me-server"))
    alice = open_session(BusConfig(mode="client", connect=(ep,), tls=tls, user="alice",
                                   password="change-me-alice"))
    try:
        wait_tokens(server, {f"{n}/{i}" for n, insts in INSTANCES.items() for i in insts})
        yield server, alice, svc_cfg
    finally:
        alice.close()
        server.close()
        for p in reversed(procs):
            p.send_signal(signal.SIGTERM)
        for p in procs:
            p.wait(20)


def run_session(server, sid, seen):
    """Frames of room_a and room_b on ``sid``; rank 1 selected for each once its hypotheses
    arrive (as the gateway does for a page); until the trajectory has both poses."""
    for n, name in enumerate(("room_a", "room_b")):
        put(server, f"findme/{sid}/frame/{n}", schemas.encode(example_frame(sid, n, name)))
    seen.until(lambda it: {f"findme/{sid}/hypotheses/{n}" for n in (0, 1)} <= {k for k, _ in it},
               what="hypotheses")
    for n in (0, 1):
        sel = schemas.Selection(session=sid, index=n, rank=1, by=schemas.SELECTED_BY_USER)
        put(server, f"findme/{sid}/selection/{n}", schemas.encode(sel))
    seen.until(lambda it: any(k.endswith("/trajectory") and len(schemas.decode(
        schemas.Trajectory, p).poses) == 2 for k, p in it), what="trajectory of two poses")


def test_status_and_sharding_under_the_acl(deployment):
    server, _, svc_cfg = deployment
    st = json.loads(run_findme("status", "--config", svc_cfg, "--json").stdout)
    assert sorted((s["service"], s["instance"]) for s in st) == sorted(
        (n, i) for n, insts in INSTANCES.items() for i in insts)
    seen = Seen(server, "findme/shard-1/**")
    run_session(server, "shard-1", seen)
    until_every_instance_answered(server, "shard-1-end")
    keys = [k.removeprefix("findme/shard-1/") for k in seen.keys()]
    published = {k: keys.count(k) for k in keys if not k.startswith(("frame/", "selection/"))}
    # once each; the trajectory after each pose
    assert published == {"hypotheses/0": 1, "hypotheses/1": 1, "scene/0": 1, "scene/1": 1,
                         "pose/0": 1, "motion/0/1": 1, "pose/1": 1, "trajectory": 2}, published
    assert not seen.errors()


def measure(session, sid, req_session=None):
    req = schemas.MeasureRequest(session=req_session or sid, index=0)
    req.pixels.extend(schemas.pixels_to_msg(PIXELS))
    (r,) = list(session.get(f"findme/{sid}/measure", payload=schemas.encode(req), timeout=10))
    if r.ok is None:
        return schemas.decode(schemas.Error, r.err.payload.to_bytes())
    return schemas.decode(schemas.MeasureReply, r.ok.payload.to_bytes())


def test_cross_session_poisoning_is_refused(deployment):
    server, alice, _ = deployment
    bob = Seen(server, "findme/bob-1/**")
    run_session(server, "bob-1", bob)
    before = measure(server, "bob-1")
    assert before.metric and not before.error
    mine = Seen(alice, "findme/alice-1/**")
    poison = example_frame("bob-1", 0, "room_a", camera_height_m=9.0,
                           intrinsics={"fx": 200.0, "fy": 200.0})
    put(alice, "findme/alice-1/frame/0", schemas.encode(poison))      # a key alice may use
    # refused by the service that takes frames in (measurement and odometry take none: they
    # ask the bus for a selected photo's frame, and check what comes back)
    refused = mine.until(lambda it: {e.service.split("/")[0] for e in mine.errors()}
                         >= {"hypotheses"}, what="refusals")
    for e in mine.errors():
        assert e.code == CODE.ERROR_CODE_FORBIDDEN and e.key == "findme/alice-1/frame/0", e
        assert "findme/alice-1/frame/0" in e.message and "findme/bob-1/frame/0" in e.message
    assert [k for k, _ in refused if not k.endswith("/error")] == ["findme/alice-1/frame/0"]
    # a request in alice's name for bob's session is refused too
    err = measure(alice, "alice-1", req_session="bob-1")
    assert err.code == CODE.ERROR_CODE_FORBIDDEN and "bob-1" in err.message
    # bob picks his hypothesis again: the scene is rebuilt from HIS frame
    scenes = bob.keys().count("findme/bob-1/scene/0")
    sel = schemas.Selection(session="bob-1", index=0, rank=1, by=schemas.SELECTED_BY_USER,
                            time_ns=time.time_ns())   # a new choice (the same bytes again are a duplicate)
    put(server, "findme/bob-1/selection/0", schemas.encode(sel))
    bob.until(lambda it: [k for k, _ in it].count("findme/bob-1/scene/0") == scenes + 1,
              what="bob's rebuilt scene")
    after = measure(server, "bob-1")
    assert [schemas.msg_to_vec3(p.xyz).tolist() for p in after.points] == \
        [schemas.msg_to_vec3(p.xyz).tolist() for p in before.points]
    assert after.distances[0].distance_m == before.distances[0].distance_m
    assert not [k for k in bob.keys() if "/error" in k]
