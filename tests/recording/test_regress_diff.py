"""Regression diffs: a result perturbed in the recording, or by the current code, fails
``findme regress`` with a readable diff naming the result, the field and the tolerance."""

from __future__ import annotations

import json

from findme.regression.diff import TOL_M, TOL_PX, diff_messages
from findme.regression.regress import regress
from services.recording.mcap_reader import read_recording

from .conftest import PAIR, rewrite


def _shift_first_hypothesis(dx):
    def change(key, msg):
        if "/hypotheses/0" in key:
            msg.hypotheses[0].polyline.points[2].u += dx
    return change


def test_a_moved_hypothesis_vertex_fails_with_a_readable_diff(tmp_path, cli):
    bad = rewrite(PAIR, tmp_path / "moved.mcap", _shift_first_hypothesis(3.0))
    rc, out, _ = cli("regress", bad)
    assert rc == 1
    assert "FAIL" in out and "1 differ" in out
    assert "hypotheses/0:" in out
    assert "hypotheses[0].polyline.points[2]:" in out and "(moved 3.00 px > 1 px)" in out


def test_a_move_within_tolerance_passes(tmp_path, cli):
    ok = rewrite(PAIR, tmp_path / "nudged.mcap", _shift_first_hypothesis(0.4 * TOL_PX))
    rc, out, _ = cli("regress", ok)
    assert rc == 0, out


def test_a_changed_measurement_fails_and_json_lists_it(tmp_path, cli):
    def change(key, msg):
        if "/measured/0" in key:
            msg.points[0].xyz.z += 5 * TOL_M          # 5 mm
            msg.distances[0].distance_m += 2 * TOL_M  # 2 mm
    bad = rewrite(PAIR, tmp_path / "measured.mcap", change)
    rc, out, _ = cli("regress", bad, "--json")
    assert rc == 1
    res = json.loads(out)
    assert not res["ok"]
    (key, diffs), = res["differences"].items()
    assert key == "measured/0 (measurement 1)"
    assert any(d.startswith("points[0].xyz:") and "(moved 5.00 mm > 1 mm)" in d for d in diffs)
    assert any(d.startswith("distances[0].distance_m:") for d in diffs)


def test_a_missing_result_is_reported(tmp_path, cli):
    from .conftest import odometry_messages
    recs = read_recording(PAIR)
    extra = [x for x in odometry_messages("golden-examples-pair", recs[-1].log_time)
             if "/error" in x[0]]
    bad = rewrite(PAIR, tmp_path / "extra-error.mcap", extra=extra)
    rc, out, _ = cli("regress", bad, "--timeout", "3")
    assert rc == 1
    assert "error:" in out
    assert "recorded, not now: findme/golden-examples-pair/selection/7" in out


def test_a_changed_service_fails_on_its_results_and_what_follows(monkeypatch):
    """The other direction: the recording is right, the current code moved."""
    from services.pipeline import hypotheses as hyp_mod
    real = hyp_mod.hypothesis_set_msg

    def shifted(*a, **kw):
        msg = real(*a, **kw)
        for p in msg.hypotheses[0].polyline.points:
            p.v += 2.5
        return msg
    monkeypatch.setattr(hyp_mod, "hypothesis_set_msg", shifted)
    r = regress(PAIR)
    assert not r.ok
    # the measured points are floor points: a boundary 2.5 px lower does not move them; the
    # motion's evidence (its layouts' agreement, registered on the boundaries) does move
    assert set(r.differences) == {"hypotheses/0", "hypotheses/1", "scene/0", "scene/1",
                                  "motion/0/1"}
    assert any("(moved 2.50 px > 1 px)" in d for d in r.differences["scene/0"])
    text = r.report()
    assert text.splitlines()[-1].startswith("FAIL (tolerances: polyline vertices")


def test_diff_messages_tolerances_are_per_quantity():
    import math

    import schemas
    a = schemas.Motion(x_m=1.0, z_m=2.0, yaw_rad=0.1, inliers=10, method="m")
    b = schemas.Motion(x_m=1.0009, z_m=2.0, yaw_rad=0.1 + math.radians(0.009), inliers=10,
                       method="m")
    assert diff_messages(a, b) == []
    b.x_m, b.yaw_rad, b.inliers = 1.0011, 0.1 + math.radians(0.011), 11
    d = diff_messages(a, b)
    assert len(d) == 3
    assert d[0].startswith("x_m: 1 recorded, 1.0011 now (off by 1.1 mm > 1 mm)")
    assert d[1].startswith("yaw_rad:") and "deg > 0.01 deg" in d[1]
    assert d[2] == "inliers: 10 recorded, 11 now"
    b = schemas.Motion(x_m=1.0, z_m=2.0, yaw_rad=0.1, inliers=10, method="m", error="x")
    assert diff_messages(a, b) == ["error: '' recorded, 'x' now"]
    c = schemas.Motion(z_m=2.0, yaw_rad=0.1, inliers=10, method="m")
    assert diff_messages(a, c) == ["x_m: set recorded, unset now"]
