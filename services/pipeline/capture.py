"""The capture service: photos from image files, a folder, a video file or a camera device
onto the bus as frames.

    -> findme/<session>/frame/<n>      (n = 0, 1, ... in capture order)

What the phone would know about each photo comes from flags, or from a sidecar JSON next
to an image (``photo.jpg`` -> ``photo.json``) with ``intrinsics {fx, fy, cx, cy, width,
height}``, ``gravity_cam`` and ``camera_height_m`` (the bundled examples' and the
evaluation set's format; nothing else in it is read). Frames stay in the service's cache so
a service that starts later can fetch them.

A frame's ``capture_time_ns`` is when the photo was taken (findme_io/capture_time.py): the
EXIF ``DateTimeOriginal`` of a photo; else the frame's capture stamp, the clock when this
service takes the photo in, strictly increasing in capture order (a file's modification
time would not do: a copy or a clone gives every file the same one, and a trajectory needs
its photos in order); a video's creation time (MP4/QuickTime ``mvhd``, else its
modification time minus its duration) plus the frame's position; a camera's frame the
clock when it was grabbed.

A file that cannot be read (missing, not an image, too large, a broken sidecar) does not
stop the others: with an ``errors`` list, ``sources`` reports it there and goes on.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2

from findme_io.capture_time import exif_time_ns, video_start_ns
from findme_io.imageio import MAX_BYTES, encode_jpeg, for_bus, read_image
from findme_core.errors import FindmeError, ImageError, InputError

from ..runtime import bus
from findme_io.convert import make_frame
from ..runtime.handler import Handler

IMAGE_EXT = {".jpg", ".jpeg", ".png", ".bmp", ".webp", ".tif", ".tiff", ".heic", ".heif", ".avif"}
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
    gravity_sigma_rad: float | None = None   # of ``gravity`` (None: the services' default)


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


def _photo(path: Path, name: str) -> tuple[str, bytes, dict]:
    original = _encoded(path)
    data, lens = for_bus(original, str(path))   # HEIC/AVIF/BMP/TIFF: upright JPEG + EXIF lens
    side = {**lens, **_sidecar(path)}
    t = exif_time_ns(original)
    if t:                      # else: the frame's capture stamp (``frames``)
        side["capture_time_ns"] = t
    return name, data, side


def sources(paths, every: int = 1, errors: list | None = None) -> Iterator[tuple[str, bytes, dict]]:
    """(name, encoded image, sidecar + ``capture_time_ns``) for every photo of image files,
    folders (sorted), video files (every ``every``-th frame) and camera devices
    (``camera:N``).

    errors: None = the first bad file raises its FindmeError; a list = each bad file or
        folder is appended as (path, FindmeError) and the rest is still read.
    """
    for p in paths:
        try:
            yield from _one_source(str(p), every, errors)
        except FindmeError as e:
            if errors is None:
                raise
            errors.append((str(p), e))


def _one_source(p: str, every: int, errors: list | None):
    if p.startswith("camera:"):
        yield from _video(p, int(p.split(":", 1)[1] or 0), every)
        return
    path = Path(p)
    if path.is_dir():
        files = sorted(q for q in path.iterdir() if q.suffix.lower() in IMAGE_EXT)
        if not files:
            raise InputError(f"{path}: no images in this folder")
        for q in files:
            try:
                yield _photo(q, q.name)
            except FindmeError as e:
                if errors is None:
                    raise
                errors.append((str(q), e))
    elif path.suffix.lower() in VIDEO_EXT and path.exists():
        yield from _video(str(path), str(path), every)
    elif path.exists():
        yield _photo(path, path.name)
    else:
        raise InputError(f"{path}: no such file, folder or camera")


def _video(name: str, source, every: int):
    cap = cv2.VideoCapture(source)
    if not cap.isOpened():
        raise InputError(f"{name}: cannot open the video or camera")
    start = None
    if isinstance(source, str):   # a file: its creation time + the frame's position
        start = video_start_ns(source)
        if start is None:
            fps, count = cap.get(cv2.CAP_PROP_FPS), cap.get(cv2.CAP_PROP_FRAME_COUNT)
            length = count / fps if fps > 0 and count > 0 else 0.0
            start = Path(source).stat().st_mtime_ns - int(length * 1e9)
    try:
        i = 0
        while True:
            ok, img = cap.read()
            if not ok:
                break
            if i % max(1, every) == 0:
                t = (time.time_ns() if start is None else
                     start + int(cap.get(cv2.CAP_PROP_POS_MSEC) * 1e6))
                yield (f"{os.path.basename(str(name))}#{i}", encode_jpeg(img, 90),
                       {"capture_time_ns": t})
            i += 1
    finally:
        cap.release()


#: Capture stamps of successive photos without a time of their own are at least this far
#: apart (ns), so that they stay in capture order in every format (TUM, CSV milliseconds).
MIN_STAMP_STEP_NS = 1_000_000


def frames(session: str, srcs, lens: Lens = Lens(), start: int = 0):
    """Frame messages, n from ``start``; flags fill in what a sidecar does not say. A photo
    without a capture time of its own gets the frame's capture stamp: now, and always
    after the previous stamp."""
    stamp = 0
    for n, (name, data, side) in enumerate(srcs, start):
        t = side.get("capture_time_ns")
        if not t:
            t = stamp = max(time.time_ns(), stamp + MIN_STAMP_STEP_NS)
        k = side.get("intrinsics")
        intr = ((k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"]) if k else None)
        if intr is None and lens.intrinsics is not None:
            from findme_io.imageio import image_size
            w, h = image_size(data, name)
            intr = (*lens.intrinsics, w, h)
        yield make_frame(session, n, data, intrinsics=intr,
                         hfov_deg=None if intr else lens.hfov_deg,
                         gravity=side.get("gravity_cam", lens.gravity),
                         gravity_sigma_rad=lens.gravity_sigma_rad,
                         camera_height_m=side.get("camera_height_m", lens.camera_height_m),
                         device=f"file:{name}", time_ns=t)


def publish_frames(service, session: str, srcs, lens: Lens = Lens(), window: int = 8,
                   on_first=None) -> int:
    """Publish every frame through a running capture ``service``, at most ``window`` of them
    unanswered at once (``runtime.pacer``); returns the count. ``on_first()`` runs once the
    first frame is out (it may raise to stop before the others)."""
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
            if n == 1 and on_first is not None:
                on_first()
    finally:
        pacer.close()
    return n
