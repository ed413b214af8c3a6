"""``findme up``, as the README runs it: the router and one process per service start as
children (this Python, no PATH), say when ready, take ``findme send``, log one line per
handled message, and all stop on SIGTERM (exit 0) or when one of them dies."""

import os
import signal
import subprocess
import sys
import threading

from tests.cli.conftest import run_findme
from tests.services.conftest import assert_example_motion, free_port


def _up(tmp_path, *extra):
    ep = f"tcp/127.0.0.1:{free_port()}"
    env = {**os.environ, "PATH": "/usr/bin:/bin"}        # no venv on PATH
    proc = subprocess.Popen([sys.executable, "-m", "findme.cli", "up", "--listen", ep,
                             "--out", str(tmp_path / "rec"), *extra], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    proc.lines, proc.cv = [], threading.Condition()

    def drain():
        for line in proc.stdout:
            with proc.cv:
                proc.lines.append(line)
                proc.cv.notify_all()
    proc.drain = threading.Thread(target=drain, daemon=True)
    proc.drain.start()
    return ep, proc


def _wait(proc, text, timeout=90):
    with proc.cv:
        assert proc.cv.wait_for(lambda: any(text in x for x in proc.lines), timeout), \
            "".join(proc.lines)[-3000:]


def _stat(path: str) -> list[str]:
    """The fields of a /proc/.../stat file after the command name (field 3 on)."""
    with open(path) as f:
        return f.read().rsplit(")", 1)[1].split()


#: the threads Zenoh's runtime names (Python's own threads keep the program's name)
ZENOH_THREADS = ("app-", "net-", "rx-", "tx-", "acc-")


def _niceness(pid: int) -> tuple[set[int], set[int]]:
    """The nice values (/proc/<pid>/task/*/stat, field 19: Linux keeps one per thread) of
    a process's Python threads and of Zenoh's runtime threads."""
    py, zenoh = set(), set()
    for tid in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{tid}/comm") as f:
            name = f.read().strip()
        (zenoh if name.startswith(ZENOH_THREADS) else py).add(
            int(_stat(f"/proc/{pid}/task/{tid}/stat")[16]))
    return py, zenoh


def _policies(pid: int) -> set[int]:
    """The scheduling policies of all a process's threads (/proc/<pid>/task/*/stat, field
    41), the Zenoh runtime's included."""
    return {int(_stat(f"/proc/{pid}/task/{tid}/stat")[38])
            for tid in os.listdir(f"/proc/{pid}/task")}


def test_up_serves_send_and_stops_on_sigterm(tmp_path):
    ep, up = _up(tmp_path)
    try:
        _wait(up, "| ready: 9 services")
        # CPU priorities on a saturated machine: the stages after the first go first, the
        # floor plans last (``Handler.nice``, applied by ``findme serve``)
        pids = {x.split(" started (pid=")[0].split()[-1]: int(x.split("pid=")[1].split(")")[0])
                for x in up.lines if " started (pid=" in x}
        nice = {k: _niceness(p) for k, p in pids.items()}
        (base,), _ = nice["router"]    # this test's own niceness (0 unless CI runs niced)
        want = {"odometry1": 0, "odometry2": 0, "selection": 0, "measurement": 0,
                "hypotheses1": 10, "hypotheses2": 10, "mapper": 19}
        # the service's threads yield; the bus's I/O threads keep the test's priority (a
        # niced subscriber still drains its link)
        assert {k: nice[k] for k in want} == {k: ({min(base + v, 19)}, {base})
                                              for k, v in want.items()}
        # off the way from a photo to its pose, every thread SCHED_BATCH (set before the bus
        # starts its threads): their wake-ups wait for the running photo's slice
        batch = {"store", "recorder", "mapper"}
        base_policy = _policies(pids["router"])   # the test's own (normal unless CI says not)
        assert {k: _policies(p) for k, p in pids.items()} == {
            k: {os.SCHED_BATCH} if k in batch else base_policy for k in pids}
        assert len(pids) == 10
        # the hint names the command as it was run (here: this Python -m findme.cli)
        _wait(up, f"send photos with: {sys.executable} -m findme.cli send --connect {ep}\n")
        p = run_findme("send", "--connect", ep, "--session", "up-1", check=False)
        assert p.returncode == 0, p.stderr
        assert_example_motion(p.stdout)
        _wait(up, "findme/up-1/frame/0 -> findme/up-1/hypotheses/0 (")   # one line per message
        _wait(up, "-> findme/up-1/scene/1")
    finally:
        up.send_signal(signal.SIGTERM)
        code = up.wait(60)
        up.drain.join(10)           # every line read (the pipe is closed)
    log = "".join(up.lines)
    assert code == 0, log[-3000:]
    for name in ("router", "store", "hypotheses1", "hypotheses2", "selection", "measurement",
                 "odometry1", "odometry2", "mapper", "recorder"):
        assert f"{name} stopped (rc=0)" in log, name
    assert (tmp_path / "rec" / "up-1.mcap").stat().st_size > 0


def test_up_stops_all_when_one_dies_and_quiet_logs_no_message_lines(tmp_path):
    ep, up = _up(tmp_path, "--quiet", "--hypotheses", "1")
    try:
        _wait(up, "ready: 8 services")
        pid = next(int(x.split("pid=")[1].rstrip(")\n")) for x in up.lines
                   if "odometry1 started (pid=" in x)
        os.kill(pid, signal.SIGKILL)
        code = up.wait(60)
        up.drain.join(10)
    finally:
        if up.poll() is None:
            up.kill()
    log = "".join(up.lines)
    assert code == -signal.SIGKILL or code != 0, log
    assert "router stopped (rc=0)" in log and "measurement stopped (rc=0)" in log, log
    assert " INFO " not in log


def test_up_refuses_a_port_in_use_before_it_starts_anything(tmp_path):
    """Another router on the port: one line naming it (exit status 2), nothing started, no
    "ready" (the services would have joined the other router)."""
    import socket
    import time
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        t0 = time.monotonic()
        p = subprocess.run([sys.executable, "-m", "findme.cli", "up", "--listen",
                            f"tcp/127.0.0.1:{port}"], cwd=tmp_path, capture_output=True,
                           text=True, timeout=60)
        took = time.monotonic() - t0
    assert p.returncode == 2 and took < 10, (p.returncode, took, p.stderr)
    assert p.stdout == "" and p.stderr.count("\n") == 1, p.stdout + p.stderr
    assert f"cannot listen on tcp/127.0.0.1:{port}: Address already in use" in p.stderr
