"""A recording while its recorder still writes it: ``findme export``, ``view`` and
``replay``'s reader take what is complete and say how far it got; ``regress`` refuses it
with the reason. The recorder here is the real ``RecorderHandler``, fed the messages of a
whole session (the example pair with odometry's results) as the bus would."""

from __future__ import annotations

import os

import pytest

from findme_core.motion.trajectory import from_tum
from services.recording.mcap_reader import read_available, read_recording
from services.recording.recorder import RecorderHandler

SESSION = "golden-examples-pair"


@pytest.fixture
def writing(tmp_path, full_recording):
    """A recorder that has written (and flushed) a whole session and not finished its file."""
    recs = read_recording(full_recording)
    recorder = RecorderHandler(tmp_path / "rec", flush_s=3600.0)   # flushed by the test only
    for r in recs:
        recorder.on_message(r.key, r.payload)
    recorder.flush()
    path = recorder.path_of(SESSION)
    yield recorder, path, recs
    recorder.close()


def test_export_and_view_read_what_is_complete_and_say_how_far(writing, tmp_path, cli):
    recorder, path, recs = writing
    got, extent = read_available(path)
    assert not extent.complete and [r.key for r in got] == [r.key for r in recs]

    rc, out, err = cli("export", path, "--tum", tmp_path / "t.txt")
    assert rc == 0, err
    assert "is not finished (still being written" in out
    assert f"read the {len(recs)} messages complete so far" in out
    stamps, poses = from_tum((tmp_path / "t.txt").read_text())
    assert len(poses) == 2 and stamps[0] < stamps[1]

    rc, out, err = cli("view", path, "--rrd", tmp_path / "s.rrd")
    assert rc == 0, err
    assert "is not finished" in out and "messages shown" in out
    assert (tmp_path / "s.rrd").stat().st_size > 0

    # regress needs every result: it refuses the unfinished file, saying why
    rc, out, err = cli("regress", path)
    assert rc == 2 and "the recording is not finished (it has no end yet)" in err, err
    assert "still being written" in err and "findme recover" in err

    recorder.close()                      # finished: no note any more
    rc, out, err = cli("export", path, "--tum", tmp_path / "t2.txt")
    assert rc == 0 and "not finished" not in out, out


def test_a_torn_last_chunk_is_left_out_with_the_reason(writing, tmp_path, cli):
    """The recorder died in the middle of writing a chunk: the whole chunks are read, and
    the note says where the file ends."""
    recorder, path, recs = writing
    first = path.stat().st_size
    for r in recs:                        # a second session's worth, then a torn chunk
        recorder.on_message(r.key, r.payload)
    recorder.flush()
    torn = tmp_path / "torn.mcap"
    data = path.read_bytes()
    torn.write_bytes(data[:(first + len(data)) // 2])
    got, extent = read_available(torn)
    assert len(got) == len(recs) and not extent.complete
    assert extent.reason.startswith("the file ends inside a record, after byte ")
    rc, out, err = cli("export", torn, "--csv", tmp_path / "t.csv")
    assert rc == 0, err
    assert f"read the {len(recs)} messages complete so far" in out
    assert f"of {os.path.getsize(torn) / 1e3:.0f} kB" in out
