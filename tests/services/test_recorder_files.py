"""The recorder as its own process keeps one file per session however many are live: 70
sessions of 5 messages each, interleaved, give 70 files of 5 messages (it holds file
handles for 64; the old recorder split each session over several files: 350 files)."""

import schemas
from services.recording.mcap_reader import read_recording
from services.runtime import bus
from tests.services.conftest import ProcBus


def test_seventy_live_sessions_give_seventy_files(tmp_path):
    pb = ProcBus()
    try:
        pb.serve("recorder", "rec", "--out", tmp_path)
        sessions = [f"s{i:02d}" for i in range(70)]
        for n in range(5):                 # every session is live at once
            for s in sessions:
                sel = schemas.Selection(session=s, index=n, rank=1, by=schemas.SELECTED_BY_AUTO)
                bus.put(pb.client, bus.key(s, "selection", n), schemas.encode(sel))
        st = pb.wait_status("recorder", "rec", lambda st: st.counters["recorded"] >= 350)
        assert st.frames_in == 350 and st.dropped == 0, st
        assert st.counters["suspends"] > 0     # more sessions than handles: some suspended
    finally:
        codes = pb.close()                     # SIGTERM: the recorder drains and finishes files
    assert codes["rec"] == 0, "".join(pb.procs["rec"].lines)[-2000:]
    files = sorted(p.name for p in tmp_path.glob("*.mcap"))
    assert files == [f"{s}.mcap" for s in sessions]
    for s in (sessions[0], sessions[37], sessions[-1]):
        recs = read_recording(tmp_path / f"{s}.mcap")
        assert [r.key for r in recs] == [bus.key(s, "selection", n) for n in range(5)]
