"""Realistic sample messages of every bus type (several variants for oneofs and failures)."""

from __future__ import annotations

import math

import pytest

import schemas as S

SESSION = "2024-05-01T10-00-00Z_pixel7-a1b2"
T0 = 1_714_557_600_123_456_789
# A small byte string shaped like a JPEG (SOI ... EOI); schemas never decode images.
JPEG = b"\xff\xd8\xff\xe0\x00\x10JFIF\x00" + bytes(range(256)) * 3 + b"\xff\xd9"


def _poly(points, kinds):
    return S.polyline_to_msg(points, kinds)


def sample_messages() -> list[tuple[str, object]]:
    """(variant id, message) pairs; every message is valid and has its schema tag set."""
    g = (0.02, 0.96, 0.28)
    n = math.sqrt(sum(c * c for c in g))
    gravity = S.Vec3(x=g[0] / n, y=g[1] / n, z=g[2] / n)
    intr = S.Intrinsics(fx=525.3, fy=524.9, cx=319.5, cy=239.5, width=640, height=480)

    frame = S.Frame(session=SESSION, index=3, capture_time_ns=T0, intrinsics=intr,
                    gravity=gravity, camera_height_m=1.42, camera_height_sigma_m=0.05,
                    device="Pixel 7 / Android 14 / findme-app 0.3", gravity_sigma_rad=0.012,
                    heading_rad=2.4, heading_sigma_rad=0.087, heading_ref="M")
    frame.image.data = JPEG
    frame.image.format = "jpeg"
    frame.image.frame_id = f"{SESSION}/camera/3"
    frame.image.timestamp.CopyFrom(S.ns_to_timestamp(T0))
    frame_hfov = S.Frame(session=SESSION, index=0, capture_time_ns=T0 - 5_000_000_000,
                         hfov_deg=68.5, device="file:IMG_0001.png")
    frame_hfov.image.data = b"\x89PNG\r\n\x1a\n" + bytes(100)
    frame_hfov.image.format = "png"

    poly1 = _poly([(0, 352.5), (210.25, 301.0), (455.0, 305.5), (639, 371.75)], [0, 1, 0])
    poly2 = _poly([(0, 360.0), (300.5, 290.0), (639, 520.0)], [2, 3])
    hset = S.HypothesisSet(
        session=SESSION, index=3, width=640, height=480, method="lsd+dp findme_core 0.1",
        hypotheses=[S.Hypothesis(rank=1, score=12.75, support=0.83, polyline=poly1),
                    S.Hypothesis(rank=2, score=9.5, support=0.61, polyline=poly2)],
        timing_ms={"lines": 24.8, "merge": 1.9, "search": 112.4},
        lines=[10.5, 300.0, 200.25, 280.0, 400.0, 120.0, 402.5, 460.0],
        camera=S.Camera(intrinsics=intr, gravity=gravity, lens_source="exif",
                        gravity_source="image", gravity_sigma_rad=0.0141,
                        gravity_cov_rad2=[0.0002, 0.00001, 0.00001, 0.00018],
                        gravity_fit_cov_rad2=[0.0001, 0.0, 0.0, 0.0001],
                        gravity_alternatives=[S.GravityAlternative(
                            gravity=S.Vec3(x=0.3, y=0.95, z=0.0), ratio=0.97)]),
        frame_height=S.FrameHeight(camera_height_m=1.42, camera_height_sigma_m=0.05))
    hset_empty = S.HypothesisSet(session=SESSION, index=4, width=640, height=480,
                                 reason="no floor lines below the horizon",
                                 timing_ms={"lines": 20.0}, method="lsd+dp findme_core 0.1")

    sel = S.Selection(session=SESSION, index=3, rank=2, by=S.SELECTED_BY_USER,
                      time_ns=T0 + 4_200_000_000, camera_height_m=1.38,
                      camera_height_sigma_m=0.03)
    sel_auto = S.Selection(session=SESSION, index=4, rank=1, by=S.SELECTED_BY_AUTO,
                           time_ns=T0 + 9_000_000_000)

    scene = S.Scene(session=SESSION, index=3, rank=2,
                    camera=S.Camera(intrinsics=intr, gravity=gravity, lens_source="input",
                                    gravity_source="input", gravity_sigma_rad=0.0087),
                    camera_height_m=1.38, camera_height_sigma_m=0.03, metric=True,
                    polyline=poly1, lines=[10.5, 300.0, 200.25, 280.0],
                    time_ns=T0 + 4_210_000_000)

    req = S.MeasureRequest(session=SESSION, index=3,
                           pixels=S.pixels_to_msg([(320.0, 420.5), (500.25, 250.0), (10, 5)]),
                           said=[S.SURFACE_FLOOR, S.SURFACE_NONE, S.SURFACE_TOP])
    reply = S.MeasureReply(
        session=SESSION, index=3, rank=2, metric=True,
        points=[
            S.MeasuredPoint(pixel=S.Pixel(u=320.0, v=420.5), surface=S.SURFACE_FLOOR,
                            xyz=S.Vec3(x=0.004, y=1.21, z=2.87), sigma_m=0.06,
                            said=S.SURFACE_FLOOR,
                            note="the chosen floor line runs below this point"),
            S.MeasuredPoint(pixel=S.Pixel(u=500.25, v=250.0), surface=S.SURFACE_WALL,
                            xyz=S.Vec3(x=1.52, y=0.18, z=4.4), sigma_m=0.21),
            S.MeasuredPoint(pixel=S.Pixel(u=10, v=5),
                            error="pixel (10, 5) is at or above the horizon"),
        ],
        distances=[S.Distance(a=0, b=1, distance_m=2.19, sigma_m=0.22),
                   S.Distance(a=1, b=2, error="an end point has no 3D position")])
    reply_err = S.MeasureReply(session=SESSION, index=7,
                               error="no scene for photo 7: select a hypothesis first")

    motion = S.Motion(session=SESSION, index_a=3, index_b=4, x_m=0.42, z_m=1.87,
                      yaw_rad=math.radians(-12.5), sigma_x_m=0.08, sigma_z_m=0.12,
                      sigma_yaw_rad=math.radians(1.5), inliers=143, matches=388,
                      method="sift+ratio+eq5-8", time_ns=T0 + 12_000_000_000,
                      score=57.25, scale_points=31, appearance=0.41, appearance_samples=3120,
                      layout=S.MotionLayout(rank_a=1, rank_b=2, samples=84, violations=3,
                                            rms_m=0.041, walls=[S.IndexPair(a=2, b=1)],
                                            corners=[S.IndexPair(a=1, b=3)]),
                      alternatives=[S.MotionAlternative(
                          x_m=-0.42, z_m=1.87, yaw_rad=math.radians(167.5), sigma_x_m=0.1,
                          sigma_z_m=0.14, sigma_yaw_rad=0.03, inliers=20, score=51.0)],
                      gravity=S.MotionGravity(status="disagree", angle_rad=0.35,
                                              sigma_a_rad=0.02, sigma_b_rad=0.4,
                                              reason="their gravities are 20 deg apart"))
    motion_agreed = S.Motion(session=SESSION, index_a=5, index_b=6, x_m=0.01, z_m=-0.02,
                             yaw_rad=math.radians(45.0), sigma_x_m=0.02, sigma_z_m=0.02,
                             sigma_yaw_rad=0.01, inliers=150, matches=180, method="findme",
                             time_ns=T0 + 14_000_000_000,
                             gravity=S.MotionGravity(
                                 status="agreed", angle_rad=0.9, sigma_a_rad=0.02,
                                 sigma_b_rad=0.04, gravity_a=S.Vec3(x=0.0, y=0.866, z=0.5),
                                 gravity_b=S.Vec3(x=0.01, y=0.87, z=0.49)))
    motion_failed = S.Motion(session=SESSION, index_a=4, index_b=5, inliers=3, matches=7,
                             method="sift+ratio+eq5-8",
                             error="too few matches: 7 (need 12)", time_ns=T0 + 13_000_000_000)

    poses = [S.Pose(index=0, time_ns=T0 - 5_000_000_000),
             S.Pose(index=3, x_m=1.1, z_m=3.4, yaw_rad=0.35, time_ns=T0, sigma_x_m=0.1,
                    sigma_z_m=0.15, sigma_yaw_rad=0.03),
             S.Pose(index=4, x_m=1.52, z_m=5.27, yaw_rad=0.13, time_ns=T0 + 8_000_000_000)]
    pose = S.Pose(schema="findme.v1.Pose", session=SESSION, index=4, x_m=1.52, z_m=5.27,
                  yaw_rad=0.13, time_ns=T0 + 8_000_000_000, sigma_x_m=0.13, sigma_z_m=0.19,
                  sigma_yaw_rad=0.04)
    traj = S.Trajectory(session=SESSION, poses=poses, time_ns=T0 + 12_500_000_000)

    P = S.PlanPoint
    square = [P(x_m=-1.5, z_m=-1.0), P(x_m=3.5, z_m=-1.0), P(x_m=3.5, z_m=3.0), P(x_m=-1.5, z_m=3.0)]
    kinds = [S.WALL_KIND_WALL, S.WALL_KIND_OPENING, S.WALL_KIND_WALL, S.WALL_KIND_MISSING]
    walls = [S.PlanWall(a=square[k], b=square[(k + 1) % 4], length_m=5.0 if k % 2 == 0 else 4.0,
                        sigma_m=0.03, kind=kinds[k]) for k in range(4)]
    walls[0].openings.append(S.PlanOpening(from_m=1.2, to_m=2.1))
    # corners 1 and 2 measured; 3 and 0 end the MISSING wall: inferred, no 1-sigma
    corners = [P(x_m=q.x_m, z_m=q.z_m) for q in square]
    for q, s in ((corners[1], (0.04, 0.03)), (corners[2], (0.05, 0.06))):
        q.sigma_x_m, q.sigma_z_m = s
    plan = S.Plan(
        session=SESSION, up_to_index=4, photos=4, origin_index=1, metric=True,
        camera_height_m=1.42, polygon=corners, walls=walls, area_m2=20.0, closed=False,
        manhattan=True, time_ns=T0 + 14_000_000_000,
        timing_ms={"relate": 410.5, "place": 120.25, "plan": 12.0},
        poses=[S.PlanPhoto(index=0, status=S.PLAN_PHOTO_STATUS_LEFT_OUT,
                           reason="no hypotheses: no floor lines below the horizon"),
               S.PlanPhoto(index=1, status=S.PLAN_PHOTO_STATUS_PLACED, x_m=0.0, z_m=0.0,
                           yaw_rad=0.0, sigma_x_m=0.01, sigma_z_m=0.012, sigma_yaw_rad=0.002),
               S.PlanPhoto(index=2, status=S.PLAN_PHOTO_STATUS_PLACED, x_m=0.1, z_m=0.05,
                           yaw_rad=0.8, sigma_x_m=0.02, sigma_z_m=0.02, sigma_yaw_rad=0.004,
                           spot=1, ambiguity=0.35),
               S.PlanPhoto(index=4, status=S.PLAN_PHOTO_STATUS_NOT_PLACED, spot=2,
                           reason="no wall of its photos matches a wall of the placed photos")])
    plan_closed = S.Plan(session=SESSION, up_to_index=7, photos=8, camera_height_m=1.5,
                         metric=True, polygon=square, area_m2=20.0, closed=True, time_ns=T0,
                         walls=[S.PlanWall(a=w.a, b=w.b, length_m=w.length_m, sigma_m=0.02,
                                           kind=S.WALL_KIND_WALL) for w in walls])
    plan_reason = S.Plan(session=SESSION, up_to_index=0, photos=1, camera_height_m=1.0,
                         reason="no placed photo saw any floor", time_ns=T0,
                         poses=[S.PlanPhoto(index=0, status=S.PLAN_PHOTO_STATUS_NOT_PLACED,
                                            reason="no layout: no floor lines")])
    # an outline whose walls its photos saw past: not sent, the photos' places kept
    plan_refused = S.Plan(
        session=SESSION, up_to_index=2, photos=3, camera_height_m=1.4, metric=True,
        time_ns=T0, reason="the outline puts a wall where 2 photo(s) (photo 1, photo 3) saw "
                           "past it: floor and a wall 0.3-1 m further out, along 3.6 m",
        poses=[S.PlanPhoto(index=0, status=S.PLAN_PHOTO_STATUS_PLACED, x_m=0.0, z_m=0.0,
                           yaw_rad=0.0, sigma_x_m=0.0, sigma_z_m=0.0, sigma_yaw_rad=0.0),
               S.PlanPhoto(index=1, status=S.PLAN_PHOTO_STATUS_PLACED, x_m=0.0, z_m=0.0,
                           yaw_rad=1.0, sigma_x_m=0.0, sigma_z_m=0.0, sigma_yaw_rad=0.01),
               S.PlanPhoto(index=2, status=S.PLAN_PHOTO_STATUS_PLACED, x_m=2.1, z_m=-0.4,
                           yaw_rad=2.5, sigma_x_m=0.3, sigma_z_m=0.2, sigma_yaw_rad=0.05,
                           spot=1)])

    err = S.Error(session=SESSION, key=f"findme/{SESSION}/selection/9",
                  code=S.ErrorCode.Value("ERROR_CODE_NO_SUCH_HYPOTHESIS"),
                  message="photo 9 has no hypothesis set; rank 2 cannot be selected",
                  time_ns=T0 + 20_000_000_000, service="selection/host-a-4121")
    err_nosession = S.Error(key="findme/bad key/frame/0",
                            code=S.ErrorCode.Value("ERROR_CODE_MALFORMED"),
                            message="session 'bad key' is not a valid session id",
                            time_ns=T0)
    status = S.ServiceStatus(service="hypotheses", instance="host-a-4121",
                             started_ns=T0 - 3_600_000_000_000, time_ns=T0,
                             frames_in=152, results_out=149, errors=2, dropped=1,
                             queue_depth=3, version="0.1.0",
                             counters={"cache_hits": 12, "oversize": 1})

    out = [("frame", frame), ("frame-hfov", frame_hfov), ("hypotheses", hset),
           ("hypotheses-empty", hset_empty), ("selection-user", sel),
           ("selection-auto", sel_auto), ("scene", scene), ("measure-request", req),
           ("measure-reply", reply), ("measure-reply-error", reply_err), ("motion", motion),
           ("motion-agreed", motion_agreed), ("motion-failed", motion_failed), ("pose", pose), ("trajectory", traj),
           ("plan", plan), ("plan-closed", plan_closed),
           ("plan-reason", plan_reason), ("plan-refused", plan_refused),
           ("error", err), ("error-no-session", err_nosession), ("status", status)]
    for _, m in out:
        if not m.schema:
            m.schema = m.DESCRIPTOR.full_name
    return out


@pytest.fixture
def samples() -> dict[str, object]:
    """variant id -> a fresh sample message."""
    return dict(sample_messages())


@pytest.fixture
def sample_of():
    """type full name -> a fresh copy of its first sample variant."""
    def get(type_name: str):
        for _, m in sample_messages():
            if m.DESCRIPTOR.full_name == type_name:
                return m
        raise KeyError(type_name)
    return get


@pytest.fixture
def sample(sample_id):
    """A fresh sample message for the parametrised ``sample_id``."""
    return dict(sample_messages())[sample_id]


def pytest_generate_tests(metafunc):
    if "sample_id" in metafunc.fixturenames:
        metafunc.parametrize("sample_id", [name for name, _ in sample_messages()])
