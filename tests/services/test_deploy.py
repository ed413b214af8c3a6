"""Deployment files: every Procfile line is a valid findme command, every Zenoh config
loads, and the phone + server router configuration enforces TLS, passwords and per-device
keys (run for real with generated certificates)."""

import shlex
import threading
from pathlib import Path

import pytest
import zenoh

from findme.cli import build_parser
from services.runtime.bus import BusConfig, open_session
from tests.services.conftest import start_tls_router

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
    proc, endpoint, tls, _ = start_tls_router(
        tmp_path, {"server": "change-me-server", "alice": "change-me-alice"})
    yield endpoint, tls
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
