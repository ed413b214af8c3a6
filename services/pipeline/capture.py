"""The capture service: photos from image files, a folder, a video file or a camera device
onto the bus as frames.

    -> findme/<session>/frame/<n>      (n = 0, 1, ... in capture order)

What the phone would know about each photo comes from flags, or from a sidecar JSON next
to an image (``photo.jpg`` -> ``photo.json``) with ``intrinsics {fx, fy, cx, cy, width,
height}``, ``gravity_cam`` and ``camera_height_m`` (the bundled examples' and the
evaluation set's format; nothing else in it is read). Frames stay in the service's cache so
a service that starts later can fetch them.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2

from findme_io.imageio import MAX_BYTES, encode_jpeg, read_image
from findme_core.errors import ImageError, InputError

from ..runtime import bus
from findme_io.convert import make_frame
from ..runtime.handler import Handler

IMAGE_EXT = {".jpg", ".jpeg", ".png", ".bmp", ".webp", ".tif", ".tiff"}
VIDEO_EXT = {".mp4", ".avi", ".mov", ".mkv", ".webm"}


class CaptureHandler(Handler):
    """A source: no inputs; it publishes frames and answers queries for them."""

    name = "capture"
    cache_keys = ("findme/*/frame/*",)


@dataclass(frozen=True)
class Lens:
    """Camera knowledge given on the command line (overrides nothing in a sidecar)."""

    intrinsics: tuple | None = None   # fx, fy, cx, cy
    hfov_deg: float | None = None
    gravity: tuple | None = None
    camera_height_m: float | None = None


def _sidecar(path: Path) -> dict:
    side = path.with_suffix(".json")
    if not side.exists():
        return {}
    try:
        meta = json.loads(side.read_text())
    except json.JSONDecodeError as e:
        raise InputError(f"{side}: not valid JSON ({e.msg} at line {e.lineno})") from None
    return {k: meta[k] for k in ("intrinsics", "gravity_cam", "camera_height_m") if k in meta}


def _encoded(path: Path) -> bytes:
    data = path.read_bytes()
    if len(data) > MAX_BYTES:
        raise ImageError(f"{path}: {len(data) / 1e6:.1f} MB is over the {MAX_BYTES / 1e6:.0f} MB limit")
    read_image(path)  # validates: decodable, size limits
    return data


def sources(paths, every: int = 1) -> Iterator[tuple[str, bytes, dict]]:
    """(name, encoded image, sidecar) for every photo of image files, folders (sorted),
    video files (every ``every``-th frame) and camera devices (``camera:N``)."""
    for p in paths:
        p = str(p)
        if p.startswith("camera:"):
            yield from _video(p, int(p.split(":", 1)[1] or 0), every)
            continue
        path = Path(p)
        if path.is_dir():
            files = sorted(q for q in path.iterdir() if q.suffix.lower() in IMAGE_EXT)
            if not files:
                raise InputError(f"{path}: no images in this folder")
            for q in files:
                yield q.name, _encoded(q), _sidecar(q)
        elif path.suffix.lower() in VIDEO_EXT:
            yield from _video(str(path), str(path), every)
        elif path.exists():
            yield path.name, _encoded(path), _sidecar(path)
        else:
            raise InputError(f"{path}: no such file, folder or camera")


def _video(name: str, source, every: int):
    cap = cv2.VideoCapture(source)
    if not cap.isOpened():
        raise InputError(f"{name}: cannot open the video or camera")
    try:
        i = 0
        while True:
            ok, img = cap.read()
            if not ok:
                break
            if i % max(1, every) == 0:
                yield f"{os.path.basename(str(name))}#{i}", encode_jpeg(img, 90), {}
            i += 1
    finally:
        cap.release()


def frames(session: str, srcs, lens: Lens = Lens(), start: int = 0):
    """Frame messages, n from ``start``; flags fill in what a sidecar does not say."""
    for n, (name, data, side) in enumerate(srcs, start):
        k = side.get("intrinsics")
        intr = ((k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"]) if k else None)
        if intr is None and lens.intrinsics is not None:
            from findme_io.imageio import image_size
            w, h = image_size(data, name)
            intr = (*lens.intrinsics, w, h)
        yield make_frame(session, n, data, intrinsics=intr,
                         hfov_deg=None if intr else lens.hfov_deg,
                         gravity=side.get("gravity_cam", lens.gravity),
                         camera_height_m=side.get("camera_height_m", lens.camera_height_m),
                         device=f"file:{name}", time_ns=time.time_ns())


def publish_frames(service, session: str, srcs, lens: Lens = Lens(), window: int = 8) -> int:
    """Publish every frame through a running capture ``service``, at most ``window`` of them
    unanswered at once (``runtime.pacer``); returns the count."""
    from ..runtime.handler import Output
    from ..runtime.pacer import Pacer
    pacer = Pacer(service.session, session, window)
    n = 0
    try:
        for f in frames(session, srcs, lens):
            pacer.wait_room()
            service.publish(Output(bus.key(session, "frame", f.index), f))
            pacer.sent(f.index)
            n += 1
    finally:
        pacer.close()
    return n
