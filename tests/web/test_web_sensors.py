"""The page's phone sensors in headless Chromium with sensor emulation (CDP
``Emulation.setSensorOverrideEnabled`` / ``setSensorOverrideReadings``, Chromium 122+):
the DeviceMotion (accelerometer) and DeviceOrientation readings of a phone held in portrait
or landscape reach the server as gravity in camera axes within 1 deg, and the page says
where each photo's gravity came from.

Chromium rounds sensor readings (0.1 m/s^2, 0.1 deg), hence the 1 deg tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.web.conftest import CHROMIUM, CHROMIUM_ARGS
from tests.web.test_web_app import PHONE, ROOM_A, close, open_page

pytestmark = pytest.mark.timeout(120)
G = 9.81
SENSOR_PERMISSIONS = ["accelerometer", "gyroscope", "magnetometer"]


def camera_gravity(pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Gravity in OpenCV camera axes of a camera pitched down and rolled right."""
    p, r = math.radians(pitch_deg), math.radians(roll_deg)
    return np.array([math.cos(p) * math.sin(r), math.cos(p) * math.cos(r), math.sin(p)])


def device_gravity(g_cam: np.ndarray, theta_deg: float) -> np.ndarray:
    """Inverse of the page's deviceToCamera (settings.js header): the device-frame gravity of a
    phone whose upright photo is the device turned counter-clockwise by theta."""
    t = math.radians(theta_deg)
    r, d = np.array([math.cos(t), -math.sin(t)]), np.array([-math.sin(t), -math.cos(t)])
    xy = g_cam[0] * r + g_cam[1] * d
    return np.array([xy[0], xy[1], -g_cam[2]])


def orientation_quaternion(g_dev: np.ndarray) -> dict:
    """A device orientation (quaternion, device -> earth) whose gravity is ``g_dev``: the
    rotation taking the device's down vector g_dev to the earth's down (0, 0, -1)."""
    a = g_dev / np.linalg.norm(g_dev)
    b = np.array([0.0, 0.0, -1.0])
    axis = np.cross(a, b)
    s = np.linalg.norm(axis)
    ang = math.atan2(s, float(a @ b))
    axis = axis / s if s > 1e-12 else np.array([1.0, 0.0, 0.0])
    x, y, z = axis * math.sin(ang / 2)
    return {"x": float(x), "y": float(y), "z": float(z), "w": math.cos(ang / 2)}


def emulate(page, context, g_dev: np.ndarray, orientation: bool):
    cdp = context.new_cdp_session(page)
    types = ["accelerometer", "linear-acceleration", "gyroscope"]
    if orientation:
        types.append("relative-orientation")
    for t in types:
        cdp.send("Emulation.setSensorOverrideEnabled", {"enabled": True, "type": t})
    a = -G * g_dev                          # accelerationIncludingGravity: the reaction
    cdp.send("Emulation.setSensorOverrideReadings", {
        "type": "accelerometer", "reading": {"xyz": {"x": a[0], "y": a[1], "z": a[2]}}})
    for t in ("linear-acceleration", "gyroscope"):
        cdp.send("Emulation.setSensorOverrideReadings",
                 {"type": t, "reading": {"xyz": {"x": 0, "y": 0, "z": 0}}})
    if orientation:
        cdp.send("Emulation.setSensorOverrideReadings", {
            "type": "relative-orientation", "reading": {"quaternion": orientation_quaternion(g_dev)}})
    return cdp


def open_sensing_page(browser, app, g_dev, orientation, **ctx):
    """A phone page whose sensors report ``g_dev`` (overrides set before the page loads:
    Chromium binds a page's sensors when it starts listening)."""
    context = browser.new_context(**(ctx or PHONE))
    context.grant_permissions(SENSOR_PERMISSIONS)     # what a phone's browser grants the page
    page = context.new_page()
    page.js_errors = []
    page.on("pageerror", lambda e: page.js_errors.append(str(e)))
    cdp = emulate(page, context, g_dev, orientation)
    page.goto(app.url)
    page.wait_for_selector('#status[data-state="connected"]')
    return page, cdp


def turn_on_sensors(page):
    """Tap "Turn on motion sensors" (Chromium asks, like iOS: DeviceMotionEvent.
    requestPermission; the context has granted it) and wait for a reading."""
    if not page.evaluate("document.getElementById('settings').open"):
        page.click("#settings summary")
    page.click("#sensors-btn")
    page.wait_for_function("() => FindMe.currentGravity() !== null")


def angle_deg(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.acos(float(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


@pytest.mark.parametrize("theta,pitch,roll,orientation", [
    (0, 28.0, 3.0, False),       # portrait, DeviceMotion only
    (0, 35.0, -6.0, True),       # portrait, DeviceOrientation preferred
    (90, 22.0, 4.0, False),      # landscape, phone turned left
    (270, 18.0, -2.0, True),     # landscape, phone turned right
])
def test_phone_tilt_reaches_the_server_in_camera_axes(browser, app, theta, pitch, roll, orientation):
    g_cam = camera_gravity(pitch, roll)
    page, _ = open_sensing_page(browser, app, device_gravity(g_cam, theta), orientation)
    turn_on_sensors(page)
    sources = set(page.evaluate("FindMe.state.sensors.samples.map(s => s.source)"))
    assert ("orientation" in sources) == orientation      # the page prefers orientation
    assert page.evaluate("FindMe.rotation()") == theta      # automatic, from gravity
    page.click("#tilt-btn")                                  # "Use phone tilt now"
    page.fill("#height", "1.42")
    page.set_input_files("#file-input", ROOM_A)
    page.wait_for_selector('#frame[data-index="0"][data-scene-rank="1"]')
    got = page.evaluate("FindMe.state.photos[0].serverGravity")   # what the gateway took
    err = angle_deg(got, g_cam)
    print(f"theta {theta}, pitch {pitch}, roll {roll} ({sources}): server {np.round(got, 4)}, "
          f"true {np.round(g_cam, 4)}, {err:.2f} deg")
    assert err < 1.0
    assert page.get_attribute("#sources", "data-gravity-source") == "sensors"
    assert "motion sensors" in page.inner_text("#sources")
    # the page sends a sensor reading with 1.5 deg. These made-up tilts are not the example
    # photo's own (its lines put gravity ~6 deg away, at the edge of the window searched):
    # kept, it carries the page's 1.5 deg; refined, the server says so
    cam = page.evaluate("FindMe.state.photos[0].camera")
    assert cam["gravity_source"] in ("input", "input+image"), str(cam)
    if cam["gravity_source"] == "input":
        assert cam["gravity_sigma_deg"] == pytest.approx(1.5), str(cam)
    close(page)


def test_without_sensors_the_photo_tells_gravity(browser, app):
    """No reading, fields empty: the server estimates gravity from the photo and the page
    says so (the bundled example is a tilted phone photo with many lines)."""
    page = open_page(browser, app)
    page.set_input_files("#file-input", ROOM_A)
    page.wait_for_selector('#frame[data-index="0"][data-scene-rank="1"]')
    assert page.get_attribute("#sources", "data-gravity-source") == "image"
    assert page.get_attribute("#sources", "data-lens-source") == "default"
    assert "estimated from the photo" in page.inner_text("#sources")
    assert page.locator('.msg[data-code="LEVEL"]').count() == 0
    close(page)


def test_a_blank_photo_warns_that_level_is_assumed(browser, app, tmp_path):
    import cv2
    img = np.full((480, 640, 3), 190, np.uint8)
    cv2.line(img, (0, 300), (639, 330), (60, 60, 60), 4)       # one line: cannot tell
    f = tmp_path / "wall.png"
    cv2.imwrite(str(f), img)
    page = open_page(browser, app)
    page.set_input_files("#file-input", str(f))
    page.wait_for_selector('.msg[data-code="LEVEL"]')
    assert page.get_attribute("#sources", "data-gravity-source") == "level"
    assert "level assumed" in page.inner_text("#sources")
    close(page)


def test_live_camera_in_landscape_uses_the_screen_angle(browser, app):
    """The live camera's preview is upright for the screen: with the screen turned to
    landscape (screen orientation emulation, angle 90) the capture's gravity is converted
    with theta = 90 and reaches the server within 1 deg."""
    g_cam = camera_gravity(24.0, 2.0)
    if True:   # a second browser with a fake camera, from the fixture's Playwright
        b = browser.browser_type.launch(executable_path=CHROMIUM, headless=True,
                                        args=CHROMIUM_ARGS + ["--use-fake-device-for-media-stream",
                                                              "--use-fake-ui-for-media-stream"])
        try:
            context = b.new_context(**PHONE)
            context.grant_permissions(["camera", *SENSOR_PERMISSIONS])
            page = context.new_page()
            page.js_errors = []
            page.on("pageerror", lambda e: page.js_errors.append(str(e)))
            cdp = emulate(page, context, device_gravity(g_cam, 90), False)
            cdp.send("Emulation.setDeviceMetricsOverride", {
                "width": 844, "height": 390, "deviceScaleFactor": 3, "mobile": True,
                "screenOrientation": {"type": "landscapePrimary", "angle": 90}})
            page.goto(app.url)
            page.wait_for_selector('#status[data-state="connected"]')
            assert page.evaluate("screen.orientation.angle") == 90
            turn_on_sensors(page)
            page.click("#live-btn")
            page.wait_for_function("() => document.getElementById('live-video').videoWidth > 0")
            page.click("#shutter-btn")
            page.wait_for_selector('#frame[data-index="0"]')
            page.wait_for_function("() => FindMe.state.photos.length && FindMe.state.photos[0].serverGravity")
            got = page.evaluate("FindMe.state.photos[0].serverGravity")
            assert angle_deg(got, g_cam) < 1.0, (got, g_cam.tolist())
            assert page.evaluate("FindMe.state.photos[0].gravitySent") == "sensors"
            assert not page.js_errors
        finally:
            b.close()


def orientation_from_angles(alpha: float, beta: float, gamma: float) -> dict:
    """The quaternion (device -> earth) of W3C DeviceOrientation angles, degrees:
    R = Rz(alpha) Rx(beta) Ry(gamma)."""
    a, b, g = (math.radians(x) / 2 for x in (alpha, beta, gamma))
    qz = np.array([math.cos(a), 0, 0, math.sin(a)])      # (w, x, y, z)
    qx = np.array([math.cos(b), math.sin(b), 0, 0])
    qy = np.array([math.cos(g), 0, math.sin(g), 0])

    def mul(p, q):
        w1, x1, y1, z1 = p
        w2, x2, y2, z2 = q
        return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                         w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                         w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                         w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])
    w, x, y, z = mul(mul(qz, qx), qy)
    return {"x": float(x), "y": float(y), "z": float(z), "w": float(w)}


def test_turning_right_grows_the_heading_the_page_reads(browser, app):
    """The heading the page would send with a live capture (``currentHeading``, from the
    orientation sensor's alpha, beta, gamma): a phone held upright, tilted down 25 deg, turned
    right by 40 deg about gravity, reads 40 deg more (the plan's yaw convention, whatever
    alpha's zero); looking straight down there is no heading to read."""
    page, cdp = open_sensing_page(browser, app, device_gravity(camera_gravity(25.0, 0.0), 0),
                                  True)

    def read(alpha, beta, gamma):
        cdp.send("Emulation.setSensorOverrideReadings", {
            "type": "relative-orientation",
            "reading": {"quaternion": orientation_from_angles(alpha, beta, gamma)}})
        page.wait_for_function(   # the reading of these angles has arrived
            "(w) => { const a = FindMe.state.sensors.angles; return a && a.every("
            "(x, i) => Math.abs(((x - w[i]) % 360 + 540) % 360 - 180) < 0.5); }",
            arg=[alpha % 360.0, beta, gamma])
        return page.evaluate("FindMe.currentHeading()")

    turn_on_sensors(page)
    h1 = read(30.0, 65.0, 0.0)
    h2 = read(30.0 - 40.0, 65.0, 0.0)      # alpha grows counter-clockwise seen from above
    assert abs((h2 - h1 + 180) % 360 - 180 - 40.0) < 1.0, (h1, h2)
    assert page.evaluate("FindMe.cameraHeading(30, 0.5, 0)") is None   # flat: looking down
    assert not page.js_errors
    close(page)


def test_a_compass_heading_is_sent_as_a_compass_s(browser, app):
    """A browser whose deviceorientation alpha follows the compass (``absolute: true``,
    e.g. Firefox on Android) is sent as a compass's heading (reference "?", +-30 deg, as a
    photo file's bearing), a gyroscope's relative alpha as the page's own (+-5 deg): a
    compass near steel may be off by a quarter turn, which a 5-deg heading would rule in."""
    context = browser.new_context(**PHONE)
    context.grant_permissions(SENSOR_PERMISSIONS)
    page = context.new_page()
    page.js_errors = []
    page.on("pageerror", lambda e: page.js_errors.append(str(e)))
    page.goto(app.url)
    page.wait_for_selector('#status[data-state="connected"]')
    if not page.evaluate("document.getElementById('settings').open"):
        page.click("#settings summary")
    page.click("#sensors-btn")
    page.wait_for_function("() => FindMe.state.sensors.on")

    def fields(absolute):
        # this headless page has no sensors of its own: the event is the only reading
        page.evaluate("(a) => window.dispatchEvent(new DeviceOrientationEvent("
                      "'deviceorientation', {alpha: 30, beta: 65, gamma: 0, absolute: a}))",
                      absolute)
        return page.evaluate("FindMe.currentHeadingFields()")
    compass, gyro = fields(True), fields(False)
    assert compass["heading_ref"] == "?" and compass["heading_sigma_deg"] == 30
    assert "heading_ref" not in gyro and gyro["heading_sigma_deg"] == 5
    assert compass["heading_deg"] == pytest.approx(gyro["heading_deg"])
    close(page)
