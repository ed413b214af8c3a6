"""A recording in Rerun: ``findme view --rrd`` (our adapters and blueprint), the viewer
service, and Rerun's own MCAP loader on the view channels; every .rrd is read back."""

from __future__ import annotations

import os
import socket
import subprocess
import time
from collections import defaultdict
from pathlib import Path

import pytest

from services.recording.mcap_reader import read_recording

from .conftest import PAIR

SID = "golden-examples-pair"


def rrd_contents(path) -> dict[str, set[str]]:
    """entity path -> component columns (e.g. "EncodedImage:blob") of the first recording."""
    import rerun.chunk as rc
    out: dict[str, set[str]] = defaultdict(set)
    for chunk in rc.RrdReader(str(path)).stream():
        out[chunk.entity_path] |= {f.name for f in chunk.to_record_batch().schema if ":" in f.name}
    return out


def column(path, entity: str, col: str) -> list:
    import rerun.chunk as rc
    vals = []
    for chunk in rc.RrdReader(str(path)).stream():
        if chunk.entity_path == entity:
            rb = chunk.to_record_batch()
            if col in rb.schema.names:
                vals += rb.column(col).to_pylist()
    return vals


def test_findme_view_writes_images_hypotheses_and_poses(full_recording, tmp_path, cli):
    out = tmp_path / "session.rrd"
    rc, text, err = cli("view", full_recording, "--rrd", out)
    assert rc == 0, err
    assert str(out) in text
    c = rrd_contents(out)
    img = "/world/photo/0/camera/image"
    assert {"EncodedImage:blob", "EncodedImage:media_type", "Pinhole:image_from_camera"} <= c[img]
    assert {"EncodedImage:blob"} <= c["/world/photo/1/camera/image"]
    assert "LineStrips2D:strips" in c[f"{img}/hypotheses"]
    assert column(out, f"{img}/hypotheses", "LineStrips2D:labels")[0] == [str(i) for i in range(1, 11)]
    assert "LineStrips2D:strips" in c[f"{img}/boundary"]
    # poses: photo 1 placed by its pose, the trajectory through both camera centres
    assert "Transform3D:translation" in c["/world/photo/1"]
    tr = column(out, "/world/photo/1", "Transform3D:translation")
    pose1 = [r.message() for r in read_recording(full_recording)
             if r.schema == "findme.v1.Pose" and r.message().index == 1][-1]
    assert tr[-1][0] == pytest.approx([pose1.x_m, 0.0, pose1.z_m], abs=1e-6)
    assert "LineStrips3D:strips" in c["/world/trajectory"]
    assert "Transform3D:mat3x3" in c["/world/photo/0/camera"]
    # floor and walls in 3D, measured points and distances, the log
    assert "Mesh3D:vertex_positions" in c["/world/photo/0/floor"]
    assert "Mesh3D:vertex_positions" in c["/world/photo/0/walls"]
    assert "Points3D:positions" in c["/world/photo/0/camera/measure/0/points"]
    assert "LineStrips3D:labels" in c["/world/photo/0/camera/measure/0/distances"]
    assert "TextLog:text" in c["/log"]
    import rerun.chunk as rcc
    assert rcc.RrdReader(str(out)).blueprints(), "the layout (blueprint) is in the file"


def test_view_defaults_to_rrd_beside_the_mcap_when_headless(tmp_path, cli, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    src = tmp_path / "pair.mcap"
    src.write_bytes(PAIR.read_bytes())
    rc, text, err = cli("view", src)
    assert rc == 0, err
    assert (tmp_path / "pair.rrd").exists()
    assert "EncodedImage:blob" in rrd_contents(tmp_path / "pair.rrd")["/world/photo/0/camera/image"]


def test_viewer_service_shows_the_bus_live_into_rrd(full_recording, tmp_path):
    from services.recording.viewer import Sink, ViewerHandler
    h = ViewerHandler(Sink("rrd", path=str(tmp_path)))
    recs = read_recording(full_recording)
    for r in recs:
        h.on_message(r.key, r.payload)
    h.close()
    c = rrd_contents(tmp_path / f"{SID}.rrd")
    assert "EncodedImage:blob" in c["/world/photo/1/camera/image"]
    assert "LineStrips2D:strips" in c["/world/photo/1/camera/image/hypotheses"]
    assert "Transform3D:translation" in c["/world/photo/1"]
    drawn_alone = {"findme.v1.Selection"}  # shown through the scene it leads to
    assert h.counters()["not_shown"] == 0
    assert h.counters()["shown"] == sum(r.schema not in drawn_alone for r in recs)


def test_rerun_own_mcap_loader_sees_images_poses_and_transforms(full_recording, tmp_path):
    from services.recording.viewer import _rerun_cli
    out = tmp_path / "converted.rrd"
    r = subprocess.run([*_rerun_cli(), "mcap", "convert", str(full_recording), "-o", str(out)],
                       capture_output=True, text=True, timeout=120, env=dict(os.environ))
    assert r.returncode == 0, r.stderr
    c = rrd_contents(out)
    base = f"/findme/{SID}/foxglove"
    assert {"EncodedImage:blob", "EncodedImage:media_type"} <= c[f"{base}/image"]
    assert "Pinhole:image_from_camera" in c[f"{base}/calibration"]
    assert "Transform3D:quaternion" in c[f"{base}/tf"]
    assert "InstancePoses3D:translations" in c[f"{base}/pose"]
    assert "InstancePoses3D:translations" in c[f"{base}/trajectory"]
    # our own messages stay as decoded protobuf (the loader reads the embedded schemas)
    assert "findme.v1.HypothesisSet:message" in c[f"/findme/{SID}/hypotheses"]


def _listening(pid: int) -> set[str]:
    """ip:port of the TCP sockets process ``pid`` listens on (from /proc)."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    out = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            f = line.split()
            if f[3] == "0A" and f[9] in inodes:   # 0A = LISTEN
                ip_hex, port_hex = f[1].split(":")
                ip = ".".join(str(int(ip_hex[i:i + 2], 16)) for i in (6, 4, 2, 0)) \
                    if len(ip_hex) == 8 else ip_hex
                out.add(f"{ip}:{int(port_hex, 16)}")
    return out


def _accepts(proc, port: int, deadline_s: float = 10.0) -> None:
    """Wait until 127.0.0.1:``port`` accepts a connection, the process exits (between tries
    it is waited on, 50 ms at a time) or ``deadline_s`` passes."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            return
        except OSError:
            try:
                proc.wait(timeout=0.05)
                return
            except subprocess.TimeoutExpired:
                continue


def _serve_web(sink, port: int, wport: int) -> tuple[bool, set[str], str]:
    """Start the viewer on ``port`` / ``wport``: (whether it said it is serving, the addresses
    it then listens on, what it wrote to stderr until then)."""
    proc = subprocess.Popen(sink.command(port, wport), stderr=subprocess.PIPE, text=True,
                            stdout=subprocess.DEVNULL, env=dict(os.environ))
    said, hosted = [], False
    try:
        for line in proc.stderr:          # wait for the viewer to say it is serving
            said.append(line)
            if "Hosting a web-viewer" in line:
                hosted = True
                break
        if hosted:                        # it may say so before both sockets listen
            _accepts(proc, port)
            _accepts(proc, wport)
        addrs = _listening(proc.pid) if hosted else set()
    finally:
        proc.terminate()
        proc.wait(10)
    return hosted, addrs, "".join(said[-10:])


def test_viewer_servers_bind_localhost_by_default():
    """Both the gRPC and the web viewer's port listen on 127.0.0.1 and nowhere else. Two free
    ports are picked and released before the viewer binds them, so another process may take
    one meanwhile: that (and only that: "in use") is tried again with new ones."""
    from services.recording.viewer import Sink, _free_port
    sink = Sink("web")
    for _ in range(3):
        port, wport = _free_port("127.0.0.1"), _free_port("127.0.0.1")
        hosted, addrs, said = _serve_web(sink, port, wport)
        if hosted or "in use" not in said:
            break
    assert hosted, f"the viewer stopped before serving: {said}"
    assert f"127.0.0.1:{port}" in addrs and f"127.0.0.1:{wport}" in addrs, (addrs, said)
    assert all(a.startswith("127.0.0.1:") for a in addrs), addrs


def _tiny_frame(session, n):
    import cv2
    import numpy as np
    from findme_io.convert import make_frame
    import schemas
    img = np.random.default_rng(n).integers(0, 255, (60, 80, 3)).astype(np.uint8)
    f = make_frame(session, n, cv2.imencode(".jpg", img)[1].tobytes(),
                   intrinsics=(80.0, 80.0, 40.0, 30.0, 80, 60), gravity=(0.0, 1.0, 0.0))
    return f"findme/{session}/frame/{n}", schemas.encode(f)


def test_viewer_bounds_what_sessions_cost(tmp_path):
    """The layout is sent when the tabbed photos reach 1, 2, 4 and 8, never again however
    many photos come (Rerun keeps a stream per layout sent); an idle session is closed, its
    file finished, and opens a new file part when it comes back; beyond max_open the least
    recently used one is closed; past the budget of what Rerun keeps (streams: recordings and
    layouts; photos drawn) the service asks to be restarted, once."""
    from findme_io.rerun_session import MAX_PHOTO_TABS
    from services.recording.viewer import Sink, ViewerHandler
    now, full = [0.0], []
    h = ViewerHandler(Sink("rrd", path=str(tmp_path)), idle_s=60, max_open=2,
                      monotonic=lambda: now[0], budget_mb=8.0, on_full=lambda: full.append(1))
    h.on_message(*_tiny_frame("s1", 0))
    sent = []
    rec = h.views["s1"].rec
    real = rec.send_blueprint
    rec.send_blueprint = lambda bp: (sent.append(bp), real(bp))
    for n in range(1, 3 * MAX_PHOTO_TABS):
        h.on_message(*_tiny_frame("s1", n))
    assert [len(b.root_container.contents[0].contents) for b in sent] == [2, 4, 8]
    assert MAX_PHOTO_TABS == 8 and h.views["s1"].layouts == 4   # with the first photo's
    now[0] = 61.0
    h.tick(now[0])
    assert not h.views and h.counters()["sessions_closed"] == 1
    assert "EncodedImage:blob" in rrd_contents(tmp_path / "s1.rrd")["/world/photo/23/camera/image"]
    h.on_message(*_tiny_frame("s1", 24))       # back after its close: a second part
    assert (tmp_path / "s1.1.rrd").exists()
    h.on_message(*_tiny_frame("s2", 0))
    h.on_message(*_tiny_frame("s3", 0))        # s1 is the least recently used of 3 > 2 open
    assert list(h.views) == ["s2", "s3"] and h.counters()["sessions_closed"] == 2
    # streams: s1 1 + 4 layouts, its 2nd part 1 + 1, s2 1 + 1, s3 1 + 1; photos 24 + 1 + 1 + 1:
    # s3's recording crossed 8 MB (7.6 -> 8.3)
    c = h.counters()
    assert full == [1] and (c["rerun_streams"], c["rerun_photos"]) == (11, 27)
    assert c["rerun_mb"] == pytest.approx(11 * 0.7 + 27 * 0.05, abs=0.05)
    h.on_message(*_tiny_frame("s4", 0))
    assert full == [1]
    h.close()
    assert not h.views


def test_a_refused_outline_in_rerun_draws_the_photos_and_says_why(tmp_path):
    import rerun as rr

    from findme_io.rerun_plan import log_plan
    from tests.schemas.conftest import sample_messages
    plan = dict(sample_messages())["plan-refused"]
    rec = rr.RecordingStream("findme-test")
    out = tmp_path / "refused.rrd"
    rec.save(str(out))
    log_plan(rec, "plan", plan)
    rec.flush()
    rec.disconnect()
    assert column(out, "/plan/cameras", "Arrows2D:labels")[-1] == ["1", "2", "3"]
    assert "LineStrips2D:strips" not in rrd_contents(out)["/plan/walls"]    # cleared
    ((text,),) = column(out, "/log", "TextLog:text")
    assert text == f"plan of photos up to 3: no outline: {plan.reason}"
