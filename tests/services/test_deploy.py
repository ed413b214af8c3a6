"""Deployment files: every Procfile line is a valid findme command, every Zenoh config
loads, and the phone + server router configuration enforces TLS, passwords and per-device
keys (run for real with generated certificates)."""

import shlex
import sys
import threading
from pathlib import Path

import pytest
import zenoh

from findme.cli import build_parser
from services.runtime.bus import BusConfig, open_session
from tests.services.conftest import free_port, spawn_findme, wait_logged

COMPOSE = Path(__file__).resolve().parents[2] / "compose"


def test_procfile_lines_are_findme_commands():
    lines = [ln for ln in (COMPOSE / "Procfile").read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    assert len(lines) >= 5
    parser = build_parser()
    for ln in lines:
        name, cmd = ln.split(":", 1)
        argv = shlex.split(cmd)
        assert argv[0] == "findme", ln
        args = parser.parse_args(argv[1:])
        assert args.command in ("router", "serve")


@pytest.mark.parametrize("name", ["router.json5", "router-tls.json5", "service-tls.json5"])
def test_zenoh_configs_load(name):
    zenoh.Config.from_file(str(COMPOSE / name))


@pytest.fixture
def tls_router(tmp_path):
    pytest.importorskip("cryptography", reason="cryptography generates the test certificates")
    sys.path.insert(0, str(COMPOSE.parent / "tools"))
    from make_certs import make_certs
    make_certs(tmp_path, ("localhost", "127.0.0.1"))
    (tmp_path / "users.txt").write_text("server:change-me-server\nalice:change-me-alice\n")
    port = free_port()
    cfg = (COMPOSE / "router-tls.json5").read_text()
    cfg = cfg.replace("/certs/", f"{tmp_path}/").replace("tls/0.0.0.0:7447", f"tls/127.0.0.1:{port}")
    (tmp_path / "router.json5").write_text(cfg)
    proc = spawn_findme("router", "--config", tmp_path / "router.json5")
    wait_logged(proc, "listening on")
    yield f"tls/127.0.0.1:{port}", {"root_ca_certificate": str(tmp_path / "ca.pem")}
    proc.terminate()
    proc.wait(10)


def test_tls_passwords_and_per_device_keys(tls_router):
    endpoint, tls = tls_router
    server = open_session(BusConfig(mode="client", connect=(endpoint,), tls=tls,
                                    user="server", password="change-me-server"))
    got, cv = [], threading.Condition()

    def cb(s):
        with cv:
            got.append(str(s.key_expr))
            cv.notify_all()

    sub = server.declare_subscriber("findme/**", cb)
    alice = open_session(BusConfig(mode="client", connect=(endpoint,), tls=tls,
                                   user="alice", password="change-me-alice"))
    # the server's subscription reaches alice's side asynchronously: repeat a put until one
    # arrives (each waits on the delivery, not a fixed time)
    for _ in range(100):
        alice.put("findme/alice-1/frame/0", b"x")
        with cv:
            if cv.wait_for(lambda: got, 0.05):
                break
    assert "findme/alice-1/frame/0" in got
    alice.put("findme/bob-1/frame/0", b"not hers")
    alice.put("findme/alice-1/frame/1", b"x")     # same client, so it arrives after bob's would
    with cv:
        assert cv.wait_for(lambda: "findme/alice-1/frame/1" in got, 10)
    assert "findme/bob-1/frame/0" not in got
    sub.undeclare()
    alice.close()
    for bad in (BusConfig(mode="client", connect=(endpoint,), tls=tls, user="alice",
                          password="wrong", connect_timeout_ms=1500),
                BusConfig(mode="client", connect=(endpoint.replace("tls/", "tcp/"),),
                          user="alice", password="change-me-alice", connect_timeout_ms=1500)):
        with pytest.raises(Exception, match="cannot open the Zenoh session"):
            open_session(bad)
    server.close()
