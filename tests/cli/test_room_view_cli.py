"""A photo that is not a room view says so, with the reason, on the command line: ``findme
hypotheses`` (text and JSON), ``locate`` (a warning) and the services' report (``findme
run``); a room view does not."""

from __future__ import annotations

import json
import re
from importlib import resources

import cv2
import pytest

from findme_core.synth.render import Box, Pose, Room, render
from tests.cli.conftest import run_findme

EXAMPLES = resources.files("findme") / "examples"


def _photo(tmp_path, name, view) -> tuple[str, str]:
    path = tmp_path / f"{name}.jpg"
    cv2.imwrite(str(path), view.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
    return str(path), "--gravity=" + ",".join(f"{g:.6f}" for g in view.camera.gravity)


@pytest.fixture(scope="module")
def top_down(tmp_path_factory):
    return _photo(tmp_path_factory.mktemp("rv"), "top-down",
                  render(Room.rectangle(6, 6), Pose(0, 0, 1.4, 20, 88, 0)))


def test_hypotheses_of_a_top_down_photo_say_it_is_not_a_room(top_down):
    photo, gravity = top_down
    p = run_findme("hypotheses", photo, gravity, "--gravity-sigma", "0")
    lines = p.stdout.splitlines()
    assert lines[0].startswith("not a room view: the camera looks 88° down"), p.stdout
    assert "(guesses: this photo does not look like a room):" in lines[1]
    j = json.loads(run_findme("hypotheses", photo, gravity, "--gravity-sigma", "0",
                              "--json").stdout)
    assert j["room_view"]["ok"] is False and "88° down" in j["room_view"]["reason"]
    assert j["hypotheses"], "the hypotheses are still there, as guesses"
    loc = run_findme("locate", photo, gravity, "--point", "320,240")
    assert "warning: not a room view: the camera looks 88° down" in loc.stderr


def test_an_object_filling_the_view_says_how_near_the_floor_ends(tmp_path):
    room = Room.rectangle(6, 6, boxes=(Box(0, 0.9, 2.6, 0.6, 1.8),))
    photo, gravity = _photo(tmp_path, "box", render(room, Pose(0, 0, 1.4, 0, 50, 0)))
    j = json.loads(run_findme("locate", photo, gravity, "--gravity-sigma", "0",
                              "--camera-height", "1.4", "--point", "320,460", "--json").stdout)
    assert j["room_view"] == {"ok": False, "reason": (
        "something fills the view: the floor ends 0.8 m from the camera all across the photo "
        "(an object right in front of it?); step back so that the photo shows the room's "
        "walls")}


def test_the_example_is_a_room_view():
    side = json.loads((EXAMPLES / "room_a.json").read_text())
    k = side["intrinsics"]
    with resources.as_file(EXAMPLES / "room_a.jpg") as photo:
        p = run_findme("hypotheses", photo, f"--intrinsics={k['fx']},{k['fy']},{k['cx']},{k['cy']}",
                       "--gravity=" + ",".join(map(str, side["gravity_cam"])))
    assert "not a room view" not in p.stdout and "guesses" not in p.stdout


def test_the_services_report_says_it_too(top_down, tmp_path):
    photo, gravity = top_down
    out = run_findme("run", photo, gravity, "--gravity-sigma", "0", "--no-record",
                     check=False).stdout
    assert re.search(r"^photo 0: \d+ hypotheses in \d+ ms; NOT A ROOM VIEW: the camera looks "
                     "88° down", out, re.M), out
