"""What ``findme run`` prints and records, as a newcomer sees it: a position line for every
photo; lengths in camera heights ("h"), never "m", without a camera height; strictly
increasing trajectory times for photos without EXIF time (the bundled example); the
overlay of ``findme hypotheses`` with the best hypothesis on top; a gravity that no sensor
gave and the photo's lines do not settle is said with the results that rest on it."""

from __future__ import annotations

import json
import math
import re
import shutil
from importlib import resources

import cv2
import numpy as np
import pytest

from findme_io.overlay import palette
from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room
from findme_core.motion.trajectory import from_tum
from tests.cli.conftest import run_findme
from tests.conftest import top_pixels

EXAMPLES = resources.files("findme") / "examples"


def test_example_pair_positions_and_increasing_trajectory_times(tmp_path):
    out = run_findme("run", "--out", tmp_path, "--session", "times").stdout
    assert "photo 0: at x +0.000 m, z +0.000 m" in out
    assert "gravity" not in out       # given with the photos (their sidecars): nothing to say
    # photo 1's position with its 1-sigmas (chained from the motion); photo 0 is the origin
    assert re.search(r"^photo 1: at x \+0\.3\d\d m, z \+0\.5\d\d m, heading -18\.0 deg from "
                     r"photo 0 \(± 0\.0\d\d m, ± 0\.0\d\d m, ± \d\.\d\d deg\)$", out, re.M), out
    assert re.search(r"^photo 0: at x \+0\.000 m, z \+0\.000 m, heading \+0\.0 deg from photo 0$",
                     out, re.M), out
    # two photos see one wall of the room: the others close the outline, and the area says so
    assert re.search(r"^floor plan: .*\? = not seen\), area [.\d]+ m² \(closed by \d walls? not "
                     r"seen\), 2 of 2 photos placed$", out, re.M), out
    run_findme("export", tmp_path / "times.mcap", "--tum", tmp_path / "t.txt")
    stamps, poses = from_tum((tmp_path / "t.txt").read_text())
    assert len(stamps) == 2 and stamps[0] < stamps[1], stamps


def test_run_measures_a_point_said_on_a_counters_top_and_says_how_high_it_is(counter_view,
                                                                             tmp_path):
    """``findme run PHOTO --measure U,V,top`` through every service: the point comes back on
    the top, with the top's height above the floor (0.9 m rendered)."""
    v, cam = counter_view, counter_view.camera
    jpg = tmp_path / "counter.jpg"
    cv2.imwrite(str(jpg), v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    (u, w), truth = (x[0] for x in top_pixels(v, step=3001))
    out = run_findme("run", "--no-record", jpg, "--intrinsics",
                     f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}",
                     "--gravity", ",".join(map(str, cam.gravity)), "--gravity-sigma", "0",
                     "--camera-height", v.camera_height, "--measure", f"{u:g},{w:g},top").stdout
    line = next(x for x in out.splitlines() if x.startswith("measure photo 0"))
    assert "top (as you said) at (" in line, out
    xyz = [float(x) for x in re.search(r"at \(([^)]*)\)", line).group(1).split(",")]
    assert np.linalg.norm(np.subtract(xyz, truth)) < 0.1, (line, truth)
    height = float(re.search(r"its top ([0-9.]+) m above the floor", line).group(1))
    assert height == pytest.approx(0.9, abs=0.03), line


def test_a_bad_surface_to_measure_on_is_refused_before_any_work(tmp_path):
    p = run_findme("run", "--no-record", "--measure", "247,378,ceiling", check=False)
    assert p.returncode == 2 and "--measure: a point's surface must be floor, wall or top, got " \
        "'ceiling'" in p.stderr, p.stderr
    assert "photo 0" not in p.stdout     # refused before the photos went out


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


def test_an_unsure_gravity_is_completed_by_the_other_photo_and_said(tmp_path):
    """Two plain photos of the rendered room, turning 45 deg at one spot, 30 deg down, no
    gravity given: the second photo's lines leave its gravity unsure (tens of degrees; said
    on its line); the motion carries the first photo's gravity to it through their matches,
    says so, and is right (without: 58 deg and 0.9 h of translation)."""
    paths = []
    for i, yaw in enumerate((0.0, 45.0)):
        v = render(Room.rectangle(5.0, 4.0), Pose(0.3, -0.2, 1.4, yaw, 30.0, 0.0), 640, 480,
                   hfov_deg=70.0, supersample=1)
        paths.append(tmp_path / f"turn_{i}.jpg")
        cv2.imwrite(str(paths[-1]), v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    out = run_findme("run", *paths, "--hfov", "70", "--no-record").stdout
    m = re.search(r"^photo 1: \d+ hypotheses in \d+ ms; photo 1's gravity from its lines, "
                  r"unsure \(± (\d+) deg\)$", out, re.M)
    assert m and int(m.group(1)) > 5, out
    mo = re.search(r"^motion 0 -> 1: x ([-+.\d]+) h, z ([-+.\d]+) h, yaw ([-+.\d]+) deg .*; "
                   r"photo 0 and photo 1 agreed on gravity through their matches \(their own "
                   r"were (\d+) deg apart\)$", out, re.M)
    assert mo and int(mo.group(4)) > 10, out
    x, z, yaw = (float(v) for v in mo.groups()[:3])
    assert math.hypot(x, z) < 0.05 and abs(yaw - 45.0) < 1.0, mo.group(0)
    assert "rests on" not in mo.group(0)      # the gravity it used is no longer unsure
    # ``findme motion`` on the same photos: the same motion and the same clause
    text = run_findme("motion", *paths, "--hfov", "70").stdout
    assert text.splitlines()[0].endswith(
        "; photo A and photo B agreed on gravity through their matches (their own were "
        + mo.group(4) + " deg apart)"), text
    js = json.loads(run_findme("motion", *paths, "--hfov", "70", "--json").stdout)
    assert (f"{js['x_m']:+.3f}", f"{js['z_m']:+.3f}", f"{js['yaw_deg']:+.2f}") == mo.groups()[:3]
    assert js["gravity"]["status"] == "agreed" and js["gravity"]["sigma_b_deg"] < 5.0


def test_a_turn_of_plain_photos_is_posed_and_planned_through_the_services(tmp_path):
    """Eight plain photos turning at one spot (45 deg steps, no gravity, JPEG): several
    photos' lines alone leave their gravity 20-50 deg off. The odometry carries the first
    sure gravity along the turn (each unsure photo completed by the one before it), so every
    motion is a 45 deg turn on the spot; the mapper's spot agrees on gravity too, and the
    room comes out 4 x 5 m."""
    paths = []
    for i, yaw in enumerate(range(0, 360, 45)):
        v = render(Room.rectangle(5.0, 4.0), Pose(0.3, -0.2, 1.4, float(yaw), 30.0, 0.0), 640,
                   480, hfov_deg=70.0, supersample=1)
        paths.append(tmp_path / f"turn_{i}.jpg")
        cv2.imwrite(str(paths[-1]), v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    out = run_findme("run", *paths, "--hfov", "70", "--camera-height", "1.4",
                     "--no-record").stdout
    motions = re.findall(r"^motion (\d) -> (\d): x ([-+.\d]+) m, z ([-+.\d]+) m, yaw ([-+.\d]+) "
                         r"deg(.*)$", out, re.M)
    assert [(int(a), int(b)) for a, b, *_ in motions] == [(i, i + 1) for i in range(7)], out
    for *_, x, z, yaw, rest in motions:
        assert math.hypot(float(x), float(z)) < 0.03 and abs(float(yaw) - 45.0) < 1.0, out
        assert "rests on" not in rest, out
    assert sum("agreed on gravity" in m[-1] for m in motions) >= 4, out
    last = re.search(r"^photo 7: at x ([-+.\d]+) m, z ([-+.\d]+) m, heading ([-+.\d]+) deg", out,
                     re.M)
    assert last and abs(float(last.group(3)) + 45.0) < 2.0, out
    # every wall seen, each length with its 1-sigma
    w = r"([.\d]+) ± ([.\d]+)"
    plan = re.search(rf"^floor plan: 4 walls \({w}, {w}, {w}, {w} m", out, re.M)
    assert plan and sorted(float(w) for w in plan.groups()[::2]) == pytest.approx([4, 4, 5, 5],
                                                                                   abs=0.1), out
    assert all(0 < float(s) < 0.5 for s in plan.groups()[1::2]), out
    assert "closed by" not in out, out
