"""The phone + server deployment across hosts, for real (``pytest -m hosts``).

Three hosts, each a network namespace with its own IP address on one LAN (tests/hosts/
lan.py), set up as compose/docker-compose.yml sets up its containers and with its files
(compose/router-tls.json5, compose/service-tls.json5, tools/make_certs.py):

* server 10.200.0.1 (``router``): the TLS router (passwords, per-device access control),
  hypotheses (instance srv), measurement, odometry, recorder;
* worker 10.200.0.2: another hypotheses instance (wrk), joining ``tls/router:7447`` by name;
* phone 10.200.0.3 (``gateway``): the gateway serving the page over HTTPS with its own
  certificate (joining the router by IP address), and headless Chromium, which trusts the
  private CA (installed in its NSS store as a phone would install ca.crt) and opens
  https://gateway:8443/.

A two-photo session from the page: its numbers equal ``findme run``'s on the same photos,
the two hypotheses hosts share the work, the recording is complete. Then the worker's
cable is pulled while a photo it owns is in flight and plugged back in: no photo is lost
(the store and the recovery sweeps: a frame whose owner vanished is handled by another
instance, or by the owner once it is back). Every wait is on a signal (a log line,
a liveliness token, a page selector, a bus message). The test's own bus observer reaches
the router over a Unix socket (no namespace needed). The namespaces share /dev/shm, real
hosts do not, so Zenoh's shared memory is off everywhere here.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from importlib import resources
from pathlib import Path

import pytest
import zenoh

import schemas
from services.recording.mcap_reader import read_recording
from services.runtime.bus import SERVICES, BusConfig, open_session
from services.runtime.service import shard_owner

from .lan import Lan, why_not

pytestmark = [pytest.mark.hosts, pytest.mark.timeout(300)]

REPO = Path(__file__).resolve().parents[2]
COMPOSE = REPO / "compose"
CHROMIUM = "/usr/bin/chromium"
EXAMPLES = resources.files("findme") / "examples"
ROOM_A, ROOM_B = str(EXAMPLES / "room_a.jpg"), str(EXAMPLES / "room_b.jpg")
SIDE_A = json.loads((EXAMPLES / "room_a.json").read_text())
SIDE_B = json.loads((EXAMPLES / "room_b.json").read_text())
HOSTS = {"server": 1, "worker": 2, "phone": 3}
NAMES = {"router": "server", "worker": "worker", "gateway": "phone"}
SERVER_USER = ("server", "change-me-server")


# ------------------------------------------------------------------------------ helpers
class Tokens:
    """Live service tokens (``name/instance``) seen by a liveliness subscriber."""

    def __init__(self, session):
        self.live, self.cv = set(), threading.Condition()
        self.sub = session.liveliness().declare_subscriber(f"{SERVICES}/**", self._cb, history=True)

    def _cb(self, s):
        tok = "/".join(str(s.key_expr).split("/")[-2:])
        with self.cv:
            (self.live.add if s.kind == zenoh.SampleKind.PUT else self.live.discard)(tok)
            self.cv.notify_all()

    def wait(self, pred, timeout, what):
        with self.cv:
            assert self.cv.wait_for(lambda: pred(self.live), timeout), \
                f"{what} within {timeout} s; live: {sorted(self.live)}"


class Keys:
    """Every message of a session seen on the bus, by key (latest wins)."""

    def __init__(self, session, sid):
        self.got, self.errors, self.cv = {}, [], threading.Condition()
        self.sub = session.declare_subscriber(f"findme/{sid}/**", self._cb)

    def _cb(self, s):
        key, data = str(s.key_expr), s.payload.to_bytes()
        with self.cv:
            self.got[key] = data
            if key.endswith("/error"):
                self.errors.append(schemas.decode(schemas.Error, data))
            self.cv.notify_all()

    def wait(self, pred, timeout):
        with self.cv:
            return self.cv.wait_for(lambda: pred(self.got), timeout)


def _config(src: Path, dst: Path, certs: Path, **json5) -> str:
    """A compose Zenoh configuration with its /certs/ paths pointing at ``certs``, the given
    keys set (json5 path: value) and shared memory off; written to ``dst``."""
    tmp = dst.with_suffix(".src.json5")
    tmp.write_text(src.read_text().replace("/certs/", f"{certs}/"))
    conf = zenoh.Config.from_file(str(tmp))
    for k, v in {"transport/shared_memory/enabled": False, **json5}.items():
        conf.insert_json5(k, json.dumps(v))
    dst.write_text(str(conf))
    return str(dst)


def _wait_line(proc, text, timeout=90):
    with proc.new_line:
        assert proc.new_line.wait_for(lambda: any(text in x for x in proc.lines) or
                                      proc.poll() is not None, timeout), \
            f"no {text!r} from {proc.args[4:7]} on {proc.host} in {timeout} s"
    assert any(text in x for x in proc.lines), \
        f"{proc.args[4:7]} on {proc.host} exited: {''.join(proc.lines)[-3000:]}"


def _trust_store(home: Path, ca: Path) -> None:
    """Chromium's NSS store in ``home`` trusting the CA (what installing ca.crt does)."""
    db = home / ".pki" / "nssdb"
    db.mkdir(parents=True)
    for args in (["-N", "--empty-password"], ["-A", "-t", "C,,", "-n", "findme-ca", "-i", str(ca)]):
        subprocess.run(["certutil", "-d", f"sql:{db}", *args], check=True, capture_output=True)


# ------------------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def lan():
    reason = why_not()
    if reason:
        pytest.skip(f"multi-host test: {reason}")
    net = Lan(HOSTS, NAMES)
    yield net
    net.close()


@pytest.fixture(scope="module")
def deployment(lan):
    pytest.importorskip("cryptography", reason="cryptography makes the certificates")
    sys.path.insert(0, str(REPO / "tools"))
    from make_certs import make_certs
    tmp = Path(tempfile.mkdtemp(prefix="fmh"))     # short: a Unix socket path lives here
    certs = tmp / "certs"
    make_certs(certs, leaves={"router": ["router", lan.ip["server"]],
                              "gateway": ["gateway", lan.ip["phone"]]})
    (certs / "users.txt").write_text("server:change-me-server\nalice:change-me-alice\n")
    sock = tmp / "router.sock"
    router_conf = _config(COMPOSE / "router-tls.json5", tmp / "router.json5", certs,
                          **{"listen/endpoints": ["tls/0.0.0.0:7447", f"unixsock-stream/{sock}"]})
    by_name = _config(COMPOSE / "service-tls.json5", tmp / "service.json5", certs)
    by_ip = _config(COMPOSE / "service-tls.json5", tmp / "service-ip.json5", certs,
                    **{"connect/endpoints": [f"tls/{lan.ip['server']}:7447"]})
    logs = tmp / "logs"
    logs.mkdir()
    router = lan.spawn("server", "router", "--config", router_conf, log=logs / "router.txt")
    _wait_line(router, "listening on")
    procs = {"router": router}
    for host, name, extra in (("server", "hypotheses", ["--instance", "srv"]),
                              ("worker", "hypotheses", ["--instance", "wrk"]),
                              ("server", "measurement", []), ("server", "odometry", []),
                              ("server", "recorder", ["--out", tmp / "recordings"])):
        procs[f"{name}@{host}"] = lan.spawn(host, "serve", name, "--config", by_name, *extra,
                                            log=logs / f"{name}-{host}.txt")
    procs["gateway"] = lan.spawn(
        "phone", "serve", "gateway", "--config", by_ip, "--http", "0.0.0.0:8443",
        "--tls-cert", certs / "gateway.pem", "--tls-key", certs / "gateway.key",
        log=logs / "gateway.txt")
    observer = open_session(BusConfig(mode="client", connect=(f"unixsock-stream/{sock}",),
                                      user=SERVER_USER[0], password=SERVER_USER[1]))
    tokens = Tokens(observer)
    try:
        want = {"hypotheses/srv", "hypotheses/wrk"}
        tokens.wait(lambda live: want <= live and {t.split("/")[0] for t in live} >=
                    {"measurement", "odometry", "recorder", "gateway"}, 90,
                    "every service on the bus over TLS (ACL allows liveliness)")
        _wait_line(procs["gateway"], "serving https://")
        yield {"tmp": tmp, "certs": certs, "procs": procs, "observer": observer, "sock": sock,
               "tokens": tokens, "logs": logs}
    finally:
        tokens.sub.undeclare()
        observer.close()
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in procs.values():
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
        shutil.rmtree(tmp, ignore_errors=True)


@pytest.fixture(scope="module")
def browser(lan, deployment):
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is missing (apt-get install -y chromium)")
    if shutil.which("certutil") is None:
        pytest.skip("certutil is missing (apt-get install -y libnss3-tools): the browser "
                    "cannot be made to trust the private CA")
    from playwright.sync_api import sync_playwright

    from tests.web.conftest import CHROMIUM_ARGS
    home = deployment["tmp"] / "home"
    _trust_store(home, deployment["certs"] / "ca.pem")
    exe = lan.wrapper("phone", CHROMIUM, deployment["tmp"] / "chromium-on-phone",
                      {"HOME": str(home)})
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(exe), headless=True, args=CHROMIUM_ARGS)
        yield b
        b.close()


# ------------------------------------------------------------------------------ the tests
def _session(browser, want):
    """A page whose session's photo n goes to hypotheses instance ``want[n]`` (None: any);
    reloads (a new session) until the sharding says so."""
    from tests.web.test_web_app import PHONE
    for _ in range(64):
        ctx = browser.new_context(**PHONE)
        page = ctx.new_page()
        page.set_default_timeout(60000)     # a loaded 2-core machine runs 8 processes here
        page.js_errors = []
        page.on("pageerror", lambda e: page.js_errors.append(str(e)))
        page.goto("https://gateway:8443/")
        page.wait_for_selector('#status[data-state="connected"]')
        sid = page.evaluate("FindMe.state.session")
        owner = [shard_owner(f"findme/{sid}/frame/{n}", {"srv", "wrk"}) for n in range(len(want))]
        if all(w is None or o == w for o, w in zip(owner, want)):
            assert page.evaluate("window.isSecureContext"), "the page is not a secure context"
            return page, sid
        ctx.close()
    raise AssertionError(f"no session in 64 whose photos go to {want}")


def _upload(page, path, side, n):
    from tests.web.test_web_app import type_camera
    type_camera(page, side, height=repr(side["camera_height_m"]))
    page.set_input_files("#file-input", path)
    page.wait_for_selector(f'#photo-tabs .tab[data-index="{n}"]')   # the gateway took it


def test_two_photo_session_across_hosts(lan, deployment, browser, tmp_path):
    """Photos 0 and 1 on different hypotheses hosts; numbers equal findme run's; the
    recording is complete."""
    from tests.web.test_web_app import tap_pixel
    d = deployment
    page, sid = _session(browser, ["srv", "wrk"])
    _upload(page, ROOM_A, SIDE_A, 0)
    page.wait_for_selector('#frame[data-index="0"][data-scene-rank="1"]')
    for q in SIDE_A["ground_truth"]["floor_points"][1:3]:
        tap_pixel(page, *q["px"])
    page.wait_for_selector('#points li[data-surface="floor"] >> nth=1')
    pixels = page.eval_on_selector_all("#points li", "els => els.map(e => [+e.dataset.u, +e.dataset.v])")
    _upload(page, ROOM_B, SIDE_B, 1)
    page.wait_for_selector('.motion-line[data-pair="0-1"]', timeout=60000)
    page.wait_for_selector('#floor-map[data-poses="2"]')
    assert not page.js_errors, page.js_errors
    page.context.close()

    # the work was shared by both hypotheses hosts, each photo handled once
    from findme.cli.status import service_statuses
    fresh = open_session(BusConfig(mode="client", connect=(f"unixsock-stream/{d['sock']}",),
                                   user=SERVER_USER[0], password=SERVER_USER[1]))
    try:
        st = {s.instance: s for s in service_statuses(fresh) if s.service == "hypotheses"}
    finally:
        fresh.close()
    assert {i: s.counters["hypothesis_sets"] for i, s in st.items()} == {"srv": 1, "wrk": 1}

    # the recording is complete (the recorder finishes its files on SIGTERM)
    rec = d["procs"]["recorder@server"]
    rec.send_signal(signal.SIGTERM)
    assert rec.wait(30) == 0
    recorded = {r.key: r for r in read_recording(d["tmp"] / "recordings" / f"{sid}.mcap")}
    want = {f"findme/{sid}/{k}" for k in
            [f"{kind}/{n}" for kind in ("frame", "hypotheses", "selection", "scene", "pose")
             for n in range(2)] + ["motion/0/1", "trajectory", "measured/0"]}
    assert want <= set(recorded), sorted(want - set(recorded))

    # the numbers equal findme run's on the same photos and pixels
    run = subprocess.run([sys.executable, "-m", "findme.cli", "run", "--session", "ref",
                          "--out", str(tmp_path), *[f"--measure={u:g},{v:g}" for u, v in pixels]],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    ref = {r.key.replace("findme/ref/", ""): r.message() for r in
           read_recording(tmp_path / "ref.mcap") if r.message() is not None}
    ours = {k.replace(f"findme/{sid}/", ""): r.message() for k, r in recorded.items()
            if r.message() is not None}
    for n in (0, 1):
        a, b = ours[f"hypotheses/{n}"], ref[f"hypotheses/{n}"]
        assert [h.polyline for h in a.hypotheses] == [h.polyline for h in b.hypotheses]
    m, r = ours["motion/0/1"], ref["motion/0/1"]
    assert (m.x_m, m.z_m, m.yaw_rad, m.inliers, m.matches) == \
        pytest.approx((r.x_m, r.z_m, r.yaw_rad, r.inliers, r.matches), abs=1e-9)
    p, q = ours["measured/0"], ref["measured/0"]
    assert len(p.points) == len(q.points) == 2
    assert [c for x in p.points for c in (x.xyz.x, x.xyz.y, x.xyz.z)] == \
        pytest.approx([c for x in q.points for c in (x.xyz.x, x.xyz.y, x.xyz.z)], abs=1e-9)
    assert p.distances[0].distance_m == pytest.approx(q.distances[0].distance_m, abs=1e-9)


def test_worker_link_cut_mid_session_loses_no_photo(lan, deployment, browser):
    """The worker's cable is pulled while photo 1 (the worker's by the sharding) is sent,
    then plugged back in, and photo 2 is sent: every photo gets its pose (recovery: a frame whose owner vanished is
    handled by another instance or by the owner once back)."""
    d = deployment
    page, sid = _session(browser, [None, "wrk"])
    keys = Keys(d["observer"], sid)
    _upload(page, ROOM_A, SIDE_A, 0)
    page.wait_for_selector('#frame[data-index="0"][data-scene-rank="1"]')
    lan.link("worker", up=False)
    _upload(page, ROOM_B, SIDE_B, 1)
    d["tokens"].wait(lambda live: "hypotheses/wrk" not in live, 30, "the worker leaves the bus")
    lan.link("worker", up=True)
    d["tokens"].wait(lambda live: "hypotheses/wrk" in live, 60, "the worker joins again")
    _upload(page, ROOM_A, SIDE_A, 2)

    def trajectory_of_3(got):
        t = got.get(f"findme/{sid}/trajectory")
        return t is not None and len(schemas.decode(schemas.Trajectory, t).poses) == 3
    done = keys.wait(trajectory_of_3, 60)
    have = sorted(k.split("/", 2)[2] for k in keys.got)
    keys.sub.undeclare()
    assert done, ("a photo was lost when the worker's link went down and came back "
                  f"(recovery): the session has {have}; errors: {keys.errors}")
    page.wait_for_selector('#floor-map[data-poses="3"]')
    assert not page.js_errors, page.js_errors
    page.context.close()
