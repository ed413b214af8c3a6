"""The floor plan on the page: ``findme app`` (its mapper) and headless Chromium.

A user stands in a rendered 5 x 4 m room and turns round, uploading 8 photos tilted down;
the page draws the plan as it grows (walls not seen dashed), with the wall lengths in metres
or feet and where each photo was taken. The photos go through the real pipeline (hypotheses,
the gateway's rank-1 preselection, the mapper), so lengths are checked within 10 cm.
Waits are on page selectors (no sleeps).
"""

from __future__ import annotations

import json

import pytest

from findme_core.synth.room import Room
from services.web.page_output import to_page
from tests.plan_room import rendered_session
from tests.schemas.conftest import sample_messages

from tests.web.test_web_app import PHONE, close, open_page, type_camera, upload

pytestmark = pytest.mark.timeout(240)


def test_plan_as_the_page_reads_it():
    samples = dict(sample_messages())
    d = to_page("s", samples["plan"])
    json.dumps(d)                                        # plain JSON
    assert d["type"] == "plan" and d["origin_index"] == 1 and d["metric"] is True
    assert [w["kind"] for w in d["walls"]] == ["wall", "opening", "wall", "missing"]
    assert d["walls"][0]["openings"] == [[1.2, 2.1]] and d["walls"][0]["a"] == [-1.5, -1.0]
    assert [q["status"] for q in d["poses"]] == ["left_out", "placed", "placed", "not_placed"]
    assert d["poses"][0]["x_m"] is None and d["poses"][2]["ambiguity"] == 0.35
    assert d["corner_sigma_m"] == [None, [0.04, 0.03], [0.05, 0.06], None]
    r = to_page("s", samples["plan-reason"])
    assert r["reason"] and r["walls"] == [] and r["polygon"] == []
    r = to_page("s", samples["plan-refused"])       # no outline, the photos' places kept
    assert r["reason"] and r["walls"] == [] and r["polygon"] == []
    assert [q["status"] for q in r["poses"]] == ["placed"] * 3 and r["poses"][2]["x_m"] == 2.1


def test_a_refused_outline_shows_where_the_photos_were_not_an_older_outline(browser, app,
                                                                           shots):
    samples = dict(sample_messages())
    page = open_page(browser, app, **PHONE)
    render = "m => FindMePlan.render(m, 'm')"
    page.evaluate(render, to_page("s", samples["plan-closed"]))
    assert page.get_attribute("#plan-map", "data-walls") == "4"
    # each measured corner's 1-sigma drawn; none for the two ends of the missing wall
    page.evaluate(render, to_page("s", samples["plan"]))
    corners = page.eval_on_selector_all(
        "#plan-map ellipse.plan-corner-sigma",
        "els => els.map(e => [+e.dataset.index, +e.getAttribute('rx'), +e.getAttribute('ry')])")
    assert corners == [[1, 0.04, 0.03], [2, 0.05, 0.06]]
    refused = to_page("s", samples["plan-refused"])
    page.evaluate(render, refused)
    assert page.get_attribute("#plan", "data-refused") == "true"
    assert page.get_attribute("#plan", "data-shown") == "2"        # this plan, not the last
    assert page.get_attribute("#plan-map", "hidden") is None        # drawn: the cameras
    assert page.get_attribute("#plan-map", "data-walls") == "0"
    assert page.locator("#plan-map polygon.floor").count() == 0
    assert page.locator("#plan-map g.plan-cam").count() == 3        # each photo, heading
    assert page.locator("#plan-map text.plan-cam-label").count() == 2   # at two spots
    # each photo's 1-sigma drawn where it has one: photo 3's, 0.3 x 0.2 m
    sig = page.eval_on_selector_all("#plan-map ellipse.plan-cam-sigma",
                                    "els => els.map(e => [+e.getAttribute('rx'), +e.getAttribute('ry')])")
    assert sig == [[0.3, 0.2]]
    text = page.inner_text("#plan-text")
    assert "disagree about the room" in text and refused["reason"] in text, text
    assert "Where 3 of them were taken is shown" in text
    shots(page, "plan-4-outline-refused-photos-shown", at="#plan")
    # then a plan with nothing placed and no outline: the refused plan's photos stay on
    # screen, not the older outline they contradicted (which came back before)
    reason = to_page("s", samples["plan-reason"])
    page.evaluate(render, reason)
    assert page.get_attribute("#plan", "data-refused") == "true"
    assert page.get_attribute("#plan", "data-shown") == "2"
    assert page.locator("#plan-map polygon.floor").count() == 0
    assert page.locator("#plan-map g.plan-cam").count() == 3
    text = page.inner_text("#plan-text")
    assert refused["reason"] in text and reason["reason"] in text, text
    assert f"With photo {reason['up_to_index'] + 1} nothing is placed" in text, text
    # an outline again: drawn
    page.evaluate(render, to_page("s", samples["plan-closed"]))
    assert page.get_attribute("#plan", "data-refused") == "false"
    assert page.get_attribute("#plan-map", "data-walls") == "4"
    assert not page.js_errors, page.js_errors
    close(page)


@pytest.fixture(scope="module")
def turning(tmp_path_factory):
    """8 photos turning round at one spot of a 5 x 4 m room, as files, and the truth."""
    room = rendered_session(Room.rectangle(5.0, 4.0), [(0.3, -0.2)], yaws=range(0, 360, 45),
                            pitch=30.0, session="page")
    d = tmp_path_factory.mktemp("turning")
    paths = []
    for n, data in enumerate(room.jpegs):
        p = d / f"turn_{n}.jpg"
        p.write_bytes(data)
        paths.append(str(p))
    c = room.views[0].camera
    side = {"intrinsics": {"fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy},
            "gravity_cam": [float(g) for g in c.gravity]}
    return room, paths, side


def _walls(page):
    return page.eval_on_selector_all(
        "#plan-map line.wall[data-length-m]",
        "els => els.map(e => [e.dataset.kind, +e.dataset.lengthM])")


def test_the_floor_plan_grows_as_photos_are_taken(browser, app, shots, turning):
    room, paths, side = turning
    page = open_page(browser, app, **PHONE)
    if "mapper" not in page.evaluate("FindMe.state.services"):
        pytest.fail(f"findme app runs no mapper: {page.evaluate('FindMe.state.services')}")
    type_camera(page, side, height="1.4")
    seen, shown = [], []
    for n, path in enumerate(paths):
        upload(page, path, n)
        page.wait_for_selector(f'#plan[data-up-to="{n}"]', state="attached")
        seen.append((page.inner_text("#plan-text"), _walls(page)))
        shown.append((int(page.get_attribute("#plan", "data-shown")),
                      page.get_attribute("#plan-map", "hidden") is None))
        if any(k == "missing" for k, _ in seen[-1][1]) and not any(
                any(k == "missing" for k, _ in w) for _, w in seen[:-1]):
            shots(page, "plan-1-growing-unseen-walls-dashed", at="#plan")
    # early on: part of the room, the unseen side named (dashed), not invented
    early = [w for _, w in seen[1:4] if w]
    assert early and any(any(k == "missing" for k, _ in w) for w in early), seen[:4]
    # once there is an outline the drawing stays: a photo that leaves the server without
    # one (it says why) keeps the last outline on screen rather than blanking it
    first = next(i for i, (_, visible) in enumerate(shown) if visible)
    assert all(visible and k <= i for i, (k, visible) in enumerate(shown) if i >= first), shown
    page.wait_for_selector('#plan-map[data-walls="4"][data-closed="true"]')
    walls = _walls(page)
    assert [k for k, _ in walls] == ["wall"] * 4
    assert sorted(x for _, x in walls) == pytest.approx(room.wall_lengths(), abs=0.1)
    assert page.locator("#plan-map g.plan-cam").count() == 8      # where each photo was taken
    labels = page.eval_on_selector_all("#plan-map text.wall-label", "els => els.map(e => e.textContent)")
    assert len(labels) == 4 and all(t.endswith(" m") for t in labels)
    for (_, m), t in zip(walls, labels):
        assert t == f"{m:.2f} m"
    assert "4 walls" in page.inner_text("#plan-text")
    shots(page, "plan-2-closed-metres", at="#plan")

    page.click("#units-btn")
    page.wait_for_selector('#units-btn[aria-pressed="true"]')
    feet = page.eval_on_selector_all("#plan-map text.wall-label", "els => els.map(e => e.textContent)")
    for (_, m), t in zip(walls, feet):
        inches = round(m / 0.0254)
        assert t == f"{inches // 12}′ {inches % 12}″"
    assert "ft²" in page.inner_text("#plan-text")
    shots(page, "plan-3-closed-feet", at="#plan")
    close(page)
