"""``findme run`` records by default (``--no-record`` not), ``findme recover`` on complete,
torn and foreign files, and the golden tool's determinism."""

from __future__ import annotations

import os
import subprocess
import sys

from services.recording.mcap_reader import read_recording
from services.recording.mcap_writer import McapRecording

from .conftest import GOLDEN, PAIR, ROOT


def _findme(*args):
    """``findme ARGS`` as its own process (report.Printer binds sys.stdout at import, so
    in-process runs after a captured test would print to a closed stream)."""
    r = subprocess.run([sys.executable, "-m", "findme.cli", *map(str, args)], cwd=ROOT,
                       capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)))
    return r.returncode, r.stdout, r.stderr


def test_findme_run_records_the_session_and_says_where(tmp_path):
    rc, out, err = _findme("run", "--out", tmp_path, "--session", "rec-test")
    assert rc == 0, err
    path = tmp_path / "rec-test.mcap"
    assert f"recording: {path}" in out
    kinds = [r.key.split("/", 2)[2] for r in read_recording(path)]
    for k in ("frame/0", "frame/1", "hypotheses/0", "hypotheses/1", "selection/0", "scene/0",
              "scene/1", "measured/0"):
        assert k in kinds, kinds
    rc, out, err = _findme("run", "--out", tmp_path, "--session", "no-rec", "--no-record")
    assert rc == 0, err
    assert not (tmp_path / "no-rec.mcap").exists() and "recording:" not in out


def test_recover_reports_complete_torn_and_foreign_files(tmp_path, cli):
    recs = read_recording(PAIR)
    rc, out, _ = cli("recover", PAIR, "-o", tmp_path / "copy.mcap")
    assert rc == 0 and "was complete" in out and f"({len(recs)} bus messages" in out
    torn = tmp_path / "torn.mcap"
    w = McapRecording(torn, "golden-examples-pair")
    for r in recs[:4]:
        w.write(r.key, r.payload, r.log_time)
    w.flush()                        # the first chunk is whole ...
    first = torn.stat().st_size
    for r in recs[4:]:
        w.write(r.key, r.payload, r.log_time)
    w.flush()
    data = torn.read_bytes()
    torn.write_bytes(data[:(first + len(data)) // 2])    # ... the second one torn
    rc, out, _ = cli("recover", torn, "-o", tmp_path / "fixed.mcap")
    assert rc == 0 and out.startswith("recovered ") and "(4 bus messages" in out
    assert "dropped the last" in out
    assert [r.key for r in read_recording(tmp_path / "fixed.mcap")] == [r.key for r in recs[:4]]
    (tmp_path / "x.mcap").write_bytes(b"definitely not mcap")
    rc, _, err = cli("recover", tmp_path / "x.mcap", "-o", tmp_path / "y.mcap")
    assert rc == 2 and "not an MCAP file" in err
    rc, _, err = cli("recover", PAIR, "-o", PAIR)
    assert rc == 2 and "another -o path" in err
    w.close()


def test_golden_canonical_form_is_deterministic(tmp_path):
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import make_golden
    finally:
        sys.path.pop(0)
    from mcap.reader import make_reader
    with open(GOLDEN / "examples-pair.mcap", "rb") as f:
        meta = next(m.metadata for m in make_reader(f).iter_metadata() if m.name == "findme")
    spec = make_golden.Spec(meta["golden"], [], note=meta["note"])
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    make_golden.canonical(GOLDEN / "examples-pair.mcap", a, spec)
    make_golden.canonical(GOLDEN / "examples-pair.mcap", b, spec)
    # compared as booleans: pytest's diff of two 150 kB byte strings takes minutes
    golden = (GOLDEN / "examples-pair.mcap").read_bytes()
    assert a.read_bytes() == b.read_bytes(), "two canonical runs differ"
    same = a.read_bytes() == golden
    assert same, ("the canonical form differs from recordings/golden/examples-pair.mcap: "
                  "regenerate it (tools/make_golden.py) after an intended change")
