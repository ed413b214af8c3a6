"""The many-process deployment as a user drives it: ``findme send`` to a router with the
services in their own processes (the report of ``findme run``, exit 0; a bad file reported
and the rest sent; exit 2 in seconds without a router or a service), ``findme serve
capture`` ending by itself, capture times from EXIF, and ``findme export`` of the
recording to TUM (timestamps = capture times) and CSV."""

import csv
import datetime as dt
import signal

import pytest

from findme_core.motion.trajectory import from_tum
from findme_io.capture_time import exif_time_ns, parse_exif_time
from services.runtime.bus import BusConfig, open_session, wait_alive
from tests.cli.conftest import run_findme
from tests.services.conftest import assert_example_motion, free_port, spawn_findme, wait_logged
from tests.services.test_e2e import _example

SERVICES = ("hypotheses", "measurement", "odometry", "recorder")
PHOTO_TIMES = ("2026:11:20 14:03:05", "2026:11:20 14:03:09")   # EXIF, at +01:00


def with_exif(jpeg: bytes, stamp: str, offset="+01:00", subsec="250") -> bytes:
    """The same JPEG (same pixels) with an EXIF DateTimeOriginal, as a phone writes it."""
    from PIL import Image
    exif = Image.Exif()
    ifd = exif.get_ifd(0x8769)
    ifd[0x9003], ifd[0x9011], ifd[0x9291] = stamp, offset, subsec
    tiff = exif.tobytes()
    return jpeg[:2] + b"\xff\xe1" + (len(tiff) + 2).to_bytes(2, "big") + tiff + jpeg[2:]


def ns(stamp: str, subsec_ns=250_000_000) -> int:
    t = dt.datetime.strptime(stamp + "+0100", "%Y:%m:%d %H:%M:%S%z")
    return int(t.timestamp()) * 1_000_000_000 + subsec_ns


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    """room_a and room_b with EXIF capture times, and their sidecars."""
    d = tmp_path_factory.mktemp("photos")
    out = []
    for name, stamp in zip(("room_a", "room_b"), PHOTO_TIMES):
        src = _example(name)[0]
        p = d / f"{name}.jpg"
        p.write_bytes(with_exif(open(src, "rb").read(), stamp))
        (d / f"{name}.json").write_text(open(src[:-4] + ".json").read())
        out.append(p)
    return out


@pytest.fixture(scope="module")
def bus(tmp_path_factory):
    rec = tmp_path_factory.mktemp("recordings")
    ep = f"tcp/127.0.0.1:{free_port()}"
    procs = {"router": spawn_findme("router", "--listen", ep)}
    wait_logged(procs["router"], "listening on")
    for name in SERVICES:
        procs[name] = spawn_findme("serve", name, "--connect", ep,
                                   *(["--out", rec] if name == "recorder" else []))
    client = open_session(BusConfig(mode="client", connect=(ep,)))
    for name in SERVICES:
        wait_alive(client, name, 60)
    client.close()
    yield ep, procs, rec
    for p in procs.values():
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    for p in procs.values():
        p.wait(20)


def test_capture_time_from_exif(photos):
    assert exif_time_ns(photos[0].read_bytes()) == ns(PHOTO_TIMES[0])
    assert exif_time_ns(open(_example("room_a")[0], "rb").read()) is None   # rendered: none
    assert parse_exif_time("0000:00:00 00:00:00") is None                  # unset
    assert parse_exif_time("2026:11:20 14:03:05", b"5", "-05:00") == \
        ns("2026:11:20 14:03:05", 500_000_000) + 6 * 3600 * 10**9
    assert exif_time_ns(b"not an image") is None


def test_send_prints_the_run_report_and_export_gives_capture_times(bus, photos, tmp_path):
    ep, procs, rec = bus
    p = run_findme("send", *map(str, photos), "--connect", ep, "--session", "sent-1",
                   "--measure", "495,276", "--measure", "247,378,floor", check=False)
    assert p.returncode == 0, p.stderr
    out = p.stdout
    for line in ("photo 0: 10 hypotheses", "photo 1: hypothesis 1 selected (auto)",
                 "photo 1: scene ready (camera 1.42 m above the floor)", "distance 1-2:",
                 "photo 0: at x +0.000 m, z +0.000 m", "photo 1: at x +0.3"):
        assert line in out, out     # each photo's position line, as findme run prints it
    assert_example_motion(out)
    assert "measure photo 0 pixel (247, 378): floor (as you said) at" in out, out
    assert "measure photo 0 pixel (495, 276): floor at" in out, out
    ref = run_findme("run", *map(str, photos), "--no-record", "--measure", "495,276",
                     "--measure", "247,378,floor").stdout
    same = [ln for ln in out.splitlines()
            if ln.startswith(("motion", "measure", "distance")) or ": at x " in ln]
    assert same and all(ln in ref.splitlines() for ln in same), (same, ref)

    # the recorder's file of that session, exported: timestamps are the EXIF times
    procs["recorder"].send_signal(signal.SIGTERM)
    assert procs["recorder"].wait(20) == 0
    tum, table = tmp_path / "t.txt", tmp_path / "t.csv"
    e = run_findme("export", str(rec / "sent-1.mcap"), "--tum", str(tum), "--csv", str(table), check=False)
    assert e.returncode == 0, e.stderr
    stamps, poses = from_tum(tum.read_text())
    assert stamps == [ns(t) for t in PHOTO_TIMES]
    assert (poses[1].x, poses[1].z) == pytest.approx((0.385, 0.592), abs=0.002)
    rows = list(csv.DictReader(table.open()))
    assert [int(r["time_ns"]) for r in rows] == stamps
    assert rows[1]["time_utc"] == "2026-11-20T13:03:09.250+00:00"


def test_send_reports_a_bad_file_and_sends_the_rest(bus, photos, tmp_path):
    ep, _, _ = bus
    bad = tmp_path / "notes.jpg"
    bad.write_text("not a photo")
    p = run_findme("send", str(photos[0]), str(bad), str(photos[1]), "--connect", ep, check=False)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "notes.jpg" in p.stderr, p.stderr
    assert_example_motion(p.stdout)


def test_serve_capture_ends_when_its_photos_have_results(bus, photos, tmp_path):
    """(With a selection service, as ``findme up`` runs: capture does not choose.)"""
    ep, _, _ = bus
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n broken")
    sel = spawn_findme("serve", "selection", "--auto", "--connect", ep)   # capture's chooser
    cap = spawn_findme("serve", "capture", "--connect", ep, "--session", "cap-1",
                       "--wait-for", "selection", str(photos[0]), str(bad), str(photos[1]))
    try:
        assert cap.wait(120) == 2      # ended by itself; 2: a file was refused
    finally:
        sel.send_signal(signal.SIGTERM)
        sel.wait(20)
    log = "".join(cap.lines)
    assert "published 2 frames of cap-1 (1 refused)" in log
    assert "every photo of cap-1 has its results" in log
    assert "broken.png" in log


def test_send_without_a_router_or_a_service_fails_in_one_line(bus):
    p = run_findme("send", "--connect", f"tcp/127.0.0.1:{free_port()}", "--wait", "1", check=False)
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert "no router answered" in p.stderr and ".rs:" not in p.stderr
    s = run_findme("status", "--connect", f"tcp/127.0.0.1:{free_port()}", check=False)
    assert s.returncode == 2 and s.stderr.count("\n") == 1 and ".rs:" not in s.stderr, s.stderr
    ep = f"tcp/127.0.0.1:{free_port()}"       # a router with no service at all
    router = spawn_findme("router", "--listen", ep)
    try:
        wait_logged(router, "listening on")
        p = run_findme("send", "--connect", ep, "--wait", "1", check=False)
        assert p.returncode == 2 and "no hypotheses service is running" in p.stderr, p.stderr
    finally:
        router.send_signal(signal.SIGTERM)
        router.wait(20)


def test_video_frames_are_timed_by_their_position(tmp_path):
    """A video without a creation time (OpenCV writes none): the file's time minus its
    duration, plus each frame's position (5 fps: 200 ms apart)."""
    import cv2
    import numpy as np

    from services.pipeline.capture import sources
    path = tmp_path / "walk.mp4"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 5.0, (64, 48))
    for i in range(5):
        w.write(np.full((48, 64, 3), 40 * i, np.uint8))
    w.release()
    times = [side["capture_time_ns"] for _, _, side in sources([path])]
    assert len(times) == 5
    assert np.diff(times) == pytest.approx([200_000_000] * 4, abs=1_000_000)
    assert times[-1] <= path.stat().st_mtime_ns
    assert path.stat().st_mtime_ns - times[0] == pytest.approx(1_000_000_000, abs=1_000_000)
