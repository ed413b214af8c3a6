"""Deployment files: every Procfile line is a valid findme command, every Zenoh config
loads, and the phone + server router configuration enforces TLS, passwords and per-device
keys (run for real with generated certificates)."""

import json
import shlex
import signal
import sys
import threading
from importlib import resources
from pathlib import Path

import pytest
import zenoh

from findme.cli import build_parser
from findme_core.errors import InputError
from services.runtime.bus import BusConfig, open_session
from tests.cli.conftest import run_findme
from tests.services.conftest import (assert_example_motion, spawn_findme, start_tls_router,
                                     wait_logged)

COMPOSE = Path(__file__).resolve().parents[2] / "compose"


def test_procfile_is_what_findme_up_runs():
    """compose/Procfile (for foreman/honcho users) lists exactly the processes of
    ``findme up``, and each line is a valid findme command."""
    lines = [ln for ln in (COMPOSE / "Procfile").read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    from findme.cli.up import processes
    parser = build_parser()
    want = [f"{name}: {shlex.join(['findme', *argv])}"
            for name, argv in processes(parser.parse_args(["up"]))]
    assert lines == want
    names = {ln.split(":")[0] for ln in lines}
    assert {"router", "selection", "measurement", "mapper", "recorder"} <= names
    assert sum(n.startswith("hypotheses") for n in names) == 2
    assert {n for n in names if n.startswith("odometry")} == {"odometry1", "odometry2"}
    for ln in lines:
        argv = shlex.split(ln.split(":", 1)[1])
        assert parser.parse_args(argv[1:]).command in ("router", "serve")


def _compose_commands() -> dict[str, list[str]]:
    """service -> its command (each a JSON list on one line, as the file says)."""
    out, service = {}, None
    for ln in (COMPOSE / "docker-compose.yml").read_text().splitlines():
        bare = ln.split("#", 1)[0].rstrip()
        if bare.startswith("  ") and not bare.startswith("   ") and bare.endswith(":"):
            service = bare.strip()[:-1]
        elif ln.strip().startswith("command:"):
            out[service] = json.loads(ln.split(":", 1)[1])
    return out


def test_compose_commands_certificates_and_image_files():
    """Every compose command is a valid findme command; the certificate names every host
    the services connect to and every TLS file they use; the image copies every package
    and its build context leaves out the venv, keys and recordings; certs/ is git-ignored."""
    cmds = _compose_commands()
    assert set(cmds) == {"router", "store", "hypotheses", "measurement", "odometry", "mapper",
                         "recorder", "gateway"}
    parser = build_parser()
    for argv in cmds.values():
        assert parser.parse_args(argv).command in ("router", "serve")
    sys.path.insert(0, str(COMPOSE.parent / "tools"))
    from make_certs import COMPOSE_TLS_HOSTS
    conf = zenoh.Config.from_file(str(COMPOSE / "service-tls.json5"))
    hosts = {e.split("/", 1)[1].rsplit(":", 1)[0] for e in json.loads(conf.get_json("connect/endpoints"))}
    assert hosts == {"router"} and hosts <= set(COMPOSE_TLS_HOSTS)
    gw = cmds["gateway"]
    assert gw[gw.index("--tls-cert") + 1] == "/certs/gateway.pem" and "gateway" in COMPOSE_TLS_HOSTS
    docker = (COMPOSE / "Dockerfile").read_text()
    import tomllib
    include = tomllib.loads((COMPOSE.parent / "pyproject.toml").read_text())[
        "tool"]["setuptools"]["packages"]["find"]["include"]
    for pkg in include:
        assert f"COPY {pkg.rstrip('*')} " in docker, pkg
    ignored = (COMPOSE.parent / ".dockerignore").read_text().split()
    assert {".venv/", "certs/", ".git/", "recordings/*", "**/__pycache__/"} <= set(ignored)
    assert "certs/" in (COMPOSE.parent / ".gitignore").read_text().split()


def test_make_certs_names_compose_hosts_and_given_ones(tmp_path):
    pytest.importorskip("cryptography", reason="cryptography reads the certificates")
    from cryptography import x509
    sys.path.insert(0, str(COMPOSE.parent / "tools"))
    from make_certs import main
    main([str(tmp_path), "--host", "findme.lan", "--host", "192.168.1.20"])
    for stem in ("router", "gateway"):
        cert = x509.load_pem_x509_certificate((tmp_path / f"{stem}.pem").read_bytes())
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        assert set(san.get_values_for_type(x509.DNSName)) == {stem, "localhost", "findme.lan"}
        assert {str(a) for a in san.get_values_for_type(x509.IPAddress)} == {"127.0.0.1", "192.168.1.20"}
        eku = cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
        assert x509.oid.ExtendedKeyUsageOID.SERVER_AUTH in eku
        assert (tmp_path / f"{stem}.key").stat().st_mode & 0o077 == 0
    ca = x509.load_der_x509_certificate((tmp_path / "ca.crt").read_bytes())
    assert ca == x509.load_pem_x509_certificate((tmp_path / "ca.pem").read_bytes())


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


def test_a_device_sends_photos_through_the_tls_router(tls_router, tmp_path):
    """``findme send`` as device alice (her password, the CA) to services joined as the
    server user, with the store as compose/docker-compose.yml runs it (odometry fetches a
    selected photo's frame from it: alice may not answer queries): the report of findme
    run, in a session named after her."""
    endpoint, tls = tls_router
    server_pw, alice_pw = tmp_path / "server.pw", tmp_path / "alice.pw"
    server_pw.write_text("change-me-server\n")
    alice_pw.write_text("change-me-alice\n")
    auth = ["--connect", endpoint, "--ca", tls["root_ca_certificate"]]
    procs = [spawn_findme("serve", name, *auth, "--user", "server", "--password-file", server_pw)
             for name in ("store", "hypotheses", "measurement", "odometry")]
    try:
        for p in procs:
            wait_logged(p, " started")
        p = run_findme("send", *auth, "--user", "alice", "--password-file", alice_pw,
                       "--wait", "30", check=False)
        assert p.returncode == 0, p.stderr
        assert "session alice-" in p.stdout
        assert_example_motion(p.stdout)
    finally:
        for p in procs:
            p.send_signal(signal.SIGTERM)
        for p in procs:
            p.wait(20)


def test_app_https_serves_the_page_with_the_generated_certificate(tmp_path):
    """``findme app --https`` uses certs/gateway.pem; a client trusting ca.pem (as a phone
    with ca.crt installed) gets the page. Without the files: one line, exit 2."""
    import ssl
    import subprocess
    import urllib.request
    no = subprocess.run([sys.executable, "-m", "findme.cli", "app", "--https"], cwd=tmp_path,
                        capture_output=True, text=True, timeout=60)
    assert no.returncode == 2 and no.stderr.count("\n") == 1 and "make_certs.py" in no.stderr
    pytest.importorskip("cryptography", reason="cryptography makes the certificates")
    sys.path.insert(0, str(COMPOSE.parent / "tools"))
    from make_certs import make_certs
    make_certs(tmp_path / "certs")
    app = subprocess.Popen([sys.executable, "-m", "findme.cli", "app", "--https", "--http",
                            "127.0.0.1:0", "--no-record"], cwd=tmp_path, text=True,
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        line = app.stdout.readline()              # the readiness line
        assert "serving https://127.0.0.1:" in line, line
        url = line.split("serving ", 1)[1].split()[0]
        ctx = ssl.create_default_context(cafile=str(tmp_path / "certs" / "ca.pem"))
        with urllib.request.urlopen(url, context=ctx, timeout=30) as r:
            assert r.status == 200 and b"<html" in r.read().lower()
    finally:
        app.send_signal(signal.SIGTERM)
        assert app.wait(30) == 0


def test_background_services_ask_for_batch_scheduling_and_survive_a_refusal(monkeypatch, caplog):
    import os

    from findme.cli import serve
    from services.registry import make_handler
    args = build_parser().parse_args(["serve", "store"])
    assert {n for n in ("store", "recorder", "mapper", "measurement", "odometry", "selection",
                        "hypotheses") if make_handler(n, args).background} == \
        {"store", "recorder", "mapper"}
    calls = []
    monkeypatch.setattr(os, "sched_setscheduler", lambda pid, pol, prm: calls.append((pid, pol)))
    assert serve.background_scheduling() and calls == [(0, os.SCHED_BATCH)]   # this thread on

    def refuse(*_):
        raise PermissionError(1, "Operation not permitted")
    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    assert not serve.background_scheduling()
    assert "cannot run as background work (SCHED_BATCH: Operation not permitted)" in caplog.text
    monkeypatch.delattr(os, "SCHED_BATCH")      # an OS without the policy: nothing asked
    assert not serve.background_scheduling()


def test_up_without_the_mapper():
    from findme.cli.up import processes
    names = [n for n, _ in processes(build_parser().parse_args(["up", "--no-mapper"]))]
    assert "mapper" not in names and {"odometry1", "measurement", "recorder"} <= set(names)


def test_up_starts_the_odometry_instances_asked_for():
    from findme.cli.up import processes
    procs = processes(build_parser().parse_args(["up", "--odometry", "3"]))
    odo = [argv for n, argv in procs if n.startswith("odometry")]
    assert [a[a.index("--instance") + 1] for a in odo] == ["o1", "o2", "o3"]
    with pytest.raises(InputError, match="--odometry must be at least 1, got 0"):
        processes(build_parser().parse_args(["up", "--odometry", "0"]))


def _send_in_process(capsys, *argv):
    """``findme send ARGV`` in this process: (exit status, stderr, seconds it took)."""
    import logging
    import time

    from findme.cli import main
    handlers = logging.root.handlers[:]
    t0 = time.monotonic()
    try:
        rc = main([str(a) for a in argv])
    finally:
        logging.root.handlers[:] = handlers
    took = time.monotonic() - t0
    return rc, capsys.readouterr().err, took


def test_a_refused_session_or_password_is_one_clear_line_within_5_s(tls_router, tmp_path,
                                                                    capsys):
    """As device alice: a session the router's access control does not give her
    (``--session bob-123``), or a wrong password, is one line saying so (exit status 2)
    within 5 s, not a 120 s wait that blames the services. Services: the server user's
    liveliness tokens (``send`` checks that they are alive first)."""
    from services.runtime import bus as rbus
    endpoint, tls = tls_router
    server = open_session(BusConfig(mode="client", connect=(endpoint,), tls=tls,
                                    user="server", password="change-me-server"))
    tokens = [server.liveliness().declare_token(f"{rbus.SERVICES}/{name}/t")
              for name in ("hypotheses", "measurement")]
    good, bad = tmp_path / "alice.pw", tmp_path / "wrong.pw"
    good.write_text("change-me-alice\n")
    bad.write_text("not-her-password\n")
    photo = str(resources.files("findme") / "examples" / "room_a.jpg")
    auth = ["--connect", endpoint, "--ca", tls["root_ca_certificate"], "--user", "alice"]
    try:
        rc, err, took = _send_in_process(capsys, "send", photo, *auth, "--password-file", good,
                                         "--session", "bob-123")
        assert rc == 2 and err.count("\n") == 1 and took < 5.0, (rc, took, err)
        assert ("did not pass on photo 0 of session 'bob-123' within 2 s: its access control "
                "does not let user 'alice' use that session (a device may only use sessions "
                "that start with its user name, alice-...") in err
        rc, err, took = _send_in_process(capsys, "send", photo, *auth, "--password-file", bad)
        assert rc == 2 and err.count("\n") == 1 and took < 5.0, (rc, took, err)
        assert (f"the router at {endpoint} answers but refused this client: as user 'alice' "
                "the password is wrong") in err
        # a device sees which services are alive, not their counters: said, not zeros
        from findme.cli import main
        assert main(["status", *auth, "--password-file", str(good)]) == 0
        out = capsys.readouterr().out
        assert "hypotheses   t             alive  no counters (this client may not read them" \
            in out, out
    finally:
        for t in tokens:
            t.undeclare()
        server.close()


def test_procfile_tls_runs_the_compose_services_with_local_configs(tmp_path):
    """compose/Procfile.tls (the TLS deployment on one machine, no Docker) runs what the
    compose file runs, each line a valid findme command on the configurations
    ``make_certs.py --local`` writes: compose's, with this folder's paths and the router on
    localhost, loadable by Zenoh."""
    lines = [ln for ln in (COMPOSE / "Procfile.tls").read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    parser = build_parser()
    names = set()
    for ln in lines:
        name, cmd = ln.split(":", 1)
        argv = shlex.split(cmd)
        assert argv[0] == "findme" and parser.parse_args(argv[1:]).command in ("router", "serve")
        names.add(argv[2] if argv[1] == "serve" else "router")
        assert any(a.startswith("certs/") and a.endswith("-local.json5") for a in argv), ln
    assert names == set(_compose_commands())
    sys.path.insert(0, str(COMPOSE.parent / "tools"))
    from make_certs import main
    main([str(tmp_path / "certs"), "--local"])
    for name in ("router-local.json5", "service-local.json5"):
        text = (tmp_path / "certs" / name).read_text()
        assert '"/certs/' not in text and f'"{(tmp_path / "certs").resolve()}/' in text
        zenoh.Config.from_file(str(tmp_path / "certs" / name))
    conf = zenoh.Config.from_file(str(tmp_path / "certs" / "service-local.json5"))
    assert json.loads(conf.get_json("connect/endpoints")) == ["tls/localhost:7447"]
