"""``findme motion`` on two plain photos (no gravity given): the motion estimated again under
each photo's gravity tilted by its 1-sigma, what each tilt gave and why it counts or not, in
the text and in ``--json`` (``motion.gravity_spread``). The rendered 5 x 4 m room, two photos
0.5 m apart turned 20 deg, 30 deg down; photo A's lines leave its gravity +-5 deg unsure."""

from __future__ import annotations

import re

import cv2
import pytest

from findme_core.synth.render import Pose, Room, planar_motion, render
from tests.cli.conftest import as_json, run_findme

POSES = (Pose(0.3, -0.6, 1.4, 0.0, 30.0, 0.0), Pose(-0.2, -0.6, 1.4, 20.0, 30.0, 0.0))


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    d = tmp_path_factory.mktemp("plain")
    paths = []
    for name, pose in zip("ab", POSES):
        v = render(Room.rectangle(5.0, 4.0), pose, 640, 480, hfov_deg=70.0, supersample=1)
        paths.append(d / f"{name}.jpg")
        cv2.imwrite(str(paths[-1]), v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    return paths


def test_tilts_the_matches_rule_out_are_listed_and_do_not_widen(photos):
    args = ("motion", *photos, "--hfov", 70, "--camera-height", 1.4)
    out = as_json(run_findme(*args, "--json"))
    tilts = out["gravity_tilts"]
    assert len(tilts) == 8 and all(set(t) >= {"photo", "axis", "tilt_deg", "another",
                                              "ruled_out", "motion"} for t in tilts)
    ruled = [t for t in tilts if t["ruled_out"]]
    assert {(t["photo"], t["axis"]) for t in ruled} >= {("A", "roll")}
    assert all(t["motion"]["inliers"] < out["inliers"] and not t["another"] for t in ruled)
    x, z, yaw = planar_motion(*POSES)
    assert abs(out["yaw_deg"] - yaw) < 3 * out["sigma_yaw_deg"] and out["sigma_yaw_deg"] < 1.0
    assert abs(out["x_m"] - x) < 3 * out["sigma_x_m"]

    text = run_findme(*args).stdout
    lines = [ln for ln in text.splitlines() if "the matches rule it out" in ln]
    assert len(lines) == len(ruled) and all("photo A's gravity tilted" in ln for ln in lines)
    agree = [int(n) for n in re.findall(r"\((\d+) agree with it, (\d+) with", lines[0])[0]]
    assert agree[0] < agree[1] == out["inliers"]
