"""Each service's pure handler, driven directly: no bus."""

import io

import numpy as np
import pytest

import schemas
from findme_io.camera_source import hypothesize_photo, with_gravity
from findme_io.convert import msg_camera
from findme_io.imageio import decode_image
from findme_core.errors import HypothesisError, ImageError, InputError
from findme_core.motion.photo_lines import photo_lines
from findme_core.single.methods import hypothesize
from findme_core.single.scene import Scene
from findme.regression.replay import measure_request
from services.pipeline.hypotheses import HypothesesHandler
from services.pipeline.measurement import MeasurementHandler
from services.runtime.authority import KeyAuthorityError
from services.runtime.handler import UnknownSession
from services.pipeline.selection import AutoChooser, SelectionHandler, TerminalChooser
from tests.services.conftest import frame_of


@pytest.fixture(scope="module")
def pipeline(request):
    view = request.getfixturevalue("level_view")
    frame = frame_of(view)
    (out,) = HypothesesHandler().on_message("findme/t1/frame/0", frame)
    (sel,) = SelectionHandler().on_message(out.key, out.msg)
    return view, frame, out.msg, sel.msg


def test_hypotheses_handler_matches_the_core(pipeline):
    """The frame's gravity refined by the photo's lines (``with_gravity``), then the
    hypotheses (``hypothesize_photo``): the core's answer, bit for bit, and the set's camera
    is the one they were built with."""
    view, frame, hset, _ = pipeline
    assert (hset.session, hset.index, hset.width, hset.height) == ("t1", 0, 640, 480)
    assert [h.rank for h in hset.hypotheses] == list(range(1, len(hset.hypotheses) + 1))
    image = decode_image(frame.image.data)       # the very bytes the service decoded
    core, cam, prov = hypothesize_photo(image, *with_gravity(view.camera, image,
                                                             view.camera.gravity))
    assert prov.gravity == hset.camera.gravity_source == "input+image"
    assert np.array_equal(msg_camera(hset.camera).gravity, cam.gravity)
    assert len(hset.hypotheses) == len(core.hypotheses)
    for m, c in zip(hset.hypotheses, core.hypotheses):
        poly, kinds = schemas.msg_to_polyline(m.polyline)
        assert np.array_equal(poly, c.polyline) and np.array_equal(kinds, c.kinds)


def test_hypotheses_of_a_large_photo_come_in_its_own_pixels(pipeline):
    """A 2560x1920 photo (the level view, 4x) is decoded at a quarter (a JPEG reduction:
    640x480, as it would be resized) with its camera scaled; the answer is in the photo's
    pixels: its size and camera, polylines from u = 0 to 2559 about 4x the 640x480
    photo's (their pixel centres: u = (u' + 0.5) * 4 - 0.5), lines too."""
    import cv2
    from findme_io.convert import make_frame, msg_lines
    view, frame, small, _ = pipeline
    c = view.camera.scaled(4.0)
    image = cv2.resize(decode_image(frame.image.data), (2560, 1920), interpolation=cv2.INTER_CUBIC)
    big = make_frame("t1", 1, cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes(),
                     intrinsics=(c.fx, c.fy, c.cx, c.cy, c.width, c.height), gravity=c.gravity,
                     camera_height_m=view.camera_height)
    (out,) = HypothesesHandler().on_message("findme/t1/frame/1", big)
    hset = out.msg
    assert (hset.width, hset.height) == (2560, 1920)
    k = hset.camera.intrinsics
    assert (k.fx, k.fy, k.cx, k.cy, k.width, k.height) == pytest.approx(
        (c.fx, c.fy, c.cx, c.cy, 2560, 1920))
    top, ref = (schemas.msg_to_polyline(h.hypotheses[0].polyline)[0] for h in (hset, small))
    assert top[0, 0] == 0.0 and top[-1, 0] == 2559.0
    rows = np.interp(np.linspace(100, 2400, 24), top[:, 0], top[:, 1])
    want = (np.interp((np.linspace(100, 2400, 24) + 0.5) / 4 - 0.5, ref[:, 0], ref[:, 1]) + 0.5) * 4 - 0.5
    assert np.median(np.abs(rows - want)) < 8.0          # 2 px of the 640x480 photo
    lines = msg_lines(hset)
    assert lines[:, [0, 2]].max() > 640 and lines[:, [1, 3]].max() <= 1919.5


def test_hypotheses_handler_sends_the_photos_lines_once(pipeline, tilted_view):
    """The set carries the whole photo's lines (in the photo's pixels, as ``pair.photo_of``
    hands them to the motion: the CLI and odometry orient the room with the same lines), so
    odometry need not detect them again: with the phone's gravity (refined by them) and with
    gravity estimated from them, the gravity estimate's own detection (the hypotheses then
    took only the part below the horizon)."""
    from findme_core.motion.photo_lines import line_segments
    from findme_io.convert import msg_lines
    view, frame, hset, _ = pipeline
    sent = msg_lines(hset)
    assert sent is not None and len(sent) > 10
    assert np.array_equal(sent, line_segments(decode_image(frame.image.data)))
    blind = frame_of(tilted_view)
    blind.ClearField("gravity")
    (out,) = HypothesesHandler().on_message("findme/t1/frame/0", blind)
    assert out.msg.hypotheses and out.msg.camera.gravity_source == "image"
    assert np.array_equal(msg_lines(out.msg), line_segments(decode_image(blind.image.data)))
    exact = frame_of(view)
    exact.gravity_sigma_rad = 0.0          # exact: taken as it is, the hypotheses' own lines
    (out,) = HypothesesHandler().on_message("findme/t1/frame/0", exact)
    assert out.msg.camera.gravity_source == "input"
    image = decode_image(exact.image.data)
    assert np.array_equal(msg_lines(out.msg), photo_lines(hypothesize(image, view.camera), image))


def test_hypotheses_handler_frame_without_gravity(tilted_view):
    """A frame without gravity: the service estimates it from the image, the hypotheses
    reuse that estimate's segments (photo.hypothesize_without_gravity gives the same), and
    the set's camera says so."""
    from findme_core.single.photo import hypothesize_without_gravity
    frame = frame_of(tilted_view)
    frame.ClearField("gravity")
    (out,) = HypothesesHandler().on_message("findme/t1/frame/0", frame)
    cam = out.msg.camera
    assert cam.gravity_source == "image" and cam.gravity_sigma_rad > 0
    g = schemas.msg_to_vec3(cam.gravity)
    assert np.degrees(np.arccos(np.clip(g @ tilted_view.camera.gravity, -1, 1))) < 0.3
    image = decode_image(frame.image.data)
    c = tilted_view.camera
    from findme_core.geometry.camera import Camera
    core, est = hypothesize_without_gravity(image, Camera(c.fx, c.fy, c.cx, c.cy, c.width, c.height))
    assert np.allclose(g, est.vector)
    for m, h in zip(out.msg.hypotheses, core.hypotheses):
        assert np.array_equal(schemas.msg_to_polyline(m.polyline)[0], h.polyline)


def test_hypotheses_handler_bad_frames(level_view):
    h = HypothesesHandler()
    f = frame_of(level_view)
    with pytest.raises(KeyAuthorityError, match="frame/3 says it belongs on findme/t1/frame/0"):
        h.on_message("findme/t1/frame/3", f)
    f.image.data = b"\xff\xd8\xff" + b"\x00" * 100
    with pytest.raises(ImageError, match="corrupt"):
        h.on_message("findme/t1/frame/0", f)
    g = frame_of(level_view)
    g.intrinsics.width = 320
    with pytest.raises(InputError, match="intrinsics are for 320x480"):
        h.on_message("findme/t1/frame/0", g)


def test_selection_auto_and_terminal(pipeline):
    _, frame, hset, sel = pipeline
    assert (sel.rank, sel.by) == (1, schemas.SELECTED_BY_AUTO)
    out = io.StringIO()
    term = TerminalChooser(out_dir="/tmp", stdin=io.StringIO("x\n99\n2\n"), stdout=out)
    assert term(hset) == 2
    assert "'x' is not a number" in out.getvalue() and "'99' is not a number" in out.getvalue()
    assert AutoChooser()(hset) == 1
    empty = schemas.HypothesisSet(session="t1", index=4, width=640, height=480, reason="blank")
    with pytest.raises(HypothesisError, match="photo 4 has no hypothesis to select: blank"):
        SelectionHandler().on_message("findme/t1/hypotheses/4", empty)


def test_measurement_scene_and_query(pipeline):
    """The scene from the hypotheses and the selection alone: the set carries the camera
    and the frame's height, so the service asks the bus for nothing (no frame)."""
    view, frame, hset, sel = pipeline
    assert hset.frame_height.camera_height_m == frame.camera_height_m
    assert hset.frame_height.HasField("camera_height_sigma_m") == frame.HasField(
        "camera_height_sigma_m")
    m = MeasurementHandler()
    m.fetch = {}.get
    with pytest.raises(InputError, match="takes no Frame"):
        m.on_message("findme/t1/frame/0", frame)
    assert m.on_message("findme/t1/hypotheses/0", hset) == []
    (scene_out,) = m.on_message("findme/t1/selection/0", sel)
    assert scene_out.key == "findme/t1/scene/0" and scene_out.msg.metric
    req = schemas.MeasureRequest(session="t1", index=0)
    req.pixels.extend(schemas.pixels_to_msg([[320, 470], [100, 450], [-3, 0]]))
    rep = m.on_query("findme/t1/measure", req)
    poly, kinds = schemas.msg_to_polyline(hset.hypotheses[0].polyline)
    cam = msg_camera(hset.camera)          # the camera the hypotheses were built with
    truth = Scene(cam, view.camera_height, poly, kinds).locate([[320, 470], [100, 450]])
    for p, t in zip(rep.points, truth):
        assert p.surface == schemas.SURFACE_FLOOR
        assert np.allclose(schemas.msg_to_vec3(p.xyz), t.xyz, atol=1e-4)
    assert "outside" in rep.points[2].error and rep.distances[1].error
    assert rep.distances[0].distance_m == pytest.approx(np.linalg.norm(truth[0].xyz - truth[1].xyz))


def test_measurement_takes_the_surface_said(pipeline):
    """Each pixel's said surface reaches ``Scene.locate`` and comes back in the reply: a
    wall pixel said floor is put on the floor (the floor beyond a cabinet a boundary runs
    along), a floor pixel said wall gets no point, with what to do; nothing said is as
    before; a replay's request, made from the reply, says the same."""
    view, frame, hset, sel = pipeline
    m = MeasurementHandler()
    m.fetch = {}.get
    m.on_message("findme/t1/hypotheses/0", hset)
    m.on_message("findme/t1/selection/0", sel)
    px = [[320, 470], [600, 300], [320, 470], [600, 300]]
    plain = schemas.MeasureRequest(session="t1", index=0, pixels=schemas.pixels_to_msg(px))
    before = m.on_query("findme/t1/measure", plain)
    assert [p.surface for p in before.points] == [schemas.SURFACE_FLOOR, schemas.SURFACE_WALL] * 2
    assert not any(p.said for p in before.points)
    said = [None, "floor", "wall", None]
    req = schemas.MeasureRequest(session="t1", index=0, pixels=schemas.pixels_to_msg(px),
                                 said=schemas.surfaces_to_msg(said))
    rep = m.on_query("findme/t1/measure", req)
    assert [p.said for p in rep.points] == schemas.surfaces_to_msg(said)
    poly, kinds = schemas.msg_to_polyline(hset.hypotheses[0].polyline)
    truth = Scene(msg_camera(hset.camera), view.camera_height, poly, kinds).locate(px, said)
    assert rep.points[1].surface == schemas.SURFACE_FLOOR
    assert np.allclose(schemas.msg_to_vec3(rep.points[1].xyz), truth[1].xyz, atol=1e-4)
    assert not np.allclose(schemas.msg_to_vec3(rep.points[1].xyz),
                           schemas.msg_to_vec3(before.points[1].xyz), atol=0.1)
    assert "floor line runs below it" in rep.points[2].error
    assert rep.points[2].surface == schemas.SURFACE_NONE and not rep.points[2].HasField("xyz")
    for i in (0, 3):
        assert rep.points[i] == before.points[i]
    schemas.decode(schemas.MeasureReply, schemas.encode(rep))   # valid on the bus
    assert schemas.encode(measure_request(rep)) == schemas.encode(req)
    assert schemas.encode(measure_request(before)) == schemas.encode(plain)
    assert m.counters()["measure_queries_said"] == 1


def test_measurement_puts_a_point_said_on_a_top_on_it(box_view):
    """A pixel said to be on a cabinet's top is put on it: its front edge is looked for among
    the lines the hypothesis set came with, which the Scene message carries on, so a service
    that rebuilds the scene from it answers the same. The set's best line here is the one
    along the cabinet's foot (the rendered truth), as a user would choose it."""
    v = box_view
    (out,) = HypothesesHandler().on_message("findme/t1/frame/0", frame_of(v))
    hset = schemas.HypothesisSet()
    hset.CopyFrom(out.msg)
    foot = v.ground_truth_boundary_polyline()
    foot = foot[np.isfinite(foot[:, 1])]
    hset.hypotheses[0].polyline.CopyFrom(schemas.polyline_to_msg(foot, np.zeros(len(foot) - 1,
                                                                                 int)))
    (sel,) = SelectionHandler().on_message("findme/t1/hypotheses/0", hset)
    m = MeasurementHandler()
    m.fetch = {}.get
    m.on_message("findme/t1/hypotheses/0", hset)
    (scene_out,) = m.on_message("findme/t1/selection/0", sel.msg)
    assert list(scene_out.msg.lines) == list(hset.lines)
    px = [[300, 132], [347, 132], [288, 136], [320, 300]]      # on the top x 3, the floor
    req = schemas.MeasureRequest(session="t1", index=0, pixels=schemas.pixels_to_msg(px),
                                 said=schemas.surfaces_to_msg(["top"] * 4))
    rep = m.on_query("findme/t1/measure", req)
    for p, (u, v_) in zip(rep.points[:3], px):
        assert p.surface == schemas.SURFACE_TOP and p.said == schemas.SURFACE_TOP
        err = np.linalg.norm(schemas.msg_to_vec3(p.xyz) - v.points_cam[v_, u])
        assert err < 0.06 and err < 3 * p.sigma_m
    assert "puts the point on the floor" in rep.points[3].error
    schemas.decode(schemas.MeasureReply, schemas.encode(rep))   # valid on the bus
    fresh = MeasurementHandler()
    fresh.fetch = {"findme/t1/scene/0": schemas.encode(scene_out.msg)}.get
    assert schemas.encode(fresh.on_query("findme/t1/measure", req)) == schemas.encode(rep)
    # a scene message without the lines: the edge cannot be looked for, and says so
    bare = schemas.Scene()
    bare.CopyFrom(scene_out.msg)
    bare.ClearField("lines")
    fresh = MeasurementHandler()
    fresh.fetch = {"findme/t1/scene/0": schemas.encode(bare)}.get
    got = fresh.on_query("findme/t1/measure", req)
    assert all("lines did not come" in p.error for p in got.points[:3])


def test_measurement_asks_for_the_frame_when_the_set_lacks_its_height(pipeline):
    """A set from a writer that does not pass the frame's height on (a recording made
    before it did): the frame is asked for, and the scene is the same as from a set that
    carries it; without the frame on the bus the selection is answered with an Error."""
    _, frame, hset, sel = pipeline
    old = schemas.HypothesisSet()
    old.CopyFrom(hset)
    old.ClearField("frame_height")
    scenes = []
    for h, store in ((hset, {}), (old, {"findme/t1/frame/0": schemas.encode(frame)})):
        m = MeasurementHandler()
        m.fetch = store.get
        m.on_message("findme/t1/hypotheses/0", h)
        (out,) = m.on_message("findme/t1/selection/0", sel)
        scenes.append(out.msg)
    assert scenes[0].metric and scenes[0].camera_height_m == frame.camera_height_m
    for s in scenes:
        s.time_ns = 0
    assert schemas.encode(scenes[0]) == schemas.encode(scenes[1])
    m = MeasurementHandler()
    m.fetch = {}.get
    m.on_message("findme/t1/hypotheses/0", old)
    with pytest.raises(HypothesisError, match="frame/0"):
        m.on_message("findme/t1/selection/0", sel)


def test_measurement_rebuilds_a_scene_from_its_scene_message(pipeline):
    """A measurement service that no longer holds a photo (restarted, or the session
    evicted) and finds neither its frame nor its hypotheses on the bus (the store keeps
    frames a minute) answers from the photo's Scene message, exactly as before."""
    _, frame, hset, sel = pipeline
    m = MeasurementHandler()
    m.on_message("findme/t1/hypotheses/0", hset)
    (scene_out,) = m.on_message("findme/t1/selection/0", sel)
    req = schemas.MeasureRequest(session="t1", index=0)
    req.pixels.extend(schemas.pixels_to_msg([[320, 470], [100, 450], [600, 120], [5, 5]]))
    before = m.on_query("findme/t1/measure", req)
    fresh = MeasurementHandler()
    fresh.fetch = {"findme/t1/scene/0": schemas.encode(scene_out.msg)}.get
    after = fresh.on_query("findme/t1/measure", req)
    assert schemas.encode(after) == schemas.encode(before)
    assert fresh.counters()["scenes_rebuilt"] == 1 and fresh.counters()["scenes"] == 0
    # held from now on: the next query asks the bus nothing
    fresh.fetch = {}.get
    assert schemas.encode(fresh.on_query("findme/t1/measure", req)) == schemas.encode(before)


def test_measurement_errors_and_fetch(pipeline):
    _, frame, hset, sel = pipeline
    m = MeasurementHandler()
    req = schemas.MeasureRequest(session="nobody", index=0)
    req.pixels.extend(schemas.pixels_to_msg([[1, 1]]))
    with pytest.raises(UnknownSession, match="'nobody' is not known"):
        m.on_query("findme/nobody/measure", req)
    # a selection first: the handler fetches the hypotheses it missed from the bus
    store = {"findme/t1/hypotheses/0": schemas.encode(hset)}
    m.fetch = store.get
    (out,) = m.on_message("findme/t1/selection/0", sel)
    assert out.key == "findme/t1/scene/0"
    bad = schemas.Selection(session="t1", index=0, rank=99, by=schemas.SELECTED_BY_USER)
    with pytest.raises(HypothesisError, match="hypothesis 99 of photo 0"):
        m.on_message("findme/t1/selection/0", bad)
    # nobody has them: the selection waits (they may still be on their way: the bus does
    # not order it after them), then is answered with an Error naming it
    now = [100.0]
    m2 = MeasurementHandler(wait_s=5.0, clock=lambda: now[0])
    m2.fetch = {}.get
    assert m2.on_message("findme/t1/selection/0", sel) == []
    assert m2.tick(104.0) == []
    (err,) = m2.tick(105.5)
    assert err.key == "findme/t1/error" and err.msg.key == "findme/t1/selection/0"
    assert "did not come within 5 s" in err.msg.message
    m3 = MeasurementHandler(clock=lambda: now[0])      # ... or they come: the scene follows
    m3.fetch = {}.get
    assert m3.on_message("findme/t1/selection/0", sel) == []
    (out,) = m3.on_message("findme/t1/hypotheses/0", hset)
    assert out.key == "findme/t1/scene/0"
