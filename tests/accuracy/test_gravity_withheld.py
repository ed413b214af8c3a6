"""Plain photos (no gravity given) of the real set: a motion's 1-sigma carries the error of the
gravity the photos' lines gave (``motion.gravity_spread``). KITTI 13 -> 14, 1.19 m straight
ahead: the lines put the camera's roll 1.5 deg off the road at +-0.5 deg, and the motion
came out 0.37 +- 0.04 m forward (19 sigma short). Skips without ../shared."""

from __future__ import annotations

import json

from tests.cli.conftest import run_findme
from tests.conftest import EVAL_DIR, needs_eval_data


def test_a_motion_on_lines_gravity_states_what_a_tilt_within_its_sigma_does():
    needs_eval_data()
    pid = "kitti06_000013_c2__kitti06_000014_c2"
    pair = json.loads((EVAL_DIR / "pairs" / f"{pid}.json").read_text())
    view = json.loads((EVAL_DIR / "views" / f"{pair['a']}.json").read_text())
    k = view["intrinsics"]
    out = json.loads(run_findme(
        "motion", EVAL_DIR / "views" / f"{pair['a']}.png", EVAL_DIR / "views" / f"{pair['b']}.png",
        "--intrinsics", f"{k['fx']},{k['fy']},{k['cx']},{k['cy']}",
        "--camera-height", view["camera_height_m"], "--json").stdout)
    truth = pair["motion"]
    assert len(out["gravity_tilts"]) == 8 and any(t["another"] for t in out["gravity_tilts"])
    for axis in ("x", "z"):
        assert abs(out[f"{axis}_m"] - truth[f"{axis}_m"]) < 3.0 * out[f"sigma_{axis}_m"], out
    assert abs(out["yaw_deg"] - truth["yaw_deg"]) < 3.0 * out["sigma_yaw_deg"]
