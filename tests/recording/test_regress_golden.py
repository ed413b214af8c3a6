"""The recorded-log regression suite: every golden recording (recordings/golden, made by
tools/make_golden.py) replays through the current services with the same results."""

from __future__ import annotations

import pytest

from .conftest import GOLDENS

assert GOLDENS, "no golden recordings: run python tools/make_golden.py"


@pytest.mark.parametrize("golden", GOLDENS, ids=lambda p: p.stem)
def test_golden_recording_regresses_clean(golden, cli):
    rc, out, err = cli("regress", golden)
    assert rc == 0, out + err
    assert "PASS" in out and " 0 differ" in out
