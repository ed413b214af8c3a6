"""What ``findme run`` prints and records, as a newcomer sees it: a position line for every
photo; lengths in camera heights ("h"), never "m", without a camera height; strictly
increasing trajectory times for photos without EXIF time (the bundled example); the
overlay of ``findme hypotheses`` with the best hypothesis on top."""

from __future__ import annotations

import json
import re
import shutil
from importlib import resources

import cv2
import numpy as np

from findme_io.overlay import palette
from findme_core.motion.trajectory import from_tum
from tests.cli.conftest import run_findme

EXAMPLES = resources.files("findme") / "examples"


def test_example_pair_positions_and_increasing_trajectory_times(tmp_path):
    out = run_findme("run", "--out", tmp_path, "--session", "times").stdout
    assert "photo 0: at x +0.000 m, z +0.000 m" in out
    assert re.search(r"^photo 1: at x \+0\.3\d\d m, z \+0\.5\d\d m", out, re.M), out
    run_findme("export", tmp_path / "times.mcap", "--tum", tmp_path / "t.txt")
    stamps, poses = from_tum((tmp_path / "t.txt").read_text())
    assert len(stamps) == 2 and stamps[0] < stamps[1], stamps


def test_without_a_camera_height_lengths_are_in_camera_heights(tmp_path):
    """The example photos without their sidecars (so without a camera height): no length is
    printed in metres; each photo still gets its position line."""
    for name in ("room_a.jpg", "room_b.jpg"):
        with resources.as_file(EXAMPLES / name) as p:
            shutil.copy(p, tmp_path / name)
    out = run_findme("run", tmp_path / "room_a.jpg", tmp_path / "room_b.jpg",
                     "--no-record").stdout
    assert not re.search(r"\d m\b", out), out
    assert "scene ready (no camera height: lengths in camera heights, h)" in out
    assert re.search(r"^photo 1: at x [-+]\d\.\d{3} h, z [-+]\d\.\d{3} h", out, re.M), out
    assert re.search(r"^motion 0 -> 1: x [-+]\d\.\d{3} h, z [-+]\d\.\d{3} h", out, re.M), out


def test_overlay_draws_the_best_hypothesis_on_top(tmp_path):
    """Where another hypothesis runs along the best one, the best one's colour shows."""
    png = tmp_path / "o.png"
    with resources.as_file(EXAMPLES / "room_a.jpg") as photo:
        hs = json.loads(run_findme("hypotheses", photo, "--overlay", png, "--json").stdout)
    img = cv2.imread(str(png))
    polys = [np.array(h["polyline"]) for h in hs["hypotheses"]]
    best = palette(len(polys))[0]
    us = np.arange(5, hs["width"] - 5)
    v1 = np.interp(us, polys[0][:, 0], polys[0][:, 1])
    shared = np.zeros(len(us), bool)
    for p in polys[1:]:
        shared |= np.abs(np.interp(us, p[:, 0], p[:, 1]) - v1) < 0.25
    shared &= (v1 > 5) & (v1 < hs["height"] - 5)
    assert shared.sum() > 50, "the example's hypotheses share part of their line"
    on_best = [tuple(int(c) for c in img[int(round(v)), u]) == best
               for u, v in zip(us[shared], v1[shared])]
    assert np.mean(on_best) > 0.9, np.mean(on_best)
