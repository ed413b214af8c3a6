"""``findme plan`` and ``findme locate-in`` end to end (real entry point, subprocesses) on a
room the project renders: the photos and their camera sidecars (findme-eval view format)
on disk, the plan's outline and poses against the truth, and a new photo taken elsewhere
found on the plan, with and without the session's photos."""

from __future__ import annotations

import json
import math
import re

import cv2
import numpy as np
import pytest

from findme_core.plan import fuse
from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room
from tests.cli.conftest import as_json, run_findme
from tests.plan_room import H, first_frame_truth, rendered_session

ROOM = Room.rectangle(5.0, 4.0)
SPOTS = [(-0.8, -0.5), (1.0, 0.6)]
NEW = Pose(0.3, -1.0, H, 115.0, 28.0, 0.0)     # a third place, facing a corner


def _write(path, image_bytes, cam):
    path.write_bytes(image_bytes)
    path.with_suffix(".json").write_text(json.dumps({
        "intrinsics": {"fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
                       "width": cam.width, "height": cam.height},
        "gravity_cam": [float(g) for g in cam.gravity], "camera_height_m": H}))


@pytest.fixture(scope="module")
def session_on_disk(tmp_path_factory):
    """(photo paths, plan JSON path, plan dict, new photo path, truth of the new photo)."""
    d = tmp_path_factory.mktemp("plan")
    room = rendered_session(ROOM, SPOTS, yaws=range(0, 360, 60))
    paths = []
    for n, (data, v) in enumerate(zip(room.jpegs, room.views)):
        paths.append(d / f"photo_{n:02d}.jpg")
        _write(paths[-1], data, v.camera)
    nv = render(ROOM, NEW, 640, 480, hfov_deg=70.0, supersample=1)
    new = d / "new.jpg"
    _write(new, cv2.imencode(".jpg", nv.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes(),
           nv.camera)
    first = Pose(SPOTS[0][0], SPOTS[0][1], H, 0.0, 28.0, 0.0)
    truth, _ = first_frame_truth(ROOM, [first, NEW])
    out = run_findme("plan", *paths, "--json", timeout=300)
    plan = as_json(out)
    plan_path = d / "plan.json"
    plan_path.write_text(out.stdout)
    return paths, plan_path, plan, new, truth[1], room


def test_the_plan_is_the_rendered_room(session_on_disk):
    _, _, plan, _, _, room = session_on_disk
    V = np.array(plan["floor_polygon_m"])
    dist = np.linalg.norm(V[:, None] - room.polygon[None], axis=2)
    assert len(V) == 4 and dist.min(1).max() < 0.15, V.round(3)
    # each corner with the 1-sigma of its x and z, the true corner within 3 of them
    S = np.array(plan["corner_sigma_m"], float)
    T = room.polygon[dist.argmin(1)]
    assert S.shape == (4, 2) and np.all((S > 0) & (S < 0.2)), S
    assert np.all(np.abs(V - T) < 3 * S), (V - T, S)
    # a closed room: no opening (photo 3 faces its wall 1 m away; when its top hypothesis was
    # a poster's lower edge, its floor ran 4 m past the wall and opened it)
    assert [w["apertures"] for w in plan["walls"]] == [[]] * 4
    got = np.array([(p["x_m"], p["z_m"], math.radians(p["yaw_deg"]))
                    for p in plan["poses"].values()])
    assert np.abs(got[:, :2] - room.poses[:, :2]).max() < 0.1
    assert np.degrees(np.abs(fuse.wrap(got[:, 2] - room.poses[:, 2]))).max() < 2.0


def test_plain_photos_take_the_flags_camera(session_on_disk, tmp_path):
    """Plain photos (no sidecar: the camera app's JPEGs) with the camera given by flags, as
    exact (``--gravity-sigma 0``; every photo is pitched 28 deg down, unrolled: one gravity
    vector for all): the plan is the room's, as from the sidecars."""
    paths, _, _, _, _, room = session_on_disk
    plain = []
    for p in paths:
        plain.append(tmp_path / p.name)
        plain[-1].write_bytes(p.read_bytes())
    c = room.views[0].camera
    out = run_findme("plan", *plain, "--intrinsics", f"{c.fx},{c.fy},{c.cx},{c.cy}",
                     "--gravity", ",".join(f"{g:.9f}" for g in c.gravity),
                     "--gravity-sigma", "0", "--camera-height", str(H), timeout=300)
    assert out.returncode == 0, out.stderr
    # the text: walls, then each corner as "corner k: x +X z +Z ± SX / SZ m"
    corners = re.findall(r"^  corner (\d): x ([-+][\d.]+) z ([-+][\d.]+) ± ([\d.]+) / "
                         r"([\d.]+) m$", out.stdout, re.M)
    assert [int(k) for k, *_ in corners] == [0, 1, 2, 3], out.stdout
    V = np.array([[float(x), float(z)] for _, x, z, _, _ in corners])
    dist = np.linalg.norm(V[:, None] - room.polygon[None], axis=2)
    assert dist.min(1).max() < 0.15, V.round(3)
    assert all(0 < float(s) < 0.2 for *_, sx, sz in corners for s in (sx, sz)), corners


def _err(pose, truth):
    return (math.hypot(pose["x_m"] - truth[0], pose["z_m"] - truth[1]),
            abs(math.degrees(float(fuse.wrap(math.radians(pose["yaw_deg"]) - truth[2])))))


def test_a_new_photo_is_found_with_the_sessions_photos(session_on_disk):
    paths, plan_path, _, new, truth, _ = session_on_disk
    out = as_json(run_findme("locate-in", plan_path, new, "--photos", *paths, "--json",
                             timeout=300))
    t, y = _err(out["pose"], truth)
    assert t < 0.15 and y < 3.0, (out, truth)
    assert out["ambiguity"] < 0.8      # the features tell the rectangle's twins apart
    # one photo: the best first, but as a candidate (one photo shows too little to be sure)
    assert not out["found"] and "one photo" in out["reason"]


def test_the_plans_walls_alone_give_the_truth_among_their_poses(session_on_disk):
    # a rectangle looks alike turned half round: the walls alone may not tell which
    _, plan_path, _, new, truth, _ = session_on_disk
    out = as_json(run_findme("locate-in", plan_path, new, "--json"))
    errs = [_err(p, truth) for p in [out["pose"], *out["alternatives"]]]
    assert any(t < 0.2 and y < 3.0 for t, y in errs), (out, truth)
    assert out["ambiguity"] > 0.95     # and says so: the corner fits every corner alike
    # so no pose is stated: the candidates are given, with the reason and what would decide
    assert not out["found"] and "walls alone" in out["reason"]
    text = run_findme("locate-in", plan_path, new).stdout.splitlines()
    assert text[0].startswith("cannot tell where you are: the plan's walls alone")
    assert [ln.split(".")[0].strip() for ln in text[1:]] == \
        [str(k + 1) for k in range(1 + len(out["alternatives"]))]


def test_photos_that_are_not_the_plans_are_refused(session_on_disk):
    paths, plan_path, _, new, _, _ = session_on_disk
    p = run_findme("locate-in", plan_path, new, "--photos", *paths[::-1], check=False)
    assert p.returncode == 2 and "not the plan's photos" in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


@pytest.fixture(scope="module")
def turn_on_disk(session_on_disk, tmp_path_factory):
    """Two more photos at the new photo's place, turned 50 and 100 deg right of it: (their
    paths with the new photo's first, the truth of each in the plan's frame)."""
    d = tmp_path_factory.mktemp("turn")
    _, _, _, new, _, _ = session_on_disk
    paths, poses = [new], [NEW]
    for k, turn in enumerate((50.0, 100.0)):
        pose = Pose(NEW.x, NEW.z, H, NEW.yaw_deg + turn, NEW.pitch_deg, 0.0)
        v = render(ROOM, pose, 640, 480, hfov_deg=70.0, supersample=1)
        paths.append(d / f"turn_{k}.jpg")
        _write(paths[-1], cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1]
               .tobytes(), v.camera)
        poses.append(pose)
    first = Pose(SPOTS[0][0], SPOTS[0][1], H, 0.0, 28.0, 0.0)
    truth, _ = first_frame_truth(ROOM, [first, *poses])
    return paths, truth[1:]


def test_a_turn_at_a_new_place_is_found_together(session_on_disk, turn_on_disk):
    paths, plan_path, _, _, _, _ = session_on_disk
    turn, truth = turn_on_disk
    out = as_json(run_findme("locate-in", plan_path, *turn, "--photos", *paths, "--json",
                             timeout=300))
    assert out["pose"]["photo"] == turn[0].name
    assert set(out["photos"]) == {p.name for p in turn}
    for p, want in zip(turn, truth):   # every photo of the turn, each with its own heading
        t, y = _err(out["photos"][p.name], want)
        assert t < 0.15 and y < 3.0, (p.name, out["photos"][p.name], want)
    assert out["found"] and "reason" not in out      # a turn with the plan's photos: stated
    # with its 1-sigma, which holds here too
    sx, sy = out["pose"]["sigma_xz_m"], out["pose"]["sigma_yaw_deg"]
    t, y = _err(out["pose"], truth[0])
    assert t < 3 * sx * math.sqrt(2) and y < 3 * sy, (out["pose"], truth[0])
    text = run_findme("locate-in", plan_path, *turn, "--photos", *paths, timeout=300).stdout
    assert text.startswith("you are at x ") and f"± {sx:.2f} m" in text, text
    assert all("sigma_xz_m" not in q for q in out["alternatives"])
    walls = as_json(run_findme("locate-in", plan_path, *turn, "--json"))
    errs = [_err(q, truth[0]) for q in [walls["pose"], *walls["alternatives"]]]
    assert any(t < 0.2 and y < 3.0 for t, y in errs), (walls, truth[0])


def test_a_refused_outline_still_says_where_the_photos_were_and_finds_a_new_one(
        session_on_disk, turn_on_disk, tmp_path, monkeypatch, capsys):
    """A plan whose outline contradicts its photos prints no walls, the reason, and where each
    photo was taken with its 1-sigma (exit 1); locate-in takes that plan with the session's
    photos and finds a turn on it, and without them says why it cannot. (The seen-past check,
    tested on its own in tests/core/plan/test_seen_past.py, is made to refuse this closed
    room, in process.)"""
    from findme.cli import main
    from findme_core.plan import consistency
    paths, _, plan, _, _, room = session_on_disk
    why = "the outline puts a wall where 2 photo(s) (photo_03.jpg, photo_08.jpg) saw past it"
    monkeypatch.setattr(consistency, "walls_seen_past", lambda plan, *a, **k: why)
    svg = tmp_path / "photos.svg"
    assert main(["plan", *map(str, paths), "--json", "--svg", str(svg)]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["reason"] == why
    drawn = svg.read_text()                  # the photos alone, and why there are no walls
    assert drawn.count("<circle ") == len(paths) and 'stroke="#1a4f9c"' not in drawn
    assert "no outline: the outline puts a wall where 2 photo(s)" in drawn
    assert out["floor_polygon_m"] == [] and out["walls"] == []
    assert out["poses"] == plan["poses"]                 # the same places, with their sigmas
    assert all("sigma_xz_m" in p for p in list(out["poses"].values())[1:])
    assert main(["plan", *map(str, paths)]) == 1
    text = capsys.readouterr().out.splitlines()
    assert text[0] == "no floor plan: " + out["reason"].splitlines()[0]
    assert text[1].startswith("where the photos were taken (x, z in m;")
    assert len(text) == 2 + len(paths) and " m and " in text[-1] and "(1-sigma " in text[-1]
    refused = tmp_path / "refused.json"
    refused.write_text(json.dumps(out))
    monkeypatch.undo()
    turn, truth = turn_on_disk
    p = run_findme("locate-in", refused, *turn, check=False)
    assert p.returncode == 2 and "has no walls" in p.stderr and "--photos" in p.stderr
    found = as_json(run_findme("locate-in", refused, *turn, "--photos", *paths, "--json",
                               timeout=300))
    t, y = _err(found["pose"], truth[0])
    assert t < 0.15 and y < 3.0 and found["found"], (found["pose"], truth[0])


def _with_direction(src, dst, degrees):
    """A copy of photo ``src`` (and its sidecar) whose EXIF says the camera looked
    ``degrees`` from magnetic north, as a phone's camera app writes its compass bearing."""
    from tests.plan_room import _jpeg_with_direction
    img = cv2.imread(str(src))
    dst.write_bytes(_jpeg_with_direction(img, degrees % 360.0))
    dst.with_suffix(".json").write_text(src.with_suffix(".json").read_text())
    return dst


def test_the_files_compass_bearings_rule_out_the_rooms_twin(session_on_disk, turn_on_disk,
                                                           tmp_path):
    # every file says which way it looked (a compass bearing 12 deg off at most, taken at a
    # compass's 30 deg): a photo at a new place is found with the session's photos, and the
    # places left are those that turn it as the compass says, give or take what a compass
    # near steel may err: the rectangle's half-turn twin is gone, a quarter turn is not.
    # (The turn's last photo alone: the three together no longer leave the twin.)
    paths, plan_path, _, _, _, room = session_on_disk
    turn, want = turn_on_disk
    rng = np.random.default_rng(5)
    north = 40.0    # where magnetic north is in the plan's frame, degrees

    def bearing(yaw):
        return math.degrees(yaw) + north + rng.uniform(-12.0, 12.0)
    copies = [_with_direction(p, tmp_path / p.name, bearing(y))
              for p, y in zip(paths, room.poses[:, 2])]
    newc = [_with_direction(p, tmp_path / p.name, bearing(w[2])) for p, w in zip(turn, want)]
    plain = as_json(run_findme("locate-in", plan_path, turn[2], "--photos", *paths, "--json",
                               timeout=300))
    told = as_json(run_findme("locate-in", plan_path, newc[2], "--photos", *copies, "--json",
                              timeout=300))

    def yaw_errs(out):
        return [_err(q, want[2])[1] for q in [out["pose"], *out["alternatives"]]]
    assert max(yaw_errs(plain)) > 170.0, plain                # the twin, as a candidate
    assert _err(told["pose"], want[2])[0] < 0.15 and max(yaw_errs(told)) < 120.0, told
