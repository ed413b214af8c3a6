"""A Frame's photo and its camera: the lens the frame gives (else the photo's EXIF, else the
default), its gravity (given, refined by the image, or estimated from it), decoded whole
(``frame_photo_camera``) or once at its working size with the camera scaled to match
(``frame_work_photo``: a 12 MP JPEG at a quarter, by DCT scaling).

Frames and units: pixels with the pixel-centre origin (a scaled camera keeps it:
c' = (c + 0.5) s - 0.5); gravity in camera coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

import schemas
from findme_core.errors import CameraError, FindmeError, InputError
from findme_core.geometry.camera import Camera
from findme_core.geometry.provenance import Provenance
from findme_core.single.methods import hypothesize
from findme_core.single.segments import WORK_SIZE

from .camera_source import lens_camera, with_gravity
from .imageio import decode_photo, probe


def _frame_lens(frame, width: int, height: int, exif=None) -> tuple[Camera, str, tuple]:
    """(level Camera, lens source, notes): the frame's lens, else the photo's EXIF focal
    length, else the default (``camera_source.lens_camera``)."""
    try:
        lens = frame.WhichOneof("lens")
        if lens == "intrinsics":
            k = frame.intrinsics
            if (k.width, k.height) != (width, height):
                raise InputError(f"frame {frame.index}: intrinsics are for {k.width}x{k.height} "
                                 f"but the image is {width}x{height}")
            return lens_camera(width, height, (k.fx, k.fy, k.cx, k.cy))
        if lens == "hfov_deg":
            return lens_camera(width, height, hfov_deg=frame.hfov_deg)
        if exif is None:
            exif = probe(frame.image.data)[2]
        return lens_camera(width, height, exif=exif)
    except CameraError as e:
        raise CameraError(f"frame {frame.index}: {e}") from None


def _frame_gravity_sigma(frame) -> float | None:
    return frame.gravity_sigma_rad if frame.HasField("gravity_sigma_rad") else None


#: 1-sigma of a frame's heading when it gives none: a phone's gyroscope over a session
#: drifts a few degrees; a compass indoors is off by 10-30 deg (``plan.heading``)
DEFAULT_HEADING_SIGMA_RAD = float(np.radians(10.0))
#: 1-sigma of a photo file's compass bearing (EXIF GPSImgDirection). Indoors a phone's
#: compass is off by 10-30 deg, and by more near steel and appliances, the same way for
#: every photo taken there: a pair's error does not average out. At 30 deg a pair of
#: photos' turn has a 1-sigma of 42 deg, and ``plan.heading`` (3 sigma) keeps the truth
#: while the compass errs by up to 127 deg between two spots and rules out a half-turn
#: twin while it errs by less than 53 deg; it never rules out a quarter turn. Measured on
#: the rendered sessions (``tools/rendered_sessions.py --heading-in exif``): at 15 deg, a
#: spot whose compass read 75 deg off put 125 of 387 photos confidently wrong (a quarter
#: turn ruled in); at 30 deg, 15 of 456, as without any heading (15 of 460). An
#: assumption, not a fit: no dataset here carries the tag.
EXIF_HEADING_SIGMA_RAD = float(np.radians(30.0))


def frame_heading(frame, exif=None) -> tuple[float, float, str] | None:
    """(heading, 1-sigma, reference) in radians of a Frame: its own (``heading_rad``,
    ``heading_sigma_rad`` else ``DEFAULT_HEADING_SIGMA_RAD``, ``heading_ref``: "" the
    page's sensors, "T" / "M" / "?" a compass), else its photo file's compass bearing
    (EXIF GPSImgDirection; reference "T" / "M", true / magnetic north, "?" when the file
    does not say; ``EXIF_HEADING_SIGMA_RAD``), else None. ``exif``: the photo's
    ``ExifInfo`` when already read (else read from the frame's bytes)."""
    if frame.HasField("heading_rad"):
        return (frame.heading_rad, frame.heading_sigma_rad if frame.HasField(
            "heading_sigma_rad") else DEFAULT_HEADING_SIGMA_RAD, frame.heading_ref)
    if exif is None:
        exif = probe(frame.image.data)[2]
    return exif_heading(exif)


def exif_heading(exif) -> tuple[float, float, str] | None:
    """(heading, 1-sigma, reference) in radians of a photo file's ``ExifInfo`` (its
    GPSImgDirection, as ``frame_heading``), None without one."""
    if exif is None or exif.heading_deg is None:
        return None
    return (float(np.radians(exif.heading_deg)), EXIF_HEADING_SIGMA_RAD,
            exif.heading_ref or "?")


def frame_camera(frame, width: int, height: int) -> Camera:
    """The Camera of a Frame whose image is ``width`` x ``height``: its lens (else EXIF,
    else the default) and its gravity (level when it gives none; the hypotheses service
    estimates it from the image then, see ``frame_photo_camera``)."""
    cam, _, _ = _frame_lens(frame, width, height)
    g = schemas.msg_to_vec3(frame.gravity) if frame.HasField("gravity") else None
    try:
        return cam.with_gravity(g)
    except CameraError as e:
        raise CameraError(f"frame {frame.index}: {e}") from None


def frame_photo_camera(frame, estimate: bool = True) -> tuple[np.ndarray, Camera, Provenance]:
    """(BGR image, Camera, Provenance) of a Frame: the lens as ``frame_camera``; gravity the
    frame's, else estimated from the image (``estimate``), else level."""
    photo = decode_photo(frame.image.data, f"frame {frame.index}")
    image = photo.image
    cam, source, notes = _frame_lens(frame, image.shape[1], image.shape[0], photo.exif)
    g = schemas.msg_to_vec3(frame.gravity) if frame.HasField("gravity") else None
    try:
        cam, prov = with_gravity(cam, image, g, _frame_gravity_sigma(frame), estimate, source,
                                 notes)
    except CameraError as e:
        raise CameraError(f"frame {frame.index}: {e}") from None
    return image, cam, prov


@dataclass(frozen=True)
class WorkPhoto:
    """A Frame's photo decoded at its working size (``frame_work_photo``).

    Attributes:
        image: (h, w, 3) uint8 BGR, ``scale`` times the photo's size.
        camera: the camera of ``image`` (intrinsics scaled with the pixel-centre convention
            kept), with gravity as ``frame_photo_camera`` gives it.
        provenance: where lens and gravity came from.
        scale: ``image`` pixels per photo pixel (1, 1/2, 1/4, 1/8).
        full: the camera of the photo itself (its own size; the same gravity).
    """

    image: np.ndarray
    camera: Camera
    provenance: Provenance
    scale: float
    full: Camera

    def to_photo(self, camera: Camera) -> Camera:
        """``camera`` (of ``image``, e.g. with a refined gravity) as the photo's camera."""
        return self.full.with_gravity(camera.gravity) if self.scale != 1.0 else camera

    def points_to_photo(self, px) -> np.ndarray:
        """(..., 2k) pixels of ``image`` -> pixels of the photo."""
        a = np.asarray(px, float)
        return a if self.scale == 1.0 else (a + 0.5) / self.scale - 0.5


def scaled_camera(camera: Camera, s: float, width: int, height: int) -> Camera:
    """The camera of its photo decoded ``s`` times its size into ``width`` x ``height``
    pixels (pixel-centre convention: c' = (c + 0.5) * s - 0.5)."""
    if s == 1.0:
        return camera
    return Camera(camera.fx * s, camera.fy * s, (camera.cx + 0.5) * s - 0.5,
                  (camera.cy + 0.5) * s - 0.5, width, height, camera.gravity)


def scaled_polyline(polyline, s: float, width: int) -> np.ndarray:
    """(k, 2) a boundary polyline (pixels, u then v) of a photo decoded ``s`` times its size
    into ``width`` columns, still running from u = 0 to u = width - 1 (``methods.to_photo``);
    pixel-centre convention as ``scaled_camera``. A new array: the input is not changed."""
    poly = (np.asarray(polyline, float) + 0.5) * s - 0.5
    poly[0, 0], poly[-1, 0] = 0.0, width - 1.0
    return poly


def frame_work_photo(frame, work_size: int = WORK_SIZE, estimate: bool = True) -> WorkPhoto:
    """A Frame's photo decoded once at the smallest JPEG reduction that keeps its long side
    at least ``work_size`` (``imageio.reduction``: a 12 MP photo at a quarter, a photo
    under twice the working size whole), with its camera scaled to match: the lens as
    ``frame_camera`` reads it for the photo's own size, gravity the frame's (refined by
    the image), else estimated from the image (``estimate``), else level."""
    photo = decode_photo(frame.image.data, f"frame {frame.index}", reduce_to=work_size)
    image = photo.image
    full, source, notes = _frame_lens(frame, photo.width, photo.height, photo.exif)
    cam = scaled_camera(full, photo.scale, image.shape[1], image.shape[0])
    g = schemas.msg_to_vec3(frame.gravity) if frame.HasField("gravity") else None
    try:
        cam, prov = with_gravity(cam, image, g, _frame_gravity_sigma(frame), estimate, source,
                                 notes)
    except CameraError as e:
        raise CameraError(f"frame {frame.index}: {e}") from None
    return WorkPhoto(image, cam, prov, photo.scale, full.with_gravity(cam.gravity))


def frame_inputs(frame) -> tuple[np.ndarray, Camera]:
    """(BGR image, Camera) of a Frame, gravity estimated when the frame gives none."""
    image, cam, _ = frame_photo_camera(frame)
    return image, cam


def best_again(image: np.ndarray, scale: float, camera: Camera, height: float | None,
               method: str = "findme"):
    """(the best boundary hypothesis of a photo under ``camera``'s gravity, or None and the
    reason): a photo whose automatically chosen boundary was found under a gravity that
    turned out wrong is hypothesized again under the right one. ``image``: the photo decoded
    at ``scale`` of its size; ``camera``: the photo's own (its pixels, the gravity to use);
    ``height``: camera height, metres (None: unknown). The polyline is in the photo's
    pixels."""
    try:
        hs = hypothesize(image, scaled_camera(camera, scale, image.shape[1], image.shape[0]),
                         method, 1, camera_height=height)
    except FindmeError as e:
        return None, str(e).splitlines()[0][:200]
    if not hs.hypotheses:
        return None, hs.reason or "no boundary under that gravity"
    h = hs.hypotheses[0]
    return replace(h, polyline=(np.asarray(h.polyline, float) + 0.5) / scale - 0.5), None
