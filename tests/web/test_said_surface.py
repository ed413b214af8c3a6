"""The user says which surface they tap (floor / wall / as the boundary says): through the
gateway to the measurement service of ``findme app`` and back, and on the phone page.

room_a with its sidecar camera: with hypothesis 1, pixel (320, 100) is on the wall and
(320, 400) on the floor (each checked in the same request, said nothing). Said floor, the
wall pixel is put on the floor; said wall, the floor pixel gets no point and the service
says what to do. Every wait is on a message or a page selector (no sleeps)."""

from __future__ import annotations

import asyncio
import json
from importlib import resources

import aiohttp
import cv2
import numpy as np
import pytest

from findme_core.single.hypotheses import column_rows
from tests.conftest import side_face_pixels, top_pixels
from test_web_app import PHONE, SIDE_A, close, tap_pixel, type_camera, upload

pytestmark = pytest.mark.timeout(120)

ROOM_A = resources.files("findme") / "examples" / "room_a.jpg"
WALL_PX, FLOOR_PX = (320, 100), (320, 400)


def upload_bytes(header: dict, image: bytes) -> bytes:
    h = json.dumps(header).encode()
    return len(h).to_bytes(4, "big") + h + image


async def next_of(ws, kind: str, timeout: float = 60, **match):
    """The next message of type ``kind`` (with ``match``'s values) on the page's socket."""
    while True:
        m = await ws.receive_json(timeout=timeout)
        if m["type"] == "error":
            raise AssertionError(f"the server refused: {m}")
        if m["type"] == kind and all(m.get(k) == v for k, v in match.items()):
            return m


def measures_of_rendered(app, view, *requests):
    """``view`` (a render: its lens, gravity and camera height sent with it) uploaded as photo
    0 through ``app``'s gateway; once its scene is up, each request (the measure's "pixels"
    and, if any, "surfaces") is sent in turn: their replies."""
    cam = view.camera
    lens = {"kind": "intrinsics", "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
            "width": cam.width, "height": cam.height}
    header = {"id": "r", "lens": lens, "gravity": cam.gravity.tolist(),
              "camera_height_m": view.camera_height}
    ok, jpg = cv2.imencode(".jpg", view.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok

    async def run():
        async with aiohttp.ClientSession() as http, http.ws_connect(app.url + "ws") as ws:
            assert (await ws.receive_json(timeout=10))["type"] == "hello"
            await ws.send_bytes(upload_bytes(header, jpg.tobytes()))
            await next_of(ws, "scene", index=0, rank=1)
            replies = []
            for i, req in enumerate(requests, 1):
                await ws.send_str(json.dumps({"type": "measure", "id": i, "index": 0, **req}))
                replies.append(await next_of(ws, "measure", id=i))
            return replies

    return asyncio.run(run())


def test_said_surfaces_reach_the_service_and_come_back(app):
    """A measure with surfaces, through a real gateway and measurement service: the reply
    to the page says what was said of each point, a wall pixel said floor comes back on
    the floor (with a floor point's sigma, not the wall's) and a note that the chosen line
    runs below it, a floor pixel said wall comes back with no point and what to do."""
    k = SIDE_A["intrinsics"]
    lens = {"kind": "intrinsics", **{n: k[n] for n in ("fx", "fy", "cx", "cy", "width", "height")}}
    header = {"id": "a", "lens": lens,
              "gravity": SIDE_A["gravity_cam"], "camera_height_m": 1.42}

    async def run():
        async with aiohttp.ClientSession() as http, http.ws_connect(app.url + "ws") as ws:
            assert (await ws.receive_json(timeout=10))["type"] == "hello"
            await ws.send_bytes(upload_bytes(header, ROOM_A.read_bytes()))
            await next_of(ws, "scene", index=0, rank=1)
            await ws.send_str(json.dumps({
                "type": "measure", "id": 1, "index": 0,
                "pixels": [WALL_PX, FLOOR_PX, WALL_PX, FLOOR_PX],
                "surfaces": [None, None, "floor", "wall"]}))
            return await next_of(ws, "measure", id=1)

    reply = asyncio.run(run())
    assert not reply["error"], reply
    wall, floor, said_floor, said_wall = reply["points"]
    assert (wall["surface"], wall["said"]) == ("wall", None)          # as the boundary says
    assert (floor["surface"], floor["said"]) == ("floor", None)
    assert (said_floor["surface"], said_floor["said"]) == ("floor", "floor"), said_floor
    assert not said_floor["error"] and said_floor["xyz"] is not None
    assert said_floor["sigma_m"] < wall["sigma_m"] / 2, (said_floor, wall)
    assert "floor line runs below this point" in said_floor["note"], said_floor
    assert wall["note"] is floor["note"] is None, (wall, floor)
    assert said_wall["said"] == "wall" and said_wall["xyz"] is None
    assert "choose a hypothesis whose floor line runs below it" in said_wall["error"], said_wall


def test_a_point_said_on_a_top_comes_back_on_it(app, counter_view):
    """A rendered counter against the far wall, through a real gateway and measurement
    service: a pixel of its top said "top" comes back on the top (its front edge found among
    the lines the hypotheses came with), one of the floor said "top" with no point and why.
    Said nothing, a top pixel comes back on the counter's face with a 1-sigma that spans its
    top reading and the note that says so, or with no point and why."""
    v = counter_view
    top_px, truth = top_pixels(v, step=4001)
    floor = np.argwhere(v.labels == 0)[-1][::-1].tolist()     # a floor pixel near the bottom
    pixels = [p.tolist() for p in top_px] + [floor]
    reply, unsaid = measures_of_rendered(
        app, v, {"pixels": pixels, "surfaces": ["top"] * len(pixels)}, {"pixels": pixels[:-1]})
    assert not reply["error"] and not unsaid["error"], (reply, unsaid)
    assert sum(p["xyz"] is not None for p in unsaid["points"]) >= 2, unsaid
    for p, q, t in zip(unsaid["points"], reply["points"], truth):
        if p["xyz"] is None:
            assert "too far apart to give one position; say top or wall" in p["error"], p
            continue
        assert (p["surface"], p["said"]) == ("wall", None), p
        assert "a level edge runs below this point" in p["note"], p
        assert np.linalg.norm(np.subtract(p["xyz"], t)) < 3 * p["sigma_m"], (p, t)
        assert p["sigma_m"] > np.linalg.norm(np.subtract(p["xyz"], q["xyz"])) * 0.9, (p, q)
    *tops, on_floor = reply["points"]
    assert len(tops) >= 3
    for p, t in zip(tops, truth):
        assert (p["surface"], p["said"]) == ("top", "top"), p
        err = np.linalg.norm(np.subtract(p["xyz"], t))
        assert err < 0.1 and err < 3 * p["sigma_m"], (p, t)
    assert on_floor["xyz"] is None and "puts the point on the floor" in on_floor["error"]


def test_a_point_beside_a_step_is_widened_toward_the_face(app, side_view):
    """A rendered cabinet turned 30 deg, through a real gateway and measurement service: the
    hypotheses step at its front corner, so pixels of its side face come back on the floor
    behind. Said nothing, those on the floor carry the note and a 1-sigma widened toward the
    face in front (the truth within 3), or have no point and why; said floor, they are on the
    floor as said, without that note or its spread."""
    px, truth = side_face_pixels(side_view, step=23)
    pixels = px.tolist()
    unsaid, said = measures_of_rendered(app, side_view, {"pixels": pixels},
                                        {"pixels": pixels, "surfaces": ["floor"] * len(pixels)})
    assert not unsaid["error"] and not said["error"], (unsaid, said)
    noted = 0
    for p, t in zip(unsaid["points"], truth):
        if p["xyz"] is None:
            assert p["error"], p
            continue
        assert np.linalg.norm(np.subtract(p["xyz"], t)) < 3 * p["sigma_m"], (p, t)
        if p["surface"] == "floor" and p["note"]:
            assert "the floor line steps back" in p["note"], p
            noted += 1
    assert noted >= 0.6 * len(pixels), unsaid
    for p, q in zip(unsaid["points"], said["points"]):   # on the floor, the user has decided
        assert (q["surface"], q["said"]) == ("floor", "floor"), q
        if p["surface"] == "floor":
            assert q["note"] is None and q["sigma_m"] < p["sigma_m"], (p, q)


def _phone_with_room_a(browser, app):
    """A phone page connected to ``app`` with room_a uploaded as photo 0 (its camera typed)."""
    page = browser.new_context(**PHONE).new_page()
    page.js_errors = []
    page.on("pageerror", lambda e: page.js_errors.append(str(e)))
    page.goto(app.url)
    page.wait_for_selector('#status[data-state="connected"]')
    assert page.is_checked('#tap-as input[value=""]')                # the default
    type_camera(page, SIDE_A)
    upload(page, str(ROOM_A), 0)
    return page


def _record_sent(page) -> None:
    """From now on, every message the page sends is also kept in ``window.__sent``."""
    page.evaluate("""() => { window.__sent = [];
        const ws = FindMe.state.ws, send = ws.send.bind(ws);
        ws.send = (d) => { if (typeof d === 'string') window.__sent.push(JSON.parse(d)); send(d); }; }""")


def test_the_page_says_which_surface_you_tap(browser, app, shots):
    """Phone page: pick "floor", tap the wall pixel: the request says surfaces ["floor"],
    the list item and the dot say it, the service's answer puts it on the floor "as you
    said", with the note that the chosen line runs below it. The choice holds for the next
    taps until changed; "as the boundary says" taps send null; "Clear points" clears what was said, and a request with nothing said has no
    surfaces at all."""
    page = _phone_with_room_a(browser, app)
    _record_sent(page)

    def measures(n):
        page.wait_for_function(
            "n => window.__sent.filter(m => m.type === 'measure').length >= n", arg=n)
        return [m for m in page.evaluate("window.__sent") if m["type"] == "measure"]

    page.locator("#tap-as label", has_text="floor").tap()
    assert page.is_checked('#tap-as input[value="floor"]')
    page.locator("#stage").evaluate("e => e.scrollIntoView({block: 'center'})")
    tap_pixel(page, *WALL_PX)
    first = measures(1)[-1]
    assert first["surfaces"] == ["floor"] and len(first["pixels"]) == 1, first
    page.wait_for_selector('#points li[data-said="floor"]')
    assert page.locator("#overlay circle.pt.said").count() == 1
    li = page.wait_for_selector('#points li[data-said="floor"][data-x]')
    assert li.get_attribute("data-surface") == "floor"
    assert li.inner_text().startswith("floor (as you said) · "), li.inner_text()
    assert "floor line runs below this point" in li.query_selector(".note").inner_text()
    shots(page, "11-phone-said-floor", at="#stage")

    page.locator("#tap-as label", has_text="as the boundary says").tap()
    page.locator("#stage").evaluate("e => e.scrollIntoView({block: 'center'})")
    tap_pixel(page, *FLOOR_PX)
    second = measures(2)[-1]
    assert second["surfaces"] == ["floor", None], second
    page.wait_for_selector('#points li[data-said=""][data-x]')
    assert page.locator("#overlay circle.pt.said").count() == 1
    assert not page.inner_text('#points li[data-said=""]').endswith("(as you said)")

    page.locator("#tap-as label", has_text="wall").tap()
    page.locator("#stage").evaluate("e => e.scrollIntoView({block: 'center'})")
    tap_pixel(page, *FLOOR_PX)
    assert measures(3)[-1]["surfaces"] == ["floor", None, "wall"]
    bad = page.wait_for_selector('#points li.bad[data-said="wall"]')
    assert "floor line runs below it" in bad.inner_text(), bad.inner_text()
    shots(page, "12-phone-said-wall-on-the-floor", at="#stage")

    page.click("#clear-btn")
    assert page.locator("#points li").count() == 0
    assert page.evaluate("FindMe.state.photos[0].surfaces") == []
    page.locator("#tap-as label", has_text="as the boundary says").tap()
    page.locator("#stage").evaluate("e => e.scrollIntoView({block: 'center'})")
    tap_pixel(page, *FLOOR_PX)
    last = measures(4)[-1]
    assert "surfaces" not in last and len(last["pixels"]) == 1, last
    page.wait_for_selector('#points li[data-said=""][data-surface="floor"]')
    close(page)


def test_the_page_measures_a_counters_top_and_says_how_high_it_is(browser, app, shots,
                                                                  counter_view, tmp_path):
    """Phone page, the rendered counter: "top of something", then a tap on its top: the
    request says surfaces ["top"], the point comes back on the top, and the list says how
    high the top is (0.9 m). A tap high on the wall behind the counter, said top, comes back
    refused (it would lie metres behind the counter's back edge) with the reason."""
    v, cam = counter_view, counter_view.camera
    jpg = tmp_path / "counter.jpg"
    cv2.imwrite(str(jpg), v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    side = {"intrinsics": {"fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy},
            "gravity_cam": cam.gravity.tolist()}
    page = browser.new_context(**PHONE).new_page()
    page.js_errors = []
    page.on("pageerror", lambda e: page.js_errors.append(str(e)))
    page.goto(app.url)
    page.wait_for_selector('#status[data-state="connected"]')
    type_camera(page, side, height=repr(v.camera_height))
    upload(page, str(jpg), 0)
    _record_sent(page)
    page.locator("#tap-as label", has_text="top of something").tap()
    assert page.is_checked('#tap-as input[value="top"]')
    u, w = top_pixels(v, step=1)[0][6000]
    page.locator("#stage").evaluate("e => e.scrollIntoView({block: 'center'})")
    tap_pixel(page, u, w)
    li = page.wait_for_selector('#points li[data-said="top"][data-height-m]')
    assert float(li.get_attribute("data-height-m")) == pytest.approx(0.9, abs=0.05)
    assert li.get_attribute("data-surface") == "top"
    assert "top (as you said)" in li.inner_text() and "above the floor" in li.inner_text()
    sent = [m for m in page.evaluate("window.__sent") if m["type"] == "measure"]
    assert sent[-1]["surfaces"] == ["top"], sent
    assert 10 <= v.labels[20, 320] < 50                          # the wall high above it
    tap_pixel(page, 320, 20)
    bad = page.wait_for_selector('#points li.bad[data-said="top"]')
    assert "farther behind that edge than a table's or a counter's top" in bad.inner_text()
    shots(page, "14-phone-said-top", at="#stage")
    close(page)


def _row_at(points, u):
    """The row of a hypothesis's polyline at column u, as the page compares it with a tap."""
    return float(column_rows(np.asarray(points, float), 480, np.array([u]))[0])


def test_a_floor_tap_above_the_line_offers_the_lines_that_agree(browser, app, shots):
    """Phone page: a pixel between the chosen line and a higher one, tapped as "floor": the
    point's note says the chosen line runs below it and offers the hypotheses whose line runs
    above it; picking one selects it, the point is measured again under it and the note is
    gone."""
    page = _phone_with_room_a(browser, app)
    hyps = page.evaluate("FindMe.state.photos[0].hyps")
    best = next(h for h in hyps if h["rank"] == 1)
    # the column where another line runs highest above the best one, and a pixel midway
    gaps = [(_row_at(best["points"], u) - _row_at(h["points"], u), u, h["rank"])
            for u in range(40, 600, 20) for h in hyps if h["rank"] != 1]
    gap, u, rank = max(gaps)
    assert gap > 20, gaps                     # room_a has such a line: the test needs one
    v = round(_row_at(best["points"], u) - gap / 2)
    above = sorted(h["rank"] for h in hyps
                   if h["rank"] != 1 and _row_at(h["points"], u) < v)
    page.locator("#tap-as label", has_text="floor").tap()
    page.locator("#stage").evaluate("e => e.scrollIntoView({block: 'center'})")
    tap_pixel(page, u, v)
    note = page.wait_for_selector('#points li[data-x] .note')
    assert "floor line runs below this point" in note.inner_text(), note.inner_text()
    offered = [int(b.get_attribute("data-rank")) for b in note.query_selector_all("button.pick")]
    assert offered == above and rank in offered, (offered, above)
    assert "Hypotheses whose line runs above it:" in note.inner_text()
    shots(page, "13-phone-floor-above-the-line", at="#points")
    _record_sent(page)
    note.query_selector(f'button.pick[data-rank="{rank}"]').click()
    page.wait_for_function(
        "r => window.__sent.some(m => m.type === 'select' && m.rank === r)", arg=rank)
    # measured again under the picked line, which runs above the point: no note
    page.wait_for_function(
        """r => { const p = FindMe.state.photos[0];
                  return p.sceneRank === r && p.reply && !p.reply.points[0].note; }""", arg=rank)
    assert page.locator("#points li .note").count() == 0
    close(page)
