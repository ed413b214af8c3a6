"""A mapping session of a room the project renders, as bus messages: each photo's Frame
(the rendered JPEG, its exact camera), a HypothesisSet whose rank 1 is the exact ground-wall
boundary (``synth``; segment kinds WALL, or STEP at occluding edges) and its Selection; plus
the truth in the level frame of photo 0 (the plan's frame).

Photos turn right at each spot (``yaws`` degrees, the spot's heading offset by 7 deg per
spot), tilted down ``pitch`` degrees, 1.4 m above the floor. With ``heading_sigma_deg``, each
Frame carries the phone's heading as a page would send it: the true yaw plus a session offset
and a seeded N(0, sigma) reading error, declared at that sigma; with ``heading_in="exif"``
the photo file carries it instead, as a phone's camera app writes its compass bearing
(GPSImgDirection, from magnetic north), and the Frame none; ``heading_bias_deg`` more on
every reading at the second spot (a compass near steel: indoor errors are local).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

import schemas
from findme_core.geometry.planar import wrap
from findme_core.single.search import SegKind
from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room
from findme_io.convert import make_frame

H = 1.4


@dataclass
class RenderedSession:
    frames: list
    hsets: list
    selections: list
    jpegs: list            # the photos' bytes (what a page uploads)
    views: list            # synth.View of each photo
    polygon: np.ndarray    # (V, 2) true outline in the level frame of photo 0
    poses: np.ndarray      # (N, 3) true (x, z, yaw) in that frame

    def messages(self):
        """(key, message) of every photo, photo by photo: frame, hypotheses, selection."""
        for f, h, s in zip(self.frames, self.hsets, self.selections):
            sid, n = f.session, f.index
            yield f"findme/{sid}/frame/{n}", f
            yield f"findme/{sid}/hypotheses/{n}", h
            yield f"findme/{sid}/selection/{n}", s

    def plans(self, handler) -> list:
        """The messages ``handler`` (a mapper's, driven without the bus) outputs for this
        session's messages, in order: its plans, the last one of the whole session last."""
        return [o.msg for k, msg in self.messages() for o in handler.on_message(k, msg)]

    def wall_lengths(self) -> list[float]:
        P = self.polygon
        return sorted(float(x) for x in np.linalg.norm(np.roll(P, -1, 0) - P, axis=1))


def boundary_kinds(cam, poly, height=H) -> np.ndarray:
    """WALL, or STEP where neighbouring columns' floor points lie far apart (an occlusion)."""
    kinds = np.full(len(poly) - 1, SegKind.WALL)
    r = cam.rays_level(poly)
    q = height / r[:, 1:2] * r[:, [0, 2]]
    step = np.linalg.norm(np.diff(q, axis=0), axis=1) > 0.05 * np.maximum(np.diff(poly[:, 0]), 1)
    kinds[step] = SegKind.STEP
    return kinds


def rendered_session(room: Room, spots_xz, yaws=range(0, 360, 45), pitch=28.0, hfov=70.0,
                     session="plan-test", size=(640, 480), heading_sigma_deg=None,
                     seed=0, heading_in: str = "frame",
                     heading_bias_deg: float = 0.0) -> RenderedSession:
    poses = [Pose(x, z, H, float(y) + 7.0 * s, pitch, 0.0)
             for s, (x, z) in enumerate(spots_xz) for y in yaws]
    spot_of = [s for s in range(len(spots_xz)) for _ in yaws]
    rng = np.random.default_rng(seed)
    frames, hsets, sels, jpegs, views = [], [], [], [], []
    for n, p in enumerate(poses):
        v = render(room, p, size[0], size[1], hfov_deg=hfov, supersample=1)
        c = v.camera
        heading = None
        if heading_sigma_deg is not None:
            s = math.radians(heading_sigma_deg)
            heading = (math.radians(p.yaw_deg) + 2.0 + s * rng.standard_normal()
                       + math.radians(heading_bias_deg) * (spot_of[n] == 1))
        if heading is not None and heading_in == "exif":
            data = _jpeg_with_direction(v.image, math.degrees(heading) % 360.0)
        else:
            data = cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()
        frames.append(make_frame(session, n, data, intrinsics=(c.fx, c.fy, c.cx, c.cy,
                                                                 c.width, c.height),
                                 gravity=c.gravity, camera_height_m=H,
                                 time_ns=1_700_000_000_000_000_000 + n * 10**9))
        if heading is not None and heading_in == "frame":
            frames[-1].heading_rad, frames[-1].heading_sigma_rad = heading, s
        poly = v.ground_truth_boundary_polyline()
        poly = poly[np.isfinite(poly[:, 1])]
        hs = schemas.HypothesisSet(session=session, index=n, width=c.width, height=c.height,
                                   method="truth")
        hs.hypotheses.add(rank=1, score=1.0, support=1.0,
                          polyline=schemas.polyline_to_msg(poly, boundary_kinds(c, poly)))
        hsets.append(hs)
        sels.append(schemas.Selection(session=session, index=n, rank=1,
                                      by=schemas.SELECTED_BY_AUTO, time_ns=n + 1))
        jpegs.append(data)
        views.append(v)
    truth, poly = first_frame_truth(room, poses)
    return RenderedSession(frames, hsets, sels, jpegs, views, poly, truth)


def _jpeg_with_direction(bgr, degrees: float) -> bytes:
    """A JPEG whose EXIF says the camera looked ``degrees`` from magnetic north (and
    nothing else, ``exif.direction_block``)."""
    import io

    from PIL import Image

    from findme_io.exif import direction_block
    out = io.BytesIO()
    Image.fromarray(bgr[:, :, ::-1]).save(out, "JPEG", quality=95,
                                          exif=direction_block(degrees, "M"))
    return out.getvalue()


def first_frame_truth(room, poses):
    """The true (x, z, yaw) of each pose (N, 3) and the floor polygon (M, 2), in the level
    frame of the first pose (metres, radians), the frame a plan is given in."""
    p0 = poses[0]
    c, s = math.cos(math.radians(p0.yaw_deg)), math.sin(math.radians(p0.yaw_deg))

    def to0(X, Z):
        dx, dz = X - p0.x, Z - p0.z
        return np.array([c * dx - s * dz, s * dx + c * dz])
    truth = np.array([[*to0(p.x, p.z), math.radians(p.yaw_deg - p0.yaw_deg)] for p in poses])
    return truth, np.array([to0(X, Z) for X, Z in room.floor_polygon])


def confident_wrong(stated, sigma, truth, slack=(0.02, 0.02, 0.01)) -> bool:
    """Whether the true pose (x, z, yaw) lies outside 3 sigma of the stated one on any axis
    (metres, radians; the yaw error wrapped), with ``slack`` for the render: what the
    mapper's tests and ``tools/rendered_sessions.py`` call confidently wrong."""
    err = (abs(stated[0] - truth[0]), abs(stated[1] - truth[1]),
           abs(float(wrap(stated[2] - truth[2]))))
    return any(e > 3.0 * s + k for e, s, k in zip(err, sigma, slack))
