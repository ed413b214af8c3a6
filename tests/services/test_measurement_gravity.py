"""The measurement service under the gravity a motion agreed on, driven directly (no bus).

Two photos of the test suite's rendered room, turning 45 deg at one spot, 30 deg down, sent
WITHOUT gravity (a camera app's photos), through the real hypotheses, selection, odometry
and measurement handlers. Photo 1's lines alone leave its gravity tens of degrees off (it
says so: a wide sigma); the odometry's motion agrees the two photos' gravities through their
matches, and from then on photo 1's points are located under the agreed gravity.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import zenoh

import schemas
from findme_core.single import gravity_alternatives as alt
from findme_core.synth.raycast import FLOOR
from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room
from findme_io.convert import make_frame
from findme_io.motion_msg import msg_agreed_gravities
from services.pipeline.hypotheses import HypothesesHandler
from services.pipeline.measurement import MeasurementHandler
from services.pipeline.odometry import OdometryHandler
from services.pipeline.selection import SelectionHandler

S = "meas"


@pytest.fixture(scope="module")
def session():
    """(views, messages of each photo in bus order, the motion 0 -> 1)."""
    hyp, sel, odo = HypothesesHandler(), SelectionHandler(), OdometryHandler()
    frames = {}
    odo.fetch = frames.get                         # it asks the bus (the store) for frames
    views, photos, motion = [], [], None
    for n, yaw in enumerate((135.0, 180.0)):        # photo 1 (yaw 180) is 52 deg off alone
        v = render(Room.rectangle(5.0, 4.0), Pose(0.3, -0.2, 1.4, yaw, 30.0, 0.0), 640, 480,
                   hfov_deg=70.0, supersample=1)
        data = cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()
        msgs = [(f"findme/{S}/frame/{n}", make_frame(S, n, data, hfov_deg=70.0,
                                                     camera_height_m=1.4))]
        hs = next(o for o in hyp.on_message(*msgs[0]) if isinstance(o.msg, schemas.HypothesisSet))
        msgs += [(hs.key, hs.msg)] + [(o.key, o.msg) for o in sel.on_message(hs.key, hs.msg)]
        frames[msgs[0][0]] = schemas.encode(msgs[0][1])
        for o in _deliver(odo, msgs):
            if o.key == f"findme/{S}/motion/0/1":
                motion = o.msg
        views.append(v)
        photos.append(msgs)
    return views, photos, motion


def _floor_pixels(v, n=40):
    """(n, 2) pixel centres on the floor (every k-th of them) and their true camera-frame
    points (n, 3), metres."""
    vv, uu = np.nonzero(v.labels == FLOOR)
    k = np.linspace(0, len(vv) - 1, n).astype(int)
    return np.column_stack([uu[k], vv[k]]).astype(float), v.points_cam[vv[k], uu[k]].astype(float)


def _handler(photos, store=True):
    """A measurement handler whose bus (``need``) holds the session's messages, as the store
    does (``store``), or nothing."""
    h = MeasurementHandler()
    held = {key: schemas.encode(msg) for msgs in photos for key, msg in msgs}
    h.fetch = held.get if store else {}.get
    return h


def _deliver(h, msgs) -> list:
    """The outputs of ``h`` for what the bus hands it of ``msgs`` ((key, message), ...): the
    messages on its inputs' keys (no frames: the hypotheses carry what it needs of them)."""
    subs = [zenoh.KeyExpr(i.key) for i in h.inputs]
    return [o for key, msg in msgs if any(s.intersects(zenoh.KeyExpr(key)) for s in subs)
            for o in h.on_message(key, msg)]


def _boundary_error_px(v, polyline) -> float:
    """Median |v - true boundary row| (pixels) of a boundary over the columns where the
    photo sees floor."""
    poly, _ = schemas.msg_to_polyline(polyline)
    us = [u for u, b in enumerate(v.boundary_v) if b is not None]
    return float(np.median([abs(np.interp(u, poly[:, 0], poly[:, 1]) - v.boundary_v[u])
                            for u in us]))


def _measure(h, n, px):
    req = schemas.MeasureRequest(session=S, index=n,
                                 pixels=[schemas.Pixel(u=u, v=v) for u, v in px])
    rep = h.on_query(f"findme/{S}/measure", req)
    xyz = np.array([schemas.msg_to_vec3(p.xyz) if not p.error else [np.nan] * 3
                    for p in rep.points])
    return xyz, np.array([p.sigma_m if not p.error else np.inf for p in rep.points])


def test_a_photo_completed_by_a_motion_is_measured_under_the_agreed_gravity(session):
    views, photos, motion = session
    h = _handler(photos)
    scenes = _deliver(h, [m for msgs in photos for m in msgs])
    assert [o.key for o in scenes] == [f"findme/{S}/scene/0", f"findme/{S}/scene/1"]
    own = schemas.msg_to_vec3(scenes[1].msg.camera.gravity)
    assert alt.angle_deg(own, views[1].camera.gravity) > 10.0          # the case is real
    assert math.degrees(scenes[1].msg.camera.gravity_sigma_rad) > 10.0  # and said
    px, truth = _floor_pixels(views[1])
    before, sigma_before = _measure(h, 1, px)

    # the motion agreed the photos' gravities: photo 1's scene is built again under it
    assert motion is not None and not motion.error and motion.gravity.status == "agreed"
    (which, g, sigma), = [a for a in msg_agreed_gravities(motion) if a[0] == "b"]
    assert alt.angle_deg(g, views[1].camera.gravity) < 1.0
    (out,) = h.on_message(f"findme/{S}/motion/0/1", motion)
    assert out.key == f"findme/{S}/scene/1"
    cam = out.msg.camera
    assert alt.angle_deg(schemas.msg_to_vec3(cam.gravity), views[1].camera.gravity) < 1.0
    assert cam.gravity_source == "image" and cam.gravity_sigma_rad == pytest.approx(sigma)
    # chosen automatically under the wrong gravity, the boundary is found again under it
    old = _boundary_error_px(views[1], scenes[1].msg.polyline)
    new = _boundary_error_px(views[1], out.msg.polyline)
    assert new < 3.0 < old, (new, old)
    after, sigma_after = _measure(h, 1, px)
    err_before = np.linalg.norm(before - truth, axis=1)
    err_after = np.linalg.norm(after - truth, axis=1)
    # before: under its own gravity (+- 25 deg) a floor point's 1-sigma is too large to
    # answer, or the answer is wide enough to hold the truth; after: answered, right
    said = np.isfinite(sigma_before)
    assert np.mean(said) < 0.5 and np.all(err_before[said] <= 3 * sigma_before[said])
    assert np.isfinite(sigma_after).all() and np.median(err_after) < 0.05
    assert np.median(sigma_after) < 0.15
    assert np.mean(err_after <= 3 * sigma_after) >= 0.95      # its sigmas hold
    assert h.counters()["scenes_regravitated"] == 1

    # photo 0 kept its own (it was sure); the same motion again changes nothing
    assert h.on_message(f"findme/{S}/motion/0/1", motion) == []


def test_an_agreed_gravity_that_comes_before_the_selection_is_used_when_it_comes(session):
    views, photos, motion = session
    h = _handler(photos)
    _deliver(h, photos[0] + photos[1][:2])              # photo 1's selection not yet
    assert h.on_message(f"findme/{S}/motion/0/1", motion) == []
    (out,) = h.on_message(*photos[1][2])
    assert alt.angle_deg(schemas.msg_to_vec3(out.msg.camera.gravity),
                         views[1].camera.gravity) < 1.0


def test_a_users_boundary_is_kept_and_lifted_under_the_agreed_gravity(session):
    views, photos, motion = session
    h = _handler(photos, store=False)          # the frame is not needed
    user = schemas.Selection(session=S, index=1, rank=1, by=schemas.SELECTED_BY_USER)
    msgs = photos[0] + photos[1][:2] + [(f"findme/{S}/selection/1", user)]
    (first,) = _deliver(h, msgs)[1:]
    (out,) = h.on_message(f"findme/{S}/motion/0/1", motion)
    assert alt.angle_deg(schemas.msg_to_vec3(out.msg.camera.gravity),
                         views[1].camera.gravity) < 1.0
    np.testing.assert_array_equal(schemas.msg_to_polyline(out.msg.polyline)[0],
                                  schemas.msg_to_polyline(first.msg.polyline)[0])


def test_without_its_frame_an_automatic_choice_stays_under_its_own_gravity(session):
    views, photos, motion = session
    h = _handler(photos, store=False)          # the frame has left the bus
    _deliver(h, photos[0] + photos[1])
    assert h.on_message(f"findme/{S}/motion/0/1", motion) == []
    c = h.counters()
    assert (c["scenes_regravitated"], c["scenes_not_regravitated"]) == (0, 1)


def test_a_sensor_gravity_is_never_replaced_by_a_motion(session):
    views, photos, motion = session
    h = _handler(photos)
    g = views[1].camera.gravity
    sensed = schemas.Frame()
    sensed.CopyFrom(photos[1][0][1])
    sensed.gravity.CopyFrom(schemas.vec3_to_msg(g))   # a phone's own gravity, given
    hs = next(o.msg for o in HypothesesHandler().on_message(photos[1][0][0], sensed)
              if isinstance(o.msg, schemas.HypothesisSet))
    _deliver(h, [(photos[1][0][0], sensed), (photos[1][1][0], hs), photos[1][2]])
    fake = schemas.Motion()
    fake.CopyFrom(motion)
    fake.gravity.gravity_b.CopyFrom(schemas.vec3_to_msg(alt.down(np.array([0.0, 1.0, 0.3]))))
    fake.gravity.sigma_b_rad = 1e-4
    assert h.on_message(f"findme/{S}/motion/0/1", fake) == []
    assert h.counters()["scenes_regravitated"] == 0
