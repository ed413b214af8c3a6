"""Rerun adapters: ``log_*(rec, path, msg)`` functions that show Find Me bus messages in a
Rerun recording (``rerun_session.SessionView`` routes a session's messages to them, and
``rerun_session.blueprint`` lays a session out).

The algorithms stay in ``findme_core``; this module only converts their results into
Rerun archetypes. Rerun is imported lazily (the CLI starts fast without it).

Frames (DESIGN.md conventions) and where data changes frame:

* ``world`` = the session frame = the LEVEL frame of photo 0: x right, y down along
  gravity, z forward (Rerun ``RDF``). The floor is the plane y = h (camera height).
* ``world/photo/<n>`` = the level frame of photo n, placed in ``world`` by its planar pose
  (x_m, 0, z_m, yaw about y; ``log_pose``). Floor, walls and the 3D boundary are logged here
  (y = h on the floor).
* ``world/photo/<n>/camera`` = the CAMERA frame of photo n (OpenCV: x right, y down,
  z forward): the rotation ``R_level_from_cam`` from gravity (p_level = R p_cam, no
  translation: the frames share the camera centre). Measured points are logged here, as on
  the bus.
* ``world/photo/<n>/camera/image`` = the pinhole (intrinsics K) and the photo: 2D pixel
  space. Bus pixels have (0, 0) at the CENTRE of the top-left pixel, Rerun's 2D space at
  its top-left CORNER, so 2D positions are logged at (u + 0.5, v + 0.5).
* ``plan`` = the floor plan seen from above, 2D (x, -z) metres: forward is up
  (``rerun_plan.log_plan``; also in 3D under ``world/photo/<origin>/plan``).
* ``log`` = text: motions, errors.

Timelines: ``photo`` (sequence: the photo index n of the message) and ``bus_time``
(timestamp: when the message was on the bus: the recording's log time, or receipt time live).
"""

from __future__ import annotations

import numpy as np

import schemas
from .motion_msg import motion_text

PIXEL_TO_RERUN = 0.5
#: Walls are drawn this many camera heights tall above the floor (a 2.5 m room seen from
#: 1.4 m); the photo does not tell a wall's true height.
WALL_HEIGHT_H = 1.8
#: Floor points farther than this many camera heights are clipped (rays near the horizon).
FLOOR_MAX_H = 15.0

FLOOR_RGBA = (90, 140, 200, 110)
WALL_RGBA = (220, 190, 140, 90)
BOUNDARY_RGBA = (255, 215, 0, 255)
MEASURE_RGBA = (255, 50, 200, 255)


def _rr():
    import rerun as rr
    return rr


def _bgr_to_rgb(c):
    return (c[2], c[1], c[0], 255)


def photo_path(n: int) -> str:
    return f"world/photo/{n}"


def camera_of(frame_or_scene):
    """findme_core Camera of a Frame (from its image size) or of a Scene message."""
    from .convert import msg_camera
    from .frame_photo import frame_camera
    if frame_or_scene.DESCRIPTOR.full_name == "findme.v1.Scene":
        return msg_camera(frame_or_scene.camera)
    from .imageio import image_size
    w, h = image_size(frame_or_scene.image.data, f"frame {frame_or_scene.index}")
    return frame_camera(frame_or_scene, w, h)


def _set_time(rec, n: int | None, t_ns: int | None) -> None:
    if n is not None:
        rec.set_time("photo", sequence=int(n))
    if t_ns:
        rec.set_time("bus_time", timestamp=np.datetime64(int(t_ns), "ns"))


# ------------------------------------------------------------------------------ adapters
def log_frame(rec, path: str, frame, camera=None) -> None:
    """A photo at ``path`` (= world/photo/<n>): the camera rotation (level <- camera), the
    pinhole and the encoded image (not decoded: JPEG stays JPEG)."""
    rr = _rr()
    cam = camera or camera_of(frame)
    rec.log(f"{path}/camera", rr.Transform3D(mat3x3=cam.R_level_from_cam))
    img = f"{path}/camera/image"
    rec.log(img, rr.Pinhole(image_from_camera=cam.K, resolution=[cam.width, cam.height],
                            camera_xyz=rr.ViewCoordinates.RDF, image_plane_distance=0.4))
    media = {"jpeg": "image/jpeg", "png": "image/png", "webp": "image/webp",
             "avif": "image/avif"}.get(frame.image.format, None)
    rec.log(img, rr.EncodedImage(contents=frame.image.data, media_type=media))


def log_sources(rec, path: str, n: int, camera) -> None:
    """Where photo n's camera and gravity came from (a Camera message of a HypothesisSet or
    Scene): the camera rotation at ``path`` (= world/photo/<n>) is re-logged with the gravity
    actually used, and one line goes to the ``log`` text view (a warning when level was
    only assumed)."""
    rr = _rr()
    from .convert import msg_camera, provenance_text
    if not camera.gravity_source:
        return
    cam = msg_camera(camera)
    rec.log(f"{path}/camera", rr.Transform3D(mat3x3=cam.R_level_from_cam))
    rec.log("log", rr.TextLog(f"photo {n}: {provenance_text(camera)}",
                              level="WARN" if camera.gravity_source == "level" else "INFO"))


def _strip(points) -> np.ndarray:
    return schemas.msg_to_pixels(points) + PIXEL_TO_RERUN


def log_hypotheses(rec, path: str, hset) -> None:
    """Ranked hypotheses as numbered 2D line strips over the photo (``path`` = the image
    entity, world/photo/<n>/camera/image); rank 1 thickest, colours as the selection image."""
    rr = _rr()
    from findme_io.overlay import palette
    strips = [_strip(h.polyline.points) for h in hset.hypotheses]
    if not strips:
        rec.log(f"{path}/hypotheses", rr.Clear(recursive=False))
        return
    cols = [_bgr_to_rgb(c) for c in palette(len(strips))]
    rec.log(f"{path}/hypotheses",
            rr.LineStrips2D(strips, colors=cols, labels=[str(h.rank) for h in hset.hypotheses],
                            radii=[2.0 if i == 0 else 1.2 for i in range(len(strips))],
                            show_labels=True, draw_order=10.0))


def log_boundary(rec, path: str, scene) -> None:
    """The chosen boundary: a thick 2D strip on the image (``path`` = world/photo/<n>), and
    in 3D the floor (a mesh on y = h of the level frame), the walls standing on the boundary's
    WALL segments, and the boundary itself on the floor."""
    rr = _rr()
    strip = _strip(scene.polyline.points)
    rec.log(f"{path}/camera/image/boundary",
            rr.LineStrips2D([strip], colors=[BOUNDARY_RGBA], radii=[3.0],
                            labels=[f"chosen {scene.rank}"], show_labels=True, draw_order=20.0))
    floor, walls, line = scene_geometry(scene)
    if floor is not None:
        v, tri = floor
        rec.log(f"{path}/floor", rr.Mesh3D(vertex_positions=v, triangle_indices=tri,
                                            vertex_colors=np.tile(FLOOR_RGBA, (len(v), 1))))
    if walls is not None:
        v, tri = walls
        rec.log(f"{path}/walls", rr.Mesh3D(vertex_positions=v, triangle_indices=tri,
                                            vertex_colors=np.tile(WALL_RGBA, (len(v), 1))))
    if line:
        rec.log(f"{path}/boundary", rr.LineStrips3D(line, colors=[BOUNDARY_RGBA], radii=[0.01]))


def scene_geometry(scene, samples: int = 48):
    """(floor (V, T) or None, walls (V, T) or None, 3D boundary strips) in the LEVEL frame
    of the photo (y down, floor y = h) from a Scene message."""
    from findme_core.single.search import SegKind
    cam = camera_of(scene)
    h = float(scene.camera_height_m) or 1.0
    poly, kinds = schemas.msg_to_polyline(scene.polyline)
    if len(poly) < 2:
        return None, None, []

    def lift(px):
        r = cam.rays_level(px)
        ok = r[:, 1] > 1e-6
        t = np.where(ok, h / np.where(ok, r[:, 1], 1.0), np.nan)
        P = r * t[:, None]
        far = np.linalg.norm(P[:, [0, 2]], axis=1) > FLOOR_MAX_H * h
        P[far] = np.nan
        return P

    # floor: a strip between the boundary and the bottom image border, column by column
    us = np.linspace(0.0, cam.width - 1.0, samples)
    vs = np.interp(us, poly[:, 0], poly[:, 1]).clip(0.0, cam.height - 1.0)
    top, bot = lift(np.column_stack([us, vs])), lift(np.column_stack([us, np.full_like(us, cam.height - 1.0)]))
    verts, tris = [], []
    for i in range(samples - 1):
        q = [top[i], bot[i], top[i + 1], bot[i + 1]]
        if any(not np.all(np.isfinite(p)) for p in q):
            continue
        b = len(verts)
        verts.extend(q)
        tris.extend([(b, b + 1, b + 2), (b + 2, b + 1, b + 3)])
    floor = (np.array(verts), np.array(tris, dtype=np.uint32)) if tris else None

    # walls: vertical quads on every WALL segment, WALL_HEIGHT_H camera heights tall
    ends = lift(poly)
    verts, tris, line = [], [], []
    for s, kind in enumerate(kinds):
        a, b = ends[s], ends[s + 1]
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            continue
        line.append(np.array([a, b]))
        if kind != SegKind.WALL:
            continue
        up = np.array([0.0, -WALL_HEIGHT_H * h, 0.0])
        k = len(verts)
        verts.extend([a, b, a + up, b + up])
        tris.extend([(k, k + 1, k + 2), (k + 2, k + 1, k + 3)])
    walls = (np.array(verts), np.array(tris, dtype=np.uint32)) if tris else None
    return floor, walls, line


def log_measure(rec, path: str, reply, k: int = 0) -> None:
    """Measured points (camera frame, ``path`` = world/photo/<n>) with their distances, and
    the tapped pixels on the image; ``k`` numbers successive measurements of one photo."""
    rr = _rr()
    unit = "m" if reply.metric else "h"
    ok = [(i, p) for i, p in enumerate(reply.points) if not p.error]
    base = f"{path}/camera/measure/{k}"
    taps = np.array([(p.pixel.u, p.pixel.v) for p in reply.points]).reshape(-1, 2) + PIXEL_TO_RERUN
    if len(taps):
        rec.log(f"{path}/camera/image/measure/{k}",
                rr.Points2D(taps, colors=[MEASURE_RGBA], radii=[4.0],
                            labels=[str(i + 1) for i in range(len(taps))], show_labels=True,
                            draw_order=30.0))
    if ok:
        xyz = np.array([schemas.msg_to_vec3(p.xyz) for _, p in ok])
        labels = [f"{i + 1} {schemas.Surface.Name(p.surface).split('_')[1].lower()}"
                  f" ({p.xyz.x:.2f}, {p.xyz.y:.2f}, {p.xyz.z:.2f}) {unit}" for i, p in ok]
        rec.log(f"{base}/points", rr.Points3D(xyz, colors=[MEASURE_RGBA], radii=[0.03],
                                              labels=labels, show_labels=True))
    segs, labels = [], []
    for d in reply.distances:
        if d.error or d.a >= len(reply.points) or d.b >= len(reply.points):
            continue
        a, b = reply.points[d.a], reply.points[d.b]
        segs.append(np.array([schemas.msg_to_vec3(a.xyz), schemas.msg_to_vec3(b.xyz)]))
        labels.append(f"{d.distance_m:.3f} {unit} ± {d.sigma_m:.3f}")
    if segs:
        rec.log(f"{base}/distances", rr.LineStrips3D(segs, colors=[MEASURE_RGBA], radii=[0.01],
                                                     labels=labels, show_labels=True))


def pose_transform(pose):
    """Rerun Transform3D of a planar pose: level frame n in level frame 0 (translation
    (x, 0, z), rotation yaw about +y, which points down: > 0 turns right)."""
    rr = _rr()
    return rr.Transform3D(translation=[pose.x_m, 0.0, pose.z_m],
                          rotation=rr.RotationAxisAngle(axis=[0.0, 1.0, 0.0],
                                                        radians=float(pose.yaw_rad)))


def log_pose(rec, path: str, pose) -> None:
    """Place photo n's level frame (``path`` = world/photo/<n>) by its pose."""
    rec.log(path, pose_transform(pose))


def log_trajectory(rec, path: str, traj) -> None:
    """The camera path through the session (``path`` = world/trajectory): a strip through the
    camera centres at y = 0 of the session frame, numbered; also re-places every photo."""
    rr = _rr()
    poses = sorted(traj.poses, key=lambda p: p.index)
    if not poses:
        return
    xyz = np.array([(p.x_m, 0.0, p.z_m) for p in poses])
    rec.log(path, rr.LineStrips3D([xyz], colors=[(0, 220, 120, 255)], radii=[0.015]))
    rec.log(f"{path}/cameras", rr.Points3D(xyz, colors=[(0, 220, 120, 255)], radii=[0.04],
                                           labels=[str(p.index) for p in poses], show_labels=True))
    for p in poses:
        rec.log(photo_path(p.index), pose_transform(p))


def log_motion(rec, path: str, motion) -> None:
    """A motion estimate as a line of text (``path`` = log)."""
    rr = _rr()
    level = "WARN" if motion.error or len(motion.alternatives) else "INFO"
    rec.log(path, rr.TextLog(motion_text(motion), level=level))


def log_error(rec, path: str, err) -> None:
    rr = _rr()
    rec.log(path, rr.TextLog(f"{err.key}: {err.message} ({err.service})", level="ERROR"))
