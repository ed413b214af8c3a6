import json
import re

import cv2
import numpy as np
import pytest

from findme_core.synth.render import FLOOR
from tests.cli.conftest import as_json, intrinsics_flag, run_findme
from tests.conftest import floor_pixel_error, top_pixels


def test_hypotheses_json_contract(level_jpg, level_view, tmp_path):
    cam = level_view.camera
    overlay = tmp_path / "sel.png"
    out = as_json(run_findme("hypotheses", level_jpg, "--intrinsics", intrinsics_flag(cam),
                             "--max", 4, "--json", "--overlay", overlay))
    assert (out["width"], out["height"]) == (640, 480)
    hyps = out["hypotheses"]
    assert 1 <= len(hyps) <= 4 and [h["rank"] for h in hyps] == list(range(1, len(hyps) + 1))
    assert [h["score"] for h in hyps] == sorted((h["score"] for h in hyps), reverse=True)
    for h in hyps:
        poly = np.array(h["polyline"])
        assert poly[0, 0] == 0 and poly[-1, 0] == 639 and (np.diff(poly[:, 0]) >= 0).all()
        assert len(h["segments"]) == len(poly) - 1
    assert floor_pixel_error(np.array(hyps[0]["polyline"]), level_view.labels) < 0.03
    assert set(out["timing_ms"]) >= {"lines", "total"}
    assert overlay.stat().st_size > 1000


def test_no_lines_is_an_empty_list_with_the_reason(tmp_path):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640, 3), 128, np.uint8))
    out = as_json(run_findme("hypotheses", blank, "--json"))
    assert out["hypotheses"] == [] and out["reason"] == "no straight lines found in the image"
    p = run_findme("locate", blank, "--point", "320,400", check=False)
    assert p.returncode == 2 and p.stderr.count("\n") == 1
    assert "hypothesis 1 does not exist" in p.stderr and "no straight lines" in p.stderr


def test_a_blank_wall_with_posters_says_no_floor_and_why(tmp_path):
    """Level, 1 m from the rendered room's wall with its posters: the boundary along a
    poster's lower edge and on across the paint comes second, after "no floor visible", and
    both the JSON and the text say how much of it is the same colour above and below."""
    import math
    from findme_core.synth.render import Pose, Room, render
    room = Room.rectangle(5.0, 4.0)
    (x0, z0), (x1, z1) = room.wall_segment(1)
    n = room.inward_normal(1)[[0, 2]]
    c = np.array([(x0 + x1) / 2, (z0 + z1) / 2]) + 1.0 * n
    v = render(room, Pose(c[0], c[1], 1.4, math.degrees(math.atan2(-n[0], -n[1])), 0, 0),
               640, 480, hfov_deg=70.0, supersample=1)
    photo = tmp_path / "posters.jpg"
    cv2.imwrite(str(photo), v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    args = ("hypotheses", photo, "--intrinsics", intrinsics_flag(v.camera), "--gravity", "0,1,0")
    out = as_json(run_findme(*args, "--json"))
    first, second = out["hypotheses"][:2]
    assert first["segments"] == ["none"] and first["flat"] == 0.0 and second["flat"] >= 0.5
    view = out["room_view"]
    assert view["ok"] is False and "no floor is in the photo" in view["reason"]
    text = run_findme(*args).stdout
    assert f"the same colour above and below along {100 * second['flat']:.0f} % of it" in text


def test_paper_method_and_text_output(level_jpg, level_view):
    p = run_findme("hypotheses", level_jpg, "--intrinsics", intrinsics_flag(level_view.camera),
                   "--method", "paper")
    assert "hypotheses for" in p.stdout and "edge support" in p.stdout


def test_locate_matches_the_rendered_scene(level_jpg, level_view, tmp_path):
    cam = level_view.camera
    lab = level_view.labels
    vs, us = np.nonzero(lab == FLOOR)
    pick = [(int(us[i]), int(vs[i])) for i in np.linspace(0, len(us) - 1, 3).astype(int)]
    pts = tmp_path / "p.json"
    pts.write_text(json.dumps({"points": pick + [[320, 50]]}))
    out = as_json(run_findme("locate", level_jpg, "--intrinsics", intrinsics_flag(cam),
                             "--gravity", "0,1,0", "--gravity-sigma", "0",
                             "--camera-height", level_view.camera_height,
                             "--points", pts, "--json"))
    assert out["metric"] is True and len(out["points"]) == 4 and len(out["distances_m"]) == 3
    assert out["camera"]["source"] == "input" and out["gravity"]["source"] == "input"
    assert out["gravity"]["vector"] == [0, 1, 0]
    for (u, v), p in zip(pick, out["points"]):
        assert p["surface"] == "floor" and p["error"] is None
        assert np.allclose(p["xyz_m"], level_view.points_cam[v, u], atol=2e-3)
    wall = out["points"][3]
    assert wall["surface"] == "wall" and wall["sigma_m"] > 0
    d01 = np.linalg.norm(np.subtract(out["points"][0]["xyz_m"], out["points"][1]["xyz_m"]))
    assert out["distances_m"][0] == pytest.approx(d01, abs=1e-5)


def test_locate_without_height_is_up_to_scale(level_jpg, level_view):
    out = as_json(run_findme("locate", level_jpg, "--intrinsics",
                             intrinsics_flag(level_view.camera), "--gravity", "0,1,0",
                             "--gravity-sigma", "0", "--point", "320,470", "--point=-4,2",
                             "--json"))
    assert out["metric"] is False and out["camera_height_m"] == 1.0
    assert out["points"][0]["xyz_m"][1] == pytest.approx(1.0)      # on the floor, y = h = 1
    assert "outside" in out["points"][1]["error"] and out["distances_m"] == [None]


BAD = [
    (["hypotheses", "{missing}"], "no such file"),
    (["hypotheses", "{text}"], "not an image"),
    (["hypotheses", "{corrupt}"], "corrupt"),
    (["hypotheses", "{huge}"], "over the"),
    (["hypotheses", "{jpg}", "--intrinsics", "1,2,3"], "4 comma-separated numbers"),
    (["hypotheses", "{jpg}", "--gravity", "0,0,0"], "zero vector"),
    (["hypotheses", "{jpg}", "--hfov", "200"], "field of view"),
    (["hypotheses", "{jpg}", "--method", "surf"], "invalid choice"),
    (["hypotheses", "{jpg}", "--max", "0"], "at least 1"),
    (["locate", "{jpg}", "--point", "1,x"], "2 comma-separated numbers"),
    (["locate", "{jpg}", "--points", "{badpoints}"], "point 1"),
    (["locate", "{jpg}", "--points", "{text}"], "not valid JSON"),
    (["locate", "{jpg}", "--point", "3,3", "--hypothesis", "99"], "does not exist"),
    (["locate", "{jpg}", "--point", "3,3", "--camera-height", "-1"], "camera-height"),
    (["locate", "{jpg}"], "required"),
    (["locate", "{jpg}", "--points", "{binary}"], "not a text file"),
    (["locate", "{jpg}", "--points", "{nanpoints}"], "NaN"),
    (["locate", "{jpg}", "--point", "3,3", "--camera-height", "nan"], "finite"),
    (["hypotheses", "{jpg}", "--overlay", "{txt_out}"], "overlay"),
    (["hypotheses", "{jpg}", "--hfov", "nan"], "finite"),
    (["hypotheses", "{heic_fake}"], "corrupt"),
]


@pytest.mark.parametrize("argv,msg", BAD)
def test_bad_input_is_one_line_and_exit_2(argv, msg, level_jpg, tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("hello, not an image")
    corrupt = tmp_path / "corrupt.jpg"
    corrupt.write_bytes(level_jpg.read_bytes()[:400])
    huge = tmp_path / "huge.png"   # a valid PNG header claiming 100000 x 100000 pixels
    huge.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\rIHDR" + (100000).to_bytes(4, "big") * 2
                     + b"\x08\x02\x00\x00\x00" + b"\x00" * 64)
    badpoints = tmp_path / "bp.json"
    badpoints.write_text(json.dumps([[1, 2], ["a", 3]]))
    binary = tmp_path / "points.bin"
    binary.write_bytes(bytes(range(256)) * 4)
    nanpoints = tmp_path / "nan.json"
    nanpoints.write_text("[[1, 2], [NaN, 3]]")
    heic_fake = tmp_path / "fake.heic"   # an HEIF box header and nothing behind it
    heic_fake.write_bytes(b"\x00\x00\x00\x18ftypheic\x00\x00\x00\x00mif1heic" + b"\x00" * 100)
    subst = dict(missing=tmp_path / "nope.jpg", text=text, corrupt=corrupt, huge=huge,
                 jpg=level_jpg, badpoints=badpoints, binary=binary, nanpoints=nanpoints,
                 txt_out=tmp_path / "out.txt", heic_fake=heic_fake)
    p = run_findme(*[a.format(**subst) for a in argv], check=False)
    assert p.returncode == 2, p.stderr
    assert msg in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr


def test_run_refuses_a_nan_field_of_view():
    p = run_findme("run", "--hfov", "nan", "--no-record", check=False)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "finite" in p.stderr


def test_run_into_a_closed_pipe_is_quiet(tmp_path):
    """``findme run | head -3``: the reader leaves early; no traceback, exit 0."""
    import subprocess
    import sys
    run = subprocess.Popen([sys.executable, "-m", "findme.cli", "run", "--out", str(tmp_path)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    head = [run.stdout.readline() for _ in range(3)]
    run.stdout.close()                      # what head does after its third line
    err = run.stderr.read().decode()
    assert run.wait(timeout=120) == 0, err
    assert all(head) and "Error" not in err and "Traceback" not in err, err


def test_one_blas_thread_per_process_set_before_numpy(monkeypatch):
    """``findme`` sets one BLAS and one OpenCV thread per process (idle pool threads spin:
    up to twice the CPU per photo, measured) unless the user chose; it can only do so before numpy is imported,
    which importing the command does not do."""
    import subprocess
    import sys
    from findme import cli
    code = "import sys, findme.cli; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.delenv("OPENCV_FOR_THREADS_NUM", raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "4")
    cli.one_thread_per_process()
    import os
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1" and os.environ["OMP_NUM_THREADS"] == "4"
    assert os.environ["OPENCV_FOR_THREADS_NUM"] == "1"
    # and this OpenCV honours the variable (its default is one thread per core)
    code = "import cv2; print(cv2.getNumThreads())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env={**os.environ, "OPENCV_FOR_THREADS_NUM": "1"})
    assert out.stdout.strip() == "1"


def test_locate_with_the_surface_you_tapped(level_jpg, level_view, tmp_path):
    """``--point U,V,floor|wall`` and ``[u, v, "floor"]``: said "wall" on a floor pixel gets
    no answer with what to do; said "floor" on a floor pixel is the floor's point; a surface
    that is neither is refused with the value."""
    cam = level_view.camera
    lab = level_view.labels
    vs, us = np.nonzero(lab == FLOOR)
    u, v = int(us[len(us) // 2]), int(vs[len(vs) // 2])
    flags = ["--intrinsics", intrinsics_flag(cam), "--gravity", "0,1,0", "--gravity-sigma", "0",
             "--camera-height", level_view.camera_height]
    out = as_json(run_findme("locate", level_jpg, *flags, f"--point={u},{v},floor",
                             f"--point={u},{v},wall", f"--point={u},{v}", "--json"))
    said, wall, plain = out["points"]
    assert said["said"] == "floor" and plain["said"] is None and said["xyz_m"] == plain["xyz_m"]
    assert np.allclose(said["xyz_m"], level_view.points_cam[v, u], atol=2e-3)
    assert wall["xyz_m"] is None and "choose a hypothesis" in wall["error"]
    pts = tmp_path / "p.json"
    pts.write_text(json.dumps([[u, v, "floor"], [u, v]]))
    text = run_findme("locate", level_jpg, *flags, "--points", pts).stdout
    assert "floor (as you said)" in text
    pts.write_text(json.dumps([[u, v, "ceiling"]]))
    bad = run_findme("locate", level_jpg, *flags, "--points", pts, check=False)
    assert bad.returncode == 2 and "'ceiling'" in bad.stderr
    bad = run_findme("locate", level_jpg, *flags, f"--point={u},{v},3", check=False)
    assert bad.returncode == 2 and "floor, wall or top" in bad.stderr


def test_locate_on_a_counters_top(counter_view, tmp_path):
    """``--point U,V,top``: a pixel of a counter's top is put on it, its height above the floor
    said; one the boundary puts on the floor is refused with what to do."""
    v, cam = counter_view, counter_view.camera
    jpg = tmp_path / "counter.jpg"
    cv2.imwrite(str(jpg), v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    px, truth = top_pixels(v, step=2003)
    flags = ["--intrinsics", intrinsics_flag(cam), "--gravity", ",".join(map(str, cam.gravity)),
             "--gravity-sigma", "0", "--camera-height", v.camera_height]
    floor = np.argwhere(v.labels == FLOOR)[-1]            # a floor pixel near the bottom
    points = [f"--point={u:g},{w:g},top" for u, w in px] + [f"--point={floor[1]},{floor[0]},top"]
    out = as_json(run_findme("locate", jpg, *flags, *points, "--json"))
    got = out["points"]
    assert len(px) >= 5
    for p, t in zip(got[:-1], truth):
        assert p["surface"] == "top" and p["said"] == "top", p
        err = np.linalg.norm(np.subtract(p["xyz_m"], t))
        assert err < 0.1 and err < 3 * p["sigma_m"]
        assert p["height_m"] == pytest.approx(0.9, abs=0.03)
    assert got[-1]["xyz_m"] is None and "puts the point on the floor" in got[-1]["error"]
    text = run_findme("locate", jpg, *flags, points[0]).stdout
    assert "  top   (as you said) x " in text
    height = float(re.search(r", ([0-9.]+) m above the floor", text).group(1))
    assert height == pytest.approx(0.9, abs=0.03)
