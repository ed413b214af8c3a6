"""What a page sends the gateway, parsed and checked: photo uploads and text commands.

    binary  [u32 big-endian n][n bytes UTF-8 JSON header][image]      a photo
    text    {"type": "select", index, rank, camera_height_m}          another hypothesis
    text    {"type": "measure", id, index, pixels: [[u, v], ...],     3D of tapped pixels
             surfaces: [null | "floor" | "wall", ...]}                (optional) one per pixel
    text    {"type": "ping"}

Limits: upload bytes (``MAX_UPLOAD_BYTES``), header and text sizes, decoded pixels
(``MAX_PIXELS``, read from the image header before decoding), pixels per measure query.
Images must decode (JPEG, PNG or WebP); lens, gravity and height values must be valid.
Every refusal is a ``GatewayError`` carrying the ``ErrorCode`` the page gets.

Units and frames of the header: the lens is ``default``, ``hfov`` (horizontal field of view,
degrees), ``focal35`` (35 mm-equivalent focal length, mm, relative to the film diagonal
``FILM_DIAGONAL_MM`` and converted here to a horizontal field of view for the photo's
diagonal) or ``intrinsics`` (fx, fy, cx, cy in pixels of this photo). ``gravity`` is three
numbers of any length above 1e-3, pointing down, in OpenCV camera axes (x right, y down,
z forward) of the upright photo; the page has already turned the phone's device-frame
reading into camera axes (findme/web/settings.js) and nothing here rotates it.
``gravity_sigma_deg`` (optional, (0, 20]) is its 1-sigma per axis: the page sends 1.5 for a
reading of the phone's motion sensors in the hand (the hypotheses service refines it by the
photo's lines, weighing it so), nothing for a typed one (the frame's default, 0.5).
``heading_deg`` (optional, finite) is which way the camera looked, turned about gravity,
growing to the right, for the plan: the page sends its motion sensors' reading with a live
capture (settings.js), and a gallery photo's EXIF compass bearing. ``heading_sigma_deg`` is
its 1-sigma in (0, 90] (default 10, a compass's 30); ``heading_ref`` what it is measured
from (``Frame.heading_ref``: none for the page's sensors, "T" / "M" / "?" for a compass).
Without a heading, the photo file's own EXIF bearing (GPSImgDirection) goes into the Frame.
``camera_height_m`` is metres above the floor; ``capture_time_ms`` is Unix milliseconds (the
server's clock is used instead when it is more than a day off).

A JPEG with an EXIF rotation is decoded upright and re-encoded (quality 95) so that the
frame's pixels are the ones the browser shows and taps refer to. Pixels follow the bus
convention: (0, 0) is the centre of the top-left pixel.

A measure's ``surfaces`` (optional) says, per pixel, the surface the user tapped: null (as
the chosen boundary says), "floor" (on the floor whatever the boundary says, below the
horizon), "wall" (no point where the boundary puts the floor, saying what to do) or "top" (on
the top of what stands on the floor line below it, or no point with the reason); the session
passes them on as the MeasureRequest's ``said``.

Pure functions: no bus, no server. The text commands' parse is ``page_command``'s.
"""

from __future__ import annotations

import json
import math
import re
import struct
import time

import schemas
from findme_io.imageio import MAX_PIXELS, _declared_size, decode_image, decode_photo, encode_jpeg
from findme_core.errors import CameraError, FindmeError, ImageError, InputError
from findme_core.single import scene

from findme_io.convert import image_format, make_frame
from findme_io.frame_photo import EXIF_HEADING_SIGMA_RAD, exif_heading, frame_camera

#: Largest photo a page may upload (bytes). Below the bus's 16 MB message limit, with room
#: for the rest of the Frame.
MAX_UPLOAD_BYTES = 15 * 1024 * 1024
MAX_HEADER_BYTES = 16 * 1024
MAX_TEXT_BYTES = 64 * 1024
MAX_MEASURE_PIXELS = 64        # per measure query
#: JSON from a page: nesting (the commands are 3 deep) and characters of one number (a
#: double needs 24), checked on the raw text BEFORE parsing: Python's parser recurses per
#: level (RecursionError) and refuses integers over 4300 digits (ValueError).
MAX_JSON_DEPTH = 8
MAX_NUMBER_CHARS = 40
#: 35 mm film diagonal (mm): a "35 mm-equivalent focal length" is relative to it.
FILM_DIAGONAL_MM = math.hypot(36.0, 24.0)
#: An uploaded JPEG is checked by decoding it at the reduction that keeps this long side
#: (``imageio.reduction``: at most an eighth): every byte is read, a fraction decoded.
CHECK_SIZE = 16
CODE = schemas.ErrorCode
#: What a page may say a tapped pixel is on (null: as the boundary says).
SURFACES = (None, *scene.SURFACES)


class GatewayError(FindmeError):
    """Refused page input, with the Error code the page gets."""

    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


def _bad(message: str, code: int = CODE.ERROR_CODE_MALFORMED) -> GatewayError:
    return GatewayError(code, message)


# strings (an unterminated one runs to the end: one pass, no backtracking), brackets, numbers
_JSON_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"?|[\[{\]}]|-?[0-9][0-9.eE+-]*')


def _no_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


def loads_bounded(text: str, what: str = "message"):
    """``json.loads`` of page text whose nesting (``MAX_JSON_DEPTH``) and number literals
    (``MAX_NUMBER_CHARS``) are checked first; NaN and Infinity are refused.

    Raises:
        GatewayError: MALFORMED (not JSON, nested too deep) or TOO_LARGE (a huge number).
    """
    depth = 0
    for m in _JSON_TOKENS.finditer(text):
        t = m.group()
        if t in "[{":
            depth += 1
            if depth > MAX_JSON_DEPTH:
                raise _bad(f"{what} is nested more than {MAX_JSON_DEPTH} levels deep")
        elif t in "]}":
            depth -= 1
        elif t[0] != '"' and len(t) > MAX_NUMBER_CHARS:
            raise _bad(f"{what} has a number of {len(t)} characters (at most "
                       f"{MAX_NUMBER_CHARS})", CODE.ERROR_CODE_TOO_LARGE)
    try:
        return json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError) as e:   # JSONDecodeError is a ValueError
        raise _bad(f"{what} is not valid JSON ({str(e)[:80]})") from None


def parse_upload(data: bytes, max_bytes: int = MAX_UPLOAD_BYTES) -> tuple[dict, bytes]:
    """Split a binary upload ``[u32 big-endian n][n bytes UTF-8 JSON header][image]``."""
    if len(data) < 4:
        raise _bad("upload is too short to carry a header and a photo")
    n = struct.unpack(">I", data[:4])[0]
    if n > MAX_HEADER_BYTES or 4 + n > len(data):
        raise _bad(f"upload header length {n} is not valid")
    try:
        text = data[4:4 + n].decode("utf-8")
    except UnicodeDecodeError:
        raise _bad("upload header is not valid UTF-8 JSON") from None
    header = loads_bounded(text, "upload header")
    if not isinstance(header, dict):
        raise _bad("upload header must be a JSON object")
    image = data[4 + n:]
    if not image:
        raise _bad("the upload carries no photo (empty file)", CODE.ERROR_CODE_BAD_IMAGE)
    if len(image) > max_bytes:
        raise _bad(f"photo is {len(image) / 1e6:.1f} MB, over the {max_bytes / 1e6:.0f} MB limit",
                   CODE.ERROR_CODE_TOO_LARGE)
    return header, image


def _number(h: dict, name: str, lo: float, hi: float, what: str) -> float | None:
    v = h.get(name)
    if v is None or v == "":
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _bad(f"{what} must be a number, got {v!r}", CODE.ERROR_CODE_BAD_CAMERA)
    if not lo < v <= hi:
        raise _bad(f"{what} must be in ({lo:g}, {hi:g}], got {v:g}", CODE.ERROR_CODE_BAD_CAMERA)
    return float(v)


def _vector(v, n: int, what: str) -> tuple[float, ...]:
    if (not isinstance(v, list) or len(v) != n or
            not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                    for x in v)):
        raise _bad(f"{what} must be {n} finite numbers, got {v!r}", CODE.ERROR_CODE_BAD_CAMERA)
    return tuple(float(x) for x in v)


def _exif_rotated(data: bytes) -> bool:
    """True when a JPEG's EXIF orientation is not 'upright' (1 or missing)."""
    if not data.startswith(b"\xff\xd8"):
        return False
    i = 2
    while i + 4 <= len(data) and data[i] == 0xFF:
        marker, seg = data[i + 1], int.from_bytes(data[i + 2:i + 4], "big")
        if marker == 0xE1 and data[i + 4:i + 10] == b"Exif\x00\x00":
            t = data[i + 10:i + 2 + seg]
            if len(t) < 8 or t[:2] not in (b"II", b"MM"):
                return False
            end = "little" if t[:2] == b"II" else "big"
            ifd = int.from_bytes(t[4:8], end)
            if ifd + 2 > len(t):
                return False
            for k in range(int.from_bytes(t[ifd:ifd + 2], end)):
                e = ifd + 2 + 12 * k
                if e + 12 > len(t):
                    return False
                if int.from_bytes(t[e:e + 2], end) == 0x0112:
                    return int.from_bytes(t[e + 8:e + 10], end) not in (0, 1)
            return False
        if marker == 0xDA:   # start of scan: no more headers
            return False
        i += 2 + seg
    return False


def checked_image(image: bytes, max_pixels: int = MAX_PIXELS):
    """(bytes to publish, width, height, re-encoded?, ``ExifInfo`` or None) of an uploaded
    photo.

    Refuses other formats than JPEG/PNG/WebP, more than ``max_pixels`` (from the header,
    before decoding), and undecodable data. An EXIF-rotated JPEG comes back upright.
    """
    try:
        image_format(image)
    except ImageError:
        raise _bad("the file is not an image the server reads (JPEG, PNG or WebP)",
                   CODE.ERROR_CODE_BAD_IMAGE) from None
    w, h = _declared_size(image)
    if w * h > max_pixels:
        raise _bad(f"photo is {w}x{h} = {w * h / 1e6:.0f} MP, over the {max_pixels / 1e6:.0f} MP "
                   "limit", CODE.ERROR_CODE_TOO_LARGE)
    rotated = _exif_rotated(image)
    try:   # checked whole at an eighth of its size (DCT scaling: every byte still read)
        # unless it must be re-encoded upright
        photo = decode_photo(image, "photo", max_bytes=len(image) + 1, max_pixels=max_pixels,
                             reduce_to=None if rotated else CHECK_SIZE)
    except ImageError as e:
        code = CODE.ERROR_CODE_TOO_LARGE if "limit" in str(e) else CODE.ERROR_CODE_BAD_IMAGE
        raise _bad(str(e), code) from None
    W, H = photo.width, photo.height
    if rotated or (w and h and (w, h) != (W, H)):
        img = photo.image if photo.scale == 1.0 else decode_image(
            image, "photo", max_bytes=len(image) + 1, max_pixels=max_pixels)
        return encode_jpeg(img, 95), W, H, True, photo.exif
    return image, W, H, False, photo.exif


def build_frame(session: str, index: int, header: dict, image: bytes,
                now_ns: int | None = None):
    """(Frame, info for the page) from a parsed upload; GatewayError if anything is off."""
    data, W, H, reencoded, exif = checked_image(image)
    lens = header.get("lens") or {}
    if not isinstance(lens, dict):
        raise _bad(f"lens must be an object, got {lens!r}", CODE.ERROR_CODE_BAD_CAMERA)
    kind = lens.get("kind", "default")
    intrinsics = hfov = None
    if kind == "intrinsics":
        fx, fy, cx, cy = (_number(lens, k, 0 if k[0] == "f" else -1e6, 1e6, k) for k in
                          ("fx", "fy", "cx", "cy"))
        if None in (fx, fy, cx, cy):
            raise _bad("intrinsics need fx, fy, cx and cy (pixels)", CODE.ERROR_CODE_BAD_CAMERA)
        seen = (lens.get("width"), lens.get("height"))
        if None not in seen and tuple(seen) != (W, H):
            raise _bad(f"intrinsics were given for a {seen[0]}x{seen[1]} photo but the photo is "
                       f"{W}x{H}", CODE.ERROR_CODE_BAD_CAMERA)
        intrinsics = (fx, fy, cx, cy, W, H)
    elif kind == "hfov":
        hfov = _number(lens, "hfov_deg", 0, 179.9, "field of view (degrees)")
    elif kind == "focal35":
        f35 = _number(lens, "focal35_mm", 1, 2000, "35 mm-equivalent focal length (mm)")
        if f35 is not None:
            f_px = f35 * math.hypot(W, H) / FILM_DIAGONAL_MM
            hfov = math.degrees(2 * math.atan(W / (2 * f_px)))
    elif kind != "default":
        raise _bad(f"lens kind {kind!r} is not one of default, hfov, focal35, intrinsics",
                   CODE.ERROR_CODE_BAD_CAMERA)
    gravity = header.get("gravity")
    if gravity is not None:
        gravity = _vector(gravity, 3, "gravity")
        if math.hypot(*gravity) < 1e-3:
            raise _bad("gravity must not be the zero vector", CODE.ERROR_CODE_BAD_CAMERA)
    sigma = _number(header, "gravity_sigma_deg", 0, 20, "gravity's 1-sigma (degrees)")
    heading = _number(header, "heading_deg", -1e6, 1e6, "heading (degrees)")
    h_sigma = _number(header, "heading_sigma_deg", 0, 90, "heading's 1-sigma (degrees)")
    h_ref = header.get("heading_ref") or ""
    if not isinstance(h_ref, str) or h_ref not in schemas.HEADING_REFS:
        raise _bad(f"heading_ref must be one of T, M, ? (or none), got {str(h_ref)[:20]!r}",
                   CODE.ERROR_CODE_BAD_CAMERA)
    if heading is None:    # the file's compass bearing, kept when the photo was re-encoded
        told = exif_heading(exif)
        if told is not None:
            heading, h_sigma, h_ref = math.degrees(told[0]), math.degrees(told[1]), told[2]
    elif h_ref and h_sigma is None:     # a compass's, as the page read it from the file
        h_sigma = math.degrees(EXIF_HEADING_SIGMA_RAD)
    height = _number(header, "camera_height_m", 0, 100, "camera height (m)")
    device = header.get("device") or ""
    device = "web" + (": " + "".join(c for c in str(device) if c.isprintable())[:80]
                      if device else "")
    now = time.time_ns() if now_ns is None else now_ns
    t = header.get("capture_time_ms")
    t_ns = int(t * 1e6) if isinstance(t, (int, float)) and not isinstance(t, bool) \
        and math.isfinite(t) and abs(t * 1e6 - now) < 86400e9 else now
    frame = make_frame(session, index, data, intrinsics=intrinsics, hfov_deg=hfov,
                       gravity=gravity, camera_height_m=height, device=device, time_ns=t_ns,
                       gravity_sigma_rad=None if sigma is None or gravity is None
                       else math.radians(sigma),
                       heading_rad=None if heading is None else math.radians(heading % 360.0),
                       heading_sigma_rad=None if h_sigma is None else math.radians(h_sigma),
                       heading_ref=h_ref if heading is not None else "")
    try:
        cam = frame_camera(frame, W, H)
    except (CameraError, InputError) as e:
        raise _bad(str(e), CODE.ERROR_CODE_BAD_CAMERA) from None
    info = {"index": index, "width": W, "height": H, "bytes": len(data), "reencoded": reencoded,
            "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
            "gravity": [float(x) for x in cam.gravity], "camera_height_m": height,
            "heading_deg": None if heading is None else heading % 360.0,
            "heading_ref": frame.heading_ref}
    return frame, info
