"""A recorder killed with SIGKILL mid-session loses at most the last FLUSH_BOUND_S (1 s):
``findme recover`` salvages every message the recorder received before that."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import numpy as np

import schemas
from findme_io.imageio import encode_jpeg
from findme_core.errors import RecordingError
from services.runtime import bus
from findme_io.convert import make_frame
from services.recording.mcap_reader import read_recording
from services.recording.recorder import FLUSH_BOUND_S

from .conftest import ROOT, free_port, wait_service

SESSION = "killed-session"
RATE_HZ = 40        # messages per second, spread over ...
SECONDS = 2.5       # ... more than twice the flush bound


def test_sigkill_then_recover_keeps_everything_older_than_the_flush_bound(tmp_path, cli):
    port = free_port()
    session = bus.open_session(bus.BusConfig(listen=(f"tcp/127.0.0.1:{port}",)))
    proc = subprocess.Popen(
        [sys.executable, "-m", "findme.cli", "serve", "recorder", "--out", str(tmp_path),
         "--mode", "peer", "--connect", f"tcp/127.0.0.1:{port}"],
        cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    sent: list[tuple[str, bytes, int]] = []
    try:
        wait_service(session, "recorder")
        rng = np.random.default_rng(0)
        jpeg = encode_jpeg(rng.integers(0, 255, (48, 64, 3), dtype=np.uint8), 80)
        # a workload spread over time (not a synchronisation): one frame every 1/RATE_HZ s
        pace = threading.Event()
        t0 = time.monotonic()
        for n in range(int(RATE_HZ * SECONDS)):
            pace.wait(max(0.0, t0 + n / RATE_HZ - time.monotonic()))
            f = make_frame(SESSION, n, jpeg, hfov_deg=60.0, time_ns=time.time_ns())
            key, payload = bus.key(SESSION, "frame", n), schemas.encode(f)
            bus.put(session, key, payload)
            sent.append((key, payload, time.time_ns()))
        killed_at = time.time_ns()
        proc.kill()                                   # SIGKILL: no clean-up at all
        assert proc.wait(10) == -9
    finally:
        if proc.poll() is None:
            proc.kill()
        session.close()

    broken = tmp_path / f"{SESSION}.mcap"
    try:
        read_recording(broken)
        raise AssertionError("a killed recorder's file should lack its summary")
    except RecordingError:
        pass
    fixed = tmp_path / "fixed.mcap"
    rc, out, _ = cli("recover", broken, "-o", fixed)
    assert rc == 0
    kept = read_recording(fixed)
    assert f"({len(kept)} bus messages" in out and out.startswith("recovered ")
    got = {r.key: r.payload for r in kept}
    old = [(k, p) for k, p, t in sent if t < killed_at - FLUSH_BOUND_S * 1e9]
    assert len(old) >= RATE_HZ  # the test exercised more than a second of history
    missing = [k for k, p in old if got.get(k) != p]
    assert not missing, f"{len(missing)} messages older than {FLUSH_BOUND_S} s were lost"
    # what was kept is exactly a prefix of what was sent, in order, intact
    assert [(r.key, r.payload) for r in kept] == [(k, p) for k, p, _ in sent[:len(kept)]]
    lost = sent[len(kept):]
    youngest_lost_age = (killed_at - lost[0][2]) / 1e9 if lost else 0.0
    print(f"\nsent {len(sent)}, recovered {len(kept)}, lost {len(lost)} "
          f"(the oldest lost was {youngest_lost_age * 1e3:.0f} ms old at the kill)")
