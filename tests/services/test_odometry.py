"""The odometry handler, driven directly: motion between selected photos, chaining, order."""

import math

import numpy as np
import pytest

import schemas
from findme_core.single.search import SegKind
from findme_core.synth.render import Pose, Room, planar_motion, render
from services.pipeline.hypotheses import HypothesesHandler
from findme_io.motion_msg import motion_text, set_motion_estimate
from services.pipeline.odometry import OdometryHandler
from services.web.page_output import to_page
from tests.services.conftest import frame_of


@pytest.fixture(scope="module")
def photos():
    """Three photos of one room walking forward and turning, with their true poses."""
    room = Room.rectangle(5.0, 6.0, floor_style="wood")
    poses = [Pose(-0.3, -1.8, 1.4, yaw_deg=10, pitch_deg=28), Pose(0.0, -1.3, 1.4, yaw_deg=-2, pitch_deg=26),
             Pose(0.3, -0.9, 1.4, yaw_deg=-15, pitch_deg=27)]
    views = [render(room, p, 640, 480, hfov_deg=70, seed=5) for p in poses]
    msgs = []
    for n, v in enumerate(views):
        f = frame_of(v, "od", n)
        (h,) = HypothesesHandler().on_message(f"findme/od/frame/{n}", f)
        msgs.append((f, h.msg, schemas.Selection(session="od", index=n, rank=1,
                                                 by=schemas.SELECTED_BY_AUTO)))
    return poses, msgs


def on_bus(handler, msgs):
    """``handler`` fetching the photos' frames from a bus that holds them (as the store
    does); the keys it asked for are in ``handler.asked``."""
    held = {f"findme/od/frame/{n}": schemas.encode(f) for n, (f, _, _) in enumerate(msgs)}
    handler.asked = []
    handler.fetch = lambda key: handler.asked.append(key) or held.get(key)
    return handler


def feed(handler, msgs, order):
    """Outputs of ``handler`` (odometry) for the photos' hypotheses, then their selections
    in ``order``; frames only on the bus, as the service takes in none."""
    out = []
    if handler.fetch is None:
        on_bus(handler, msgs)
    for n, (f, h, _) in enumerate(msgs):
        handler.on_message(f"findme/od/hypotheses/{n}", h)
    for n in order:
        out += handler.on_message(f"findme/od/selection/{n}", msgs[n][2])
    return {o.key: o.msg for o in out}


def test_motion_and_trajectory_match_the_truth(photos):
    poses, msgs = photos
    out = feed(OdometryHandler(), msgs, [0, 1, 2])
    for a, b in ((0, 1), (1, 2)):
        m = out[f"findme/od/motion/{a}/{b}"]
        x, z, yaw = planar_motion(poses[a], poses[b])
        assert not m.error and m.inliers > 20
        assert math.hypot(m.x_m - x, m.z_m - z) < 0.05
        assert abs(math.degrees(m.yaw_rad) - yaw) < 1.0
    traj = out["findme/od/trajectory"]
    assert [p.index for p in traj.poses] == [0, 1, 2]
    x, z, yaw = planar_motion(poses[0], poses[2])   # chained pose of photo 2 vs the truth
    p2 = out["findme/od/pose/2"]
    assert math.hypot(p2.x_m - x, p2.z_m - z) < 0.08 and abs(math.degrees(p2.yaw_rad) - yaw) < 1.5
    assert p2.sigma_x_m > out["findme/od/pose/1"].sigma_x_m > 0   # uncertainty grows


def test_large_photos_move_as_their_reduced_decode_does(photos):
    """The same walk in 1280x960 photos: odometry decodes each at half (a JPEG reduction)
    and scales the hypotheses' camera, boundary and lines to it; the motion (metres) is
    the truth's as with 640x480 photos."""
    poses, _ = photos
    room = Room.rectangle(5.0, 6.0, floor_style="wood")
    msgs = []
    for n, p in enumerate(poses):
        f = frame_of(render(room, p, 1280, 960, hfov_deg=70, seed=5), "od", n)
        (h,) = HypothesesHandler().on_message(f"findme/od/frame/{n}", f)
        assert (h.msg.width, h.msg.height) == (1280, 960)
        msgs.append((f, h.msg, schemas.Selection(session="od", index=n, rank=1,
                                                 by=schemas.SELECTED_BY_AUTO)))
    out = feed(OdometryHandler(), msgs, [0, 1, 2])
    for a, b in ((0, 1), (1, 2)):
        m = out[f"findme/od/motion/{a}/{b}"]
        x, z, yaw = planar_motion(poses[a], poses[b])
        assert not m.error and m.inliers > 20
        assert math.hypot(m.x_m - x, m.z_m - z) < 0.05
        assert abs(math.degrees(m.yaw_rad) - yaw) < 1.0


def test_selections_out_of_order_wait_for_their_predecessor(photos):
    _, msgs = photos
    h = OdometryHandler()
    early = feed(h, msgs, [0, 2])          # photo 1 not selected yet: 2 must wait
    assert "findme/od/motion/0/2" not in early and "findme/od/pose/2" not in early
    late = {o.key: o.msg for o in h.on_message("findme/od/selection/1", msgs[1][2])}
    assert {"findme/od/motion/0/1", "findme/od/motion/1/2", "findme/od/pose/2"} <= set(late)


def test_the_first_photo_is_the_origin_whatever_the_order(photos):
    _, msgs = photos
    h = OdometryHandler()
    assert feed(h, msgs, [2, 1]) == {}                  # photo 0 known, not selected: wait
    out = {o.key: o.msg for o in h.on_message("findme/od/selection/0", msgs[0][2])}
    p0 = out["findme/od/pose/0"]
    assert (p0.x_m, p0.z_m, p0.yaw_rad) == (0.0, 0.0, 0.0)
    assert [p.index for p in out["findme/od/trajectory"].poses] == [0, 1, 2]


def unmatchable(msgs):
    """The photos with photo 1 blank and all floor: no feature and no wall in common with
    any other photo, so its motions fail."""
    blank = schemas.Frame()
    blank.CopyFrom(msgs[1][0])
    import cv2
    blank.image.data = cv2.imencode(".jpg", np.full((480, 640, 3), 128, np.uint8))[1].tobytes()
    floor_only = schemas.HypothesisSet()
    floor_only.CopyFrom(msgs[1][1])
    floor_only.hypotheses[0].polyline.CopyFrom(
        schemas.polyline_to_msg([[0.0, -0.5], [639.0, -0.5]], [SegKind.OPEN]))
    return [msgs[0], (blank, floor_only, msgs[1][2]), msgs[2]]


def test_a_failed_motion_carries_its_error_and_the_chain_goes_on(photos):
    _, msgs = photos
    out = feed(OdometryHandler(), unmatchable(msgs), [0, 1, 2])
    m01 = out["findme/od/motion/0/1"]
    assert m01.error and not m01.HasField("x_m") and "findme/od/pose/1" not in out
    assert not out["findme/od/motion/0/2"].error          # photo 2 chains from photo 0
    assert [p.index for p in out["findme/od/trajectory"].poses] == [0, 2]


def test_after_instances_change_a_session_takes_the_poses_another_instance_made(photos):
    """Sharded by session: while this instance was cut off, another one posed photo 2; when
    the instances change, the session takes the poses on the bus before going on."""
    _, msgs = photos
    h = OdometryHandler()
    out = feed(h, msgs[:2], [0, 1])
    theirs = schemas.Pose(session="od", index=2, x_m=0.5, z_m=0.9, yaw_rad=-0.4, sigma_x_m=0.01,
                          sigma_z_m=0.01, sigma_yaw_rad=0.01)
    bus_poses = [("findme/od/pose/0", schemas.encode(out["findme/od/pose/0"])),
                 ("findme/od/pose/2", schemas.encode(theirs))]
    h.fetch_all = lambda pattern: bus_poses if pattern == "findme/od/pose/*" else []
    h.peers_changed()
    assert h.on_message("findme/od/hypotheses/2", msgs[2][1]) == []  # posed already: nothing to do
    st = h.sessions.peek("od")
    assert sorted(st.poses) == [0, 1, 2] and st.poses[2].x == 0.5 and not st.stale
    assert st.poses[1].x == out["findme/od/pose/1"].x_m                # its own are kept


def test_each_photo_is_prepared_once_for_all_its_motions(photos, monkeypatch):
    """Photo 1 takes part in motions 0/1 and 1/2: its features and layouts are computed once."""
    import services.pipeline.odometry as od
    calls = []
    real = od.prepare
    monkeypatch.setattr(od, "prepare", lambda *a, **k: calls.append(a[3]) or real(*a, **k))
    _, msgs = photos
    out = feed(OdometryHandler(), msgs, [0, 1, 2])
    assert not out["findme/od/motion/1/2"].error
    assert len(calls) == 3


def test_the_motion_on_the_bus_carries_its_evidence(photos):
    poses, msgs = photos
    m = feed(OdometryHandler(), msgs, [0, 1])["findme/od/motion/0/1"]
    m = schemas.decode(schemas.Motion, schemas.encode(m))     # both validate
    # both photos see the rectangle's walls: their layouts' agreement is the evidence
    assert m.HasField("layout") and m.layout.samples > 20 and len(m.layout.walls) >= 1
    assert m.layout.rank_a == m.layout.rank_b == 1 and m.layout.rms_m < 0.1
    assert m.HasField("score") and m.score > 0 and m.scale_points > 0
    # the photos' appearance on each other's walls and floor agrees (textured rendered room)
    assert m.appearance_samples > 0 and 0.2 < m.appearance <= 1.0
    page = to_page("od", m)
    assert page["layout"]["walls"] == len(m.layout.walls) and page["scale_points"] > 0


def test_a_symmetric_room_reaches_the_page_as_alternatives():
    """A square room seen as in tests/core/motion/test_register.py: two motions a quarter turn
    apart fit equally; the bus message carries both, each with its evidence."""
    from tests.core.layout_rooms import exact_orientation, no_matches, view_layout
    from findme_core.motion.methods import estimate
    pa, pb = Pose(0.0, -1.5, 1.45, 0.0, 25.0), Pose(1.2, 1.0, 1.45, 45.0, 30.0)
    square = Room.rectangle(5.0, 5.0)
    (va, la), (vb, lb) = view_layout(square, pa), view_layout(square, pb)
    mo = estimate(no_matches(), va.camera, vb.camera, 1.45, 1.45, None, None,
                  layouts=([la], [lb]), orientations=(exact_orientation(pa), exact_orientation(pb)))
    assert mo.alternatives
    m = set_motion_estimate(schemas.Motion(session="od", index_a=0, index_b=1), mo)
    m = schemas.decode(schemas.Motion, schemas.encode(m))     # both validate
    assert len(m.alternatives) == min(len(mo.alternatives), 8)
    yaws = sorted([m.yaw_rad, m.alternatives[0].yaw_rad])
    assert abs(math.degrees(yaws[1] - yaws[0]) - 90.0) < 0.01     # the truth and its twin
    assert all(a.HasField("score") and a.score > 0 for a in m.alternatives)
    assert m.inliers == 0 and m.layout.samples > 20
    page = to_page("od", m)
    assert len(page["alternatives"]) == len(m.alternatives)
    # the console and Rerun line says so too (the twins turned away; a distance along the
    # same way is said apart)
    n = sum(abs(math.remainder(a.yaw_rad - m.yaw_rad, 2 * math.pi)) > math.radians(3.0)
            for a in m.alternatives)
    assert n >= 1
    assert f"ambiguous: {n} other motion{'s fit' if n > 1 else ' fits'} almost as well" \
        in motion_text(m)


def test_the_console_line_says_another_distance_along_the_way():
    """An alternative at the answer's turn and direction of travel but twice as far reads as
    a distance, not as another place; one turned half round as another place."""
    m = schemas.Motion(session="od", index_a=0, index_b=1, x_m=0.3, z_m=0.4, yaw_rad=0.2,
                       inliers=30, matches=50, alternatives=[
                           schemas.MotionAlternative(x_m=0.6, z_m=0.8, yaw_rad=0.21, score=5.0)])
    text = motion_text(m)
    assert "the distance may also be 1.000 m" in text and "ambiguous" not in text, text
    m.alternatives.append(schemas.MotionAlternative(x_m=-0.3, z_m=-0.4, yaw_rad=0.2 + math.pi))
    text = motion_text(m, "h")
    assert "the distance may also be 1.000 h" in text, text
    assert "ambiguous: 1 other motion fits almost as well" in text, text


def test_the_console_line_states_the_1_sigmas():
    """Each number of a motion with its 1-sigma, in the session's unit, as points and
    distances are said; a motion that states none (a bare message) says none."""
    m = schemas.Motion(session="od", index_a=0, index_b=1, x_m=0.3, z_m=0.4, yaw_rad=0.2,
                       sigma_x_m=0.032, sigma_z_m=0.027, sigma_yaw_rad=math.radians(0.71),
                       inliers=30, matches=50)
    assert ("x +0.300 m, z +0.400 m, yaw +11.46 deg (± 0.032 m, ± 0.027 m, ± 0.71 deg; "
            "30/50 inliers)") in motion_text(m), motion_text(m)
    assert "(± 0.032 h, ± 0.027 h, ± 0.71 deg; 30/50 inliers)" in motion_text(m, "h")
    m.ClearField("sigma_yaw_rad")
    assert "yaw +11.46 deg (30/50 inliers)" in motion_text(m), motion_text(m)


def test_it_takes_no_frames_and_fetches_each_posed_photos_once(photos):
    """Frames reach odometry only when it asks: once per photo, when its hypotheses come,
    and not held after its photo is prepared (a refused photo costs it nothing)."""
    from findme_core.errors import InputError
    _, msgs = photos
    h = OdometryHandler()
    assert not any("frame" in i.key for i in h.inputs)
    out = feed(h, msgs, [0, 1, 2])
    assert "findme/od/pose/2" in out
    assert sorted(h.asked) == [f"findme/od/frame/{n}" for n in range(3)]
    st = h.sessions.peek("od")
    assert all(p.frame is None for p in st.photos.values())
    assert out["findme/od/pose/1"].time_ns == msgs[1][0].capture_time_ns > 0
    with pytest.raises(InputError, match="takes no Frame .*findme/od/frame/0"):
        h.on_message("findme/od/frame/0", msgs[0][0])


def test_a_selection_waits_for_a_lower_photo_not_heard_of_yet(photos):
    """Photo 1's hypotheses are late (another worker): photo 2, selected first, waits for
    it instead of chaining from photo 0, since its frame is in flight."""
    _, msgs = photos
    h = on_bus(OdometryHandler(), msgs)
    for n in (0, 2):
        h.on_message(f"findme/od/hypotheses/{n}", msgs[n][1])
    early = {o.key for n in (0, 2) for o in h.on_message(f"findme/od/selection/{n}", msgs[n][2])}
    assert "findme/od/pose/0" in early and "findme/od/pose/2" not in early
    h.on_message("findme/od/hypotheses/1", msgs[1][1])
    late = {o.key for o in h.on_message("findme/od/selection/1", msgs[1][2])}
    assert {"findme/od/motion/0/1", "findme/od/motion/1/2", "findme/od/pose/2"} <= late


def test_a_photo_never_heard_of_is_chained_past_after_the_wait_and_named(photos):
    _, msgs = photos
    clock = [0.0]
    h = on_bus(OdometryHandler(gap_wait_s=5.0, clock=lambda: clock[0]), msgs)
    for n in (0, 2):
        h.on_message(f"findme/od/hypotheses/{n}", msgs[n][1])
        h.on_message(f"findme/od/selection/{n}", msgs[n][2])
    assert h.tick(4.9) == []
    clock[0] = 5.0
    out = h.tick(5.0)
    by_key = {o.key: o.msg for o in out}
    assert not by_key["findme/od/motion/0/2"].error and "findme/od/pose/2" in by_key
    (gap,) = [o.msg for o in out if o.key == "findme/od/error"]
    assert gap.key == "findme/od/selection/1" and "photo 1" in gap.message
    assert h.gaps == 1


def test_a_photo_chained_past_a_late_one_is_tried_again_from_it(photos):
    """Photo 1 is late (its host was cut off): photo 2 chains past it after the wait, from
    photo 0, and that motion fails (photo 2 is photo 0 again: nothing moved). When photo 1
    comes and gets its pose, photo 2 is tried again from it at the next tick and gets its
    pose: the session ends as it would have without the delay."""
    _, msgs = photos
    again = [schemas.Frame(), schemas.HypothesisSet()]
    for m, src in zip(again, msgs[0][:2]):
        m.CopyFrom(src)
        m.index = 2
    sel2 = schemas.Selection(session="od", index=2, rank=1, by=schemas.SELECTED_BY_AUTO)
    shots = [msgs[0], msgs[1], (again[0], again[1], sel2)]
    clock = [0.0]
    h = on_bus(OdometryHandler(gap_wait_s=5.0, clock=lambda: clock[0]), shots)
    frames, hsets = h.fetch, {"findme/od/hypotheses/1": schemas.encode(shots[1][1])}
    h.fetch = lambda key: hsets.get(key) or frames(key)    # the store has what came late
    for n in (0, 2):
        h.on_message(f"findme/od/hypotheses/{n}", shots[n][1])
        h.on_message(f"findme/od/selection/{n}", shots[n][2])
    clock[0] = 5.0
    first = {o.key: o.msg for o in h.tick(5.0)}
    assert "identical" in first["findme/od/motion/0/2"].error and "findme/od/pose/2" not in first
    h.on_message("findme/od/hypotheses/1", shots[1][1])
    late = {o.key: o.msg for o in h.on_message("findme/od/selection/1", shots[1][2])}
    assert not late["findme/od/motion/0/1"].error and "findme/od/pose/2" not in late
    clock[0] = 5.5
    retried = {o.key: o.msg for o in h.tick(5.5)}
    assert not retried["findme/od/motion/1/2"].error
    p2 = retried["findme/od/pose/2"]          # photo 2 is where photo 0 was
    assert math.hypot(p2.x_m, p2.z_m) < 0.05 and abs(math.degrees(p2.yaw_rad)) < 1.0
    assert [p.index for p in retried["findme/od/trajectory"].poses] == [0, 1, 2]
    assert h.tick(6.0) == [] and not h.sessions.peek("od").failed   # tried once, not again


def test_a_failed_photo_is_not_tried_again_from_a_farther_anchor(photos):
    """Only a nearer anchor than the one a motion failed from reopens it: a failed photo 1
    stays failed when photo 2 gets its pose."""
    _, msgs = photos
    h = OdometryHandler()
    out = feed(h, unmatchable(msgs), [0, 1, 2])
    assert out["findme/od/motion/0/1"].error and "findme/od/pose/2" in out
    assert list(h.sessions.peek("od").failed) == [1] and h.tick(1e9) == []


def test_a_selection_after_the_store_forgot_the_frame_still_gets_its_motion(photos):
    """The frame is asked for when the hypotheses come (seconds after the photo), so a user
    who selects after the store's minute, from a sender that keeps no cache, still gets the
    motion and the capture time."""
    _, msgs = photos
    h = on_bus(OdometryHandler(), msgs)
    for n in (0, 1):
        h.on_message(f"findme/od/hypotheses/{n}", msgs[n][1])
    assert h.asked == ["findme/od/frame/0", "findme/od/frame/1"]
    h.fetch = lambda key: None          # the minute has passed: nobody has the frames now
    out = {o.key: o.msg for n in (0, 1)
           for o in h.on_message(f"findme/od/selection/{n}", msgs[n][2])}
    assert not out["findme/od/motion/0/1"].error
    assert out["findme/od/pose/1"].time_ns == msgs[1][0].capture_time_ns > 0
    st = h.sessions.peek("od")
    assert all(p.frame is None for p in st.photos.values())   # dropped once prepared


def test_frames_held_for_a_late_selection_are_bounded_per_session(photos):
    """At most ``keep_frames`` frames wait for their selection; an older one is dropped with
    its capture time kept, and asked for again when its photo is selected."""
    from services.pipeline.odometry_session import OdometrySession
    _, msgs = photos
    st = OdometrySession(keep_frames=1)
    for n in (0, 1):
        p = st.photo(n, 0.0)
        p.hold(msgs[n][0])     # as the handler holds a fetched frame
    st.prune()
    assert st.photos[0].frame is None and st.photos[1].frame is msgs[1][0]
    assert st.photos[0].time_ns == msgs[0][0].capture_time_ns
