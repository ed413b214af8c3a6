"""The same answers on every machine: every golden recording regresses clean, and
``tools/make_golden.py --check`` finds the goldens current, under each OpenBLAS kernel and
with numpy's AVX-512 dispatch off (``tests.numeric_envs``), one subprocess per environment.
And ``--check`` still tells a real change from last-bit noise."""

from __future__ import annotations

import sys

import pytest

from tests.numeric_envs import ROOT, env_params, run_python

from .conftest import GOLDENS, PAIR, rewrite

_SCRIPT = """
import logging, sys
sys.path.insert(0, "tools")
from pathlib import Path
from findme.regression.regress import regress
import make_golden
logging.disable(logging.ERROR)
bad = 0
for g in sorted(Path("recordings/golden").glob("*.mcap")):
    r = regress(g)
    print(r.report())
    bad += not r.ok
bad += make_golden.main(["--check"])
sys.exit(1 if bad else 0)
"""


@pytest.mark.parametrize("env", env_params())
def test_goldens_regress_clean_and_are_current_under(env):
    r = run_python(_SCRIPT, env)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert r.stdout.count("PASS (tolerances") == len(GOLDENS)
    assert r.stdout.count(": up to date") == len(GOLDENS)


def test_check_tells_a_real_change_from_the_last_bits(tmp_path):
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import make_golden
    finally:
        sys.path.remove(str(ROOT / "tools"))

    def nudge(dv):
        def change(key, msg):
            if "/scene/0" in key:
                msg.polyline.points[1].v += dv
        return change
    assert make_golden.check(PAIR, PAIR) == (True, "up to date")
    same, text = make_golden.check(PAIR, rewrite(PAIR, tmp_path / "bits.mcap", nudge(1e-9)))
    assert same and text.startswith("up to date within regress's tolerances")
    same, text = make_golden.check(PAIR, rewrite(PAIR, tmp_path / "moved.mcap", nudge(3.0)))
    assert not same and "scene/0:" in text and "polyline.points[1]" in text
    assert "(moved 3.00 px > 1 px)" in text

    def other_photo(key, msg):
        if "/frame/1" in key:
            msg.image.data = msg.image.data + b"\0"   # bytes after the end of the JPEG
    same, text = make_golden.check(PAIR, rewrite(PAIR, tmp_path / "in.mcap", other_photo))
    assert not same and "its inputs differ (findme/golden-examples-pair/frame/1)" in text
