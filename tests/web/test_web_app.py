"""End to end: the phone page served by ``findme app``, driven in headless Chromium.

Every wait is on a page selector, a page event or a reply (no sleeps). The page is used at
a phone's size (390 x 844, touch) except where a desktop is the point.
"""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
import zlib
from importlib import resources

import pytest

pytestmark = pytest.mark.timeout(120)

EXAMPLES = resources.files("findme") / "examples"
ROOM_A, ROOM_B = str(EXAMPLES / "room_a.jpg"), str(EXAMPLES / "room_b.jpg")
SIDE_A = json.loads((EXAMPLES / "room_a.json").read_text())
SIDE_B = json.loads((EXAMPLES / "room_b.json").read_text())
PAIR = json.loads((EXAMPLES / "pair.json").read_text())
PHONE = {"viewport": {"width": 390, "height": 844}, "device_scale_factor": 3,
         "is_mobile": True, "has_touch": True}


# ------------------------------------------------------------------------------ helpers
def open_page(browser, app, received=None, **ctx):
    """A connected page (a phone's unless ``ctx`` says); ``received``: a list the
    WebSocket's incoming messages are appended to."""
    context = browser.new_context(**(ctx or PHONE))
    page = context.new_page()
    page.js_errors = []
    page.on("pageerror", lambda e: page.js_errors.append(str(e)))
    if received is not None:
        page.on("websocket", lambda ws: ws.on("framereceived", lambda d: received.append(d)))
    page.goto(app.url)
    page.wait_for_selector('#status[data-state="connected"]')
    # log every busy-indicator state, to show it was up while the server worked
    page.evaluate("""() => { window.__busy = [];
        new MutationObserver(() => window.__busy.push(document.body.dataset.busy || ''))
          .observe(document.body, {attributes: true, attributeFilter: ['data-busy']}); }""")
    return page


def frame_ack(received) -> dict:
    """The gateway's acknowledgement of the first photo sent (``type`` "frame")."""
    return next(m for m in (json.loads(r) for r in received if isinstance(r, str))
                if m.get("type") == "frame")


def close(*pages):
    for page in pages:
        errors = page.js_errors
        page.context.close()
        assert not errors, f"JavaScript errors on the page: {errors}"


def type_camera(page, side, height="1.42"):
    """The sidecar's numbers typed into the form: intrinsics, gravity, camera height."""
    k = side["intrinsics"]
    if not page.evaluate("document.getElementById('settings').open"):
        page.click("#settings summary")
    page.select_option("#lens", "intrinsics")
    for name in ("fx", "fy", "cx", "cy"):
        page.fill(f"#{name}", repr(k[name]))
    for name, g in zip(("gx", "gy", "gz"), side["gravity_cam"]):
        page.fill(f"#{name}", repr(g))
    page.fill("#height", height)


def camera_flags(side, height=1.42):
    k = side["intrinsics"]
    return [f"--intrinsics={k['fx']!r},{k['fy']!r},{k['cx']!r},{k['cy']!r}",
            "--gravity=" + ",".join(repr(g) for g in side["gravity_cam"]),
            f"--camera-height={height!r}"]


def upload(page, path, index):
    page.set_input_files("#file-input", path)
    page.wait_for_selector(f'#frame[data-index="{index}"][data-scene-rank="1"]')


def tap_pixel(page, u, v, size=(640, 480), touch=True):
    """Tap (or click, on a desktop) where pixel (u, v) of the photo is on the screen."""
    box = page.locator("#photo").bounding_box()
    x = box["x"] + (u + 0.5) * box["width"] / size[0]
    y = box["y"] + (v + 0.5) * box["height"] / size[1]
    (page.touchscreen.tap if touch else page.mouse.click)(x, y)


def session_of(page) -> str:
    return page.evaluate("FindMe.state.session")


def locate(image, side, rank, pixels):
    cmd = [sys.executable, "-m", "findme.cli", "locate", image, *camera_flags(side),
           f"--hypothesis={rank}", "--json", *[f"--point={u:g},{v:g}" for u, v in pixels]]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


# ------------------------------------------------------------------------------ tests
def test_gravity_conversion_in_the_page(browser, app):
    """The page's device-to-camera gravity conversion (documented in settings.js)."""
    page = open_page(browser, app)
    r = page.evaluate("""() => {
        const F = FindMe, c = (g, t) => F.deviceToCamera(g, t).map(x => +x.toFixed(6));
        const pitch = 28 * Math.PI / 180;
        return {
          upright: c(F.deviceGravityFromOrientation(90, 0), 0),
          pitched: c(F.deviceGravityFromOrientation(90 - 28, 0), 0),
          expect_pitched: [0, +Math.cos(pitch).toFixed(6), +Math.sin(pitch).toFixed(6)],
          flat_up: F.deviceGravityFromOrientation(0, 0).map(x => +x.toFixed(6)),
          motion_upright: c(F.deviceGravityFromMotion(0, 9.81, 0), 0),
          left_rot: F.autoRotation([-1, 0, 0]), left: c([-1, 0, 0], F.autoRotation([-1, 0, 0])),
          right_rot: F.autoRotation([1, 0, 0]), right: c([1, 0, 0], F.autoRotation([1, 0, 0])),
          rolled: c(F.deviceGravityFromOrientation(90, 10), 0),
        }; }""")
    assert r["upright"] == [0, 1, 0]
    assert r["pitched"] == r["expect_pitched"]           # looking down: +z
    assert r["flat_up"] == [0, 0, -1]
    assert r["motion_upright"] == [0, 1, 0]
    assert (r["left_rot"], r["left"]) == (90, [0, 1, 0])
    assert (r["right_rot"], r["right"]) == (270, [0, 1, 0])
    assert r["rolled"][0] == 0 and r["rolled"][1] == 1   # gamma alone at beta = 90 is yaw
    close(page)


def test_photo_hypothesis_and_distance_match_locate(browser, app, shots):
    """Phone-sized page: room_a with its sidecar numbers, pick hypothesis 2, tap two floor
    points; the distance shown equals ``findme locate`` for the same pixels and flags."""
    page = open_page(browser, app)
    shots(page, "01-phone-empty")
    type_camera(page, SIDE_A)
    upload(page, ROOM_A, 0)
    chips = page.locator("#hyp-chips .chip")
    assert chips.count() >= 2
    assert page.get_attribute('#hyp-chips .chip[data-rank="1"]', "aria-pressed") == "true"
    shots(page, "02-phone-hypotheses-best-preselected", at="#result")

    page.locator('#hyp-chips .chip[data-rank="2"]').tap()
    page.wait_for_selector('#frame[data-rank="2"][data-scene-rank="2"]')
    assert page.get_attribute('#hyp-chips .chip[data-rank="2"]', "aria-pressed") == "true"
    shots(page, "03-phone-hypothesis-2-picked", at="#result")

    targets = [tuple(q["px"]) for q in SIDE_A["ground_truth"]["floor_points"][1:3]]
    for u, v in targets:
        tap_pixel(page, u, v)
    page.wait_for_selector("#distances li[data-distance-m]")
    page.wait_for_selector('#points li[data-surface="floor"] >> nth=1')
    shots(page, "04-phone-two-floor-points", at="#stage")
    pixels = page.eval_on_selector_all("#points li", "els => els.map(e => [+e.dataset.u, +e.dataset.v])")
    assert len(pixels) == 2
    assert all(abs(p - t) <= 2 for pix, tgt in zip(pixels, targets) for p, t in zip(pix, tgt))
    shown = float(page.get_attribute("#distances li[data-distance-m]", "data-distance-m"))
    text = page.inner_text("#distances .dist")

    ref = locate(ROOM_A, SIDE_A, 2, pixels)
    print(f"page: pixels {pixels}, distance {shown!r} ({text}); findme locate --hypothesis 2: "
          f"{ref['distances_m'][0]!r}")
    assert ref["points"][0]["surface"] == "floor" and ref["points"][1]["surface"] == "floor"
    assert shown == pytest.approx(ref["distances_m"][0], abs=1e-5)
    assert text == f"{ref['distances_m'][0]:.3f} m"
    xyz = page.eval_on_selector_all("#points li", "els => els.map(e => [+e.dataset.x, +e.dataset.y, +e.dataset.z])")
    for got, want in zip(xyz, ref["points"]):
        assert got == pytest.approx(want["xyz_m"], abs=1e-5)

    page.click("#units-btn")
    page.wait_for_selector('#units-btn[aria-pressed="true"]')
    assert " ft " in page.inner_text("#distances .dist")
    shots(page, "05-phone-feet-and-inches", at="#stage")
    if "recorder" in page.evaluate("FindMe.state.services"):   # recorded like any session
        assert (app.recordings / f"{session_of(page)}.mcap").exists()
    busy = page.evaluate("window.__busy")
    assert any("upload" in b for b in busy) and any("measure" in b for b in busy)
    assert page.is_hidden("#busy")      # and gone once the server answered
    close(page)


def test_page_state_does_not_depend_on_message_order(browser, app):
    """The bus does not order a selection (published by the gateway) against its scene
    (published by the measurement service): a scene that reaches the page before its
    selection still ends the wait for it."""
    page = open_page(browser, app)
    type_camera(page, SIDE_A)
    upload(page, ROOM_A, 0)
    before, after = page.evaluate("""() => {
        const F = FindMe, p0 = F.state.photos[0], h = p0.height_m;
        F.handle({type: 'frame', id: null, index: 1, width: p0.width, height: p0.height,
                  camera_height_m: h, reencoded: false});
        F.handle({type: 'hypotheses', index: 1, hypotheses: p0.hyps, reason: ''});
        F.handle({type: 'scene', index: 1, rank: 1, metric: true, camera_height_m: h});
        const before = document.body.dataset.busy;
        F.handle({type: 'selection', index: 1, rank: 1, by: 'auto', camera_height_m: null});
        return [before, document.body.dataset.busy];
    }""")
    assert "scene" in before.split()                        # the scene's rank is not chosen yet
    assert not {"scene", "upload"} & set(after.split()), after
    close(page)


def test_two_photos_show_the_motion(browser, app, shots):
    """room_a then room_b: the second photo's motion and the floor map (needs odometry)."""
    page = open_page(browser, app)
    type_camera(page, SIDE_A)
    upload(page, ROOM_A, 0)
    type_camera(page, SIDE_B)
    upload(page, ROOM_B, 1)
    assert page.locator("#photo-tabs .tab").count() == 2
    page.wait_for_selector("#motion:not([hidden])")
    if "odometry" not in page.evaluate("FindMe.state.services"):
        shots(page, "06-two-photos-no-odometry", at="#motion")
        assert "no odometry service" in page.inner_text("#motion-text")
        pytest.skip("findme app runs no odometry service (services/pipeline/odometry.py is not in this "
                    "checkout): the page says so; the motion display is tested with injected "
                    "messages in test_motion_messages_are_drawn")
    line = page.wait_for_selector('.motion-line[data-pair="0-1"]', timeout=60000)
    page.wait_for_selector('#floor-map[data-poses="2"]')
    shots(page, "06-two-photos-motion-and-map", at="#motion")
    x, z, yaw = (float(line.get_attribute(a)) for a in ("data-x-m", "data-z-m", "data-yaw-deg"))
    want = PAIR["motion"]
    assert math.hypot(x - want["x_m"], z - want["z_m"]) < 0.3, (x, z, want)
    assert abs(yaw - want["yaw_deg"]) < 5, (yaw, want)
    # both photos' walls on the map, photo 2's registered in photo 1's frame: an end of one
    # of its walls lies on the line of one of photo 1's
    page.wait_for_selector('#floor-map .wall[data-index="1"]')
    walls = page.evaluate("""[...document.querySelectorAll('#floor-map .wall')].map((w) =>
        [+w.dataset.index, ...['x1', 'y1', 'x2', 'y2'].map((a) => +w.getAttribute(a))])""")
    first = [w[1:] for w in walls if w[0] == 0]
    second = [w[1:] for w in walls if w[0] == 1]
    assert first and second

    def off_line(p, w):
        (x1, y1, x2, y2), n = w, math.hypot(w[2] - w[0], w[3] - w[1])
        return abs((x2 - x1) * (y1 - p[1]) - (x1 - p[0]) * (y2 - y1)) / max(n, 1e-9)
    assert min(off_line(p, w) for v in second for p in (v[:2], v[2:]) for w in first) < 0.15
    close(page)


def test_motion_messages_are_drawn(browser, app, shots):
    """Motion, pose and trajectory messages on the page's session keys (published here by a
    peer on the app's bus, as odometry would) reach the page: text and floor map."""
    import schemas
    from services.runtime.bus import wait_alive
    from services.runtime import bus

    page = open_page(browser, app)
    type_camera(page, SIDE_A)
    upload(page, ROOM_A, 0)
    sid = session_of(page)
    zs = bus.open_session(bus.BusConfig(mode="peer", connect=(app.endpoint,)))
    try:
        wait_alive(zs, "gateway", timeout=30)
        yaw = math.radians(PAIR["motion"]["yaw_deg"])
        # two alternatives: twice as far along the same way, and a half turn elsewhere
        alts = [schemas.MotionAlternative(x_m=0.77, z_m=1.186, yaw_rad=yaw, score=30.0),
                schemas.MotionAlternative(x_m=-0.4, z_m=2.0, yaw_rad=yaw + math.pi, score=30.0)]
        m = schemas.Motion(session=sid, index_a=0, index_b=1, x_m=0.385, z_m=0.593, yaw_rad=yaw,
                           sigma_x_m=0.032, sigma_z_m=0.027, sigma_yaw_rad=math.radians(0.71),
                           inliers=40, matches=52, method="test", alternatives=alts)
        t = schemas.Trajectory(session=sid, poses=[schemas.Pose(index=0),
                                                   schemas.Pose(index=1, x_m=0.385, z_m=0.593,
                                                                yaw_rad=yaw)])
        bus.put(zs, bus.key(sid, "motion", 0, 1), schemas.encode(m))
        bus.put(zs, bus.key(sid, "trajectory"), schemas.encode(t))
        line = page.wait_for_selector('.motion-line[data-pair="0-1"]')
        page.wait_for_selector('#floor-map[data-poses="2"]')
    finally:
        zs.close()
    text = line.inner_text()
    # each number with its 1-sigma
    assert "0.39 m ± 0.032 m right" in text and "0.59 m ± 0.027 m ahead" in text, text
    assert "turned 18.0° ± 0.7° left" in text, text
    assert "the photos also allow 1.41 m apart instead of 0.71 m" in text, text
    assert "looks alike from 1 other place" in text, text
    assert "warn" in line.get_attribute("class")
    assert page.locator("#floor-map .cam").count() == 2
    shots(page, "07-motion-and-floor-map", at="#motion")
    close(page)


def _png_header_only(w, h) -> bytes:
    """A valid 1-bit PNG of w x h (tiny file, huge image)."""
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    raw = zlib.compress(b"".join(b"\x00" + bytes((w + 7) // 8) for _ in range(h)), 9)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 1, 0, 0, 0, 0))
            + chunk(b"IDAT", raw) + chunk(b"IEND", b""))


def test_a_large_photo_is_sent_at_1600_px_with_its_intrinsics_scaled(browser, app, tmp_path):
    """A 1920x1440 photo with intrinsics typed for it goes out at 1600x1200 (the page's
    MAX_UPLOAD_SIDE), the intrinsics scaled with it (pixel centres kept), and is measured."""
    import cv2
    big = tmp_path / "big.jpg"
    cv2.imwrite(str(big), cv2.resize(cv2.imread(ROOM_A), (1920, 1440),
                                     interpolation=cv2.INTER_CUBIC), [cv2.IMWRITE_JPEG_QUALITY, 95])
    k = SIDE_A["intrinsics"]
    typed = {"fx": 3 * k["fx"], "fy": 3 * k["fy"], "cx": (k["cx"] + 0.5) * 3 - 0.5,
             "cy": (k["cy"] + 0.5) * 3 - 0.5}
    received = []
    page = open_page(browser, app, received)
    type_camera(page, {**SIDE_A, "intrinsics": typed})
    upload(page, str(big), 0)
    ack = frame_ack(received)
    s = 1600 / 1920
    assert (ack["width"], ack["height"]) == (1600, 1200)
    assert ack["bytes"] < big.stat().st_size
    assert ack["fx"] == pytest.approx(typed["fx"] * s) and ack["fy"] == pytest.approx(typed["fy"] * s)
    assert ack["cx"] == pytest.approx((typed["cx"] + 0.5) * s - 0.5)
    assert ack["cy"] == pytest.approx((typed["cy"] + 0.5) * s - 0.5)
    close(page)


def test_a_photo_files_compass_bearing_survives_the_pages_re_encoding(browser, app, tmp_path):
    """A 12 MP-like photo is re-encoded by the page (EXIF gone); the compass bearing its
    EXIF held (GPSImgDirection 123.4 deg from magnetic north) goes in the upload's header
    and reaches the Frame, as a compass's."""
    import cv2
    from PIL import TiffImagePlugin

    from tests.io.test_imageio import encode, exif_block
    img = cv2.resize(cv2.imread(ROOM_A), (1920, 1440), interpolation=cv2.INTER_CUBIC)
    big = tmp_path / "bearing.jpg"
    big.write_bytes(encode(img[:, :, ::-1], "JPEG", exif_block(
        direction=TiffImagePlugin.IFDRational(1234, 10), direction_ref="M"), quality=90))
    received = []
    page = open_page(browser, app, received)
    upload(page, str(big), 0)
    ack = frame_ack(received)
    assert (ack["width"], ack["height"]) == (1600, 1200)      # re-encoded by the page
    assert ack["heading_deg"] == pytest.approx(123.4) and ack["heading_ref"] == "M"
    close(page)


def test_bad_input_gets_a_message_and_others_are_served(browser, app, shots, tmp_path):
    not_image = tmp_path / "notes.jpg"
    not_image.write_text("this is not a photo\n" * 100)
    huge = tmp_path / "huge.png"
    huge.write_bytes(_png_header_only(10000, 6000))
    too_big = tmp_path / "big.jpg"
    with open(too_big, "wb") as f:
        f.truncate(16 * 1024 * 1024)

    page = open_page(browser, app)
    page.set_input_files("#file-input", str(not_image))
    page.wait_for_selector('.msg.error[data-code="BAD_IMAGE"]')
    assert "not an image" in page.inner_text('.msg.error[data-code="BAD_IMAGE"]')

    page.set_input_files("#file-input", str(huge))
    page.wait_for_selector('.msg.error[data-code="TOO_LARGE"]')
    assert "60 MP, over the 50 MP limit" in page.inner_text('.msg.error[data-code="TOO_LARGE"]')

    page.set_input_files("#file-input", str(too_big))      # refused before sending
    page.wait_for_selector('.msg.error[data-code="TOO_LARGE"] >> text=/takes photos up to/')
    page.wait_for_function("() => !document.body.dataset.busy")
    assert page.locator("#photo-tabs .tab").count() == 0

    upload(page, ROOM_A, 0)                                  # the session still works
    page.locator("#stage").evaluate("e => e.scrollIntoView({block: 'center'})")
    box = page.locator("#stage").bounding_box()
    page.touchscreen.tap(box["x"] + 5, box["y"] + box["height"] - 5)   # the mat, not the photo
    page.wait_for_selector('.msg.warn[data-code="OUTSIDE"]')
    shots(page, "08-phone-bad-input-messages", at="#stage")

    # what a page's own code cannot send, but a forged client could: the server refuses
    page.evaluate("FindMe.send({type: 'measure', id: 7, index: 0, pixels: [[5000, 5000]]})")
    page.wait_for_selector(".msg.error >> text=/outside the 640x480 photo/")
    page.evaluate("FindMe.send({type: 'select', index: 0, rank: 99})")
    page.wait_for_selector('.msg.error[data-code="NO_SUCH_HYPOTHESIS"] >> text=/hypothesis 99 does not exist/')
    page.evaluate("FindMe.send({type: 'measure', id: 8, index: 3, pixels: [[1, 1]]})")
    page.wait_for_selector('.msg.error[data-code="NO_SUCH_FRAME"]')
    page.evaluate("FindMe.send('{not json')")
    page.wait_for_selector('.msg.error[data-code="MALFORMED"]')
    page.evaluate("FindMe.send(new ArrayBuffer(16 * 1024 * 1024 + 65536))")  # over the socket limit
    page.wait_for_selector('#status[data-state="closed"]')
    page.wait_for_selector('.msg.error[data-code="CLOSED"] >> text=/too large/')
    shots(page, "09-phone-connection-closed-after-oversize", at="body")

    # another page, another session: served as if nothing happened
    other = open_page(browser, app, viewport={"width": 1280, "height": 900})
    assert session_of(other) != session_of(page)
    upload(other, ROOM_A, 0)
    tap_pixel(other, 247, 378, touch=False)
    other.wait_for_selector('#points li[data-surface="floor"]')
    shots(other, "10-desktop-second-session-still-served", at="#result")
    assert app.proc.poll() is None
    close(page, other)
