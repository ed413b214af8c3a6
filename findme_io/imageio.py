"""Reading photos: bytes or files in, an upright BGR array out, with bounds and clear errors.

Decoding is Pillow's (JPEG, PNG, WebP, BMP, TIFF, AVIF) and pillow-heif's (HEIC/HEIF), not
OpenCV's: ``cv2.imdecode`` is faster on JPEG (bench/bench_decode.py: 0.7 vs 1.4 ms for
640x480, 28 vs 55 ms for 12 MP) but libjpeg/libpng print their warnings on file descriptor
2 (two to four lines per broken file where one is promised) and it reads neither HEIC nor
EXIF focal lengths.

Bounds, whatever the bytes claim (issue 11): the size, pixel count and structure checks
made before any decoder runs are ``image_format``'s; truncated data is an error (never
padded with grey), and only the first frame of an animation or multi-page file is read.

Every refusal is one ``ImageError`` naming the file; the C libraries print nothing and
Pillow's own warnings (EXIF, decompression bomb) are caught, not printed. EXIF orientation
is applied (pixels come out as every viewer shows them) and the EXIF block is parsed for
the camera (``findme_io.exif``); a broken EXIF block never fails a photo.
"""

from __future__ import annotations

import functools
import io
import os
import threading
import time
import warnings
from dataclasses import dataclass, field

import cv2
import numpy as np

from findme_core.errors import ImageError

# the checks before decoding live in ``image_format``; re-exported here, where they began
from .image_format import (_PIL_FORMATS, MAX_BYTES, MAX_JPEG_SCANS, MAX_PIXELS,  # noqa: F401
                           MAX_PNG_CHUNKS, NAMES, check_encoded, declared_size, sniff)

_declared_size = declared_size   # its old name (services/web/page_input imports it)

_STATS_LOCK = threading.Lock()
_STATS = {"image_decodes": 0, "image_decode_us": 0, "image_decoded_kpx": 0, "image_probes": 0}


def decode_stats() -> dict[str, int]:
    """This process's decoding so far (a service's status shows them): photos decoded,
    microseconds of wall time spent decoding, thousands of pixels decoded, header probes."""
    with _STATS_LOCK:
        return dict(_STATS)


def _count(**add) -> None:
    with _STATS_LOCK:
        for k, v in add.items():
            _STATS[k] += int(v)


@dataclass(frozen=True)
class Photo:
    """A decoded photo.

    Attributes:
        image: (h, w, 3) uint8 BGR, upright (EXIF orientation applied); decoded at a reduced
            size when asked (``decode_photo(reduce_to=...)``): then ``scale`` < 1.
        format: "jpeg", "png", "webp", "heif", "avif", "bmp" or "tiff".
        exif: what the EXIF block says about the camera (``findme_io.exif.ExifInfo``).
        scale: ``image``'s pixels per pixel of the photo (1, 1/2, 1/4 or 1/8): a pixel
            (u, v) of the photo is (u', v') = ((u + 0.5) * scale - 0.5, (v + 0.5) * scale -
            0.5) of ``image`` (JPEG DCT scaling averages each k x k block).
        size: (W, H) of the photo, upright (``image``'s when ``scale`` is 1).
    """

    image: np.ndarray
    format: str
    exif: object = field(default=None)
    scale: float = 1.0
    size: tuple[int, int] | None = None

    @property
    def width(self) -> int:
        return self.size[0] if self.size else self.image.shape[1]

    @property
    def height(self) -> int:
        return self.size[1] if self.size else self.image.shape[0]


def reduction(width: int, height: int, work_size: int) -> int:
    """The JPEG DCT scaling factor k (1, 2, 4 or 8) to decode a ``width`` x ``height`` photo
    at: the largest that keeps its long side at least ``work_size`` pixels (a 4032x3024
    photo for a 640 px working size: 4, 1008x756; a 1600 or 1280 px one: 2; under 1280 px:
    1, so a photo under twice the working size is decoded whole) and its short side at
    least 16 pixels."""
    k = 1
    while k < 8 and max(width, height) / (2 * k) >= work_size and min(width, height) / (2 * k) >= 16:
        k *= 2
    return k


@functools.cache
def _pillow():
    """Pillow with the HEIF opener registered (once, on first use: no import-time side
    effects)."""
    from PIL import Image
    import pillow_heif
    pillow_heif.register_heif_opener(thumbnails=False, depth_images=False, aux_images=False)
    return Image


def _to_bgr(im) -> np.ndarray:
    """A loaded Pillow image of any mode -> (H, W, 3) uint8 BGR."""
    mode = im.mode
    if mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        a = np.asarray(im, dtype=np.float64)
        top = 65535.0 if mode.startswith("I;16") or a.max(initial=0) > 255 else 255.0
        g = np.clip(a * (255.0 / top), 0, 255).astype(np.uint8)
        return cv2.cvtColor(g, cv2.COLOR_GRAY2BGR)
    if mode == "L":
        return cv2.cvtColor(np.asarray(im), cv2.COLOR_GRAY2BGR)
    if mode != "RGB":
        im = im.convert("RGBA" if "A" in mode or mode in ("P", "PA") else "RGB")
        if im.mode == "RGBA":   # alpha dropped, as OpenCV's IMREAD_COLOR did
            return cv2.cvtColor(np.asarray(im), cv2.COLOR_RGBA2BGR)
    return cv2.cvtColor(np.asarray(im), cv2.COLOR_RGB2BGR)


#: EXIF orientation -> the cv2 operations that make the stored pixels upright.
_UPRIGHT = {2: ("flip", 1), 3: ("rot", cv2.ROTATE_180), 4: ("flip", 0),
            5: ("transpose", None), 6: ("rot", cv2.ROTATE_90_CLOCKWISE),
            7: ("transverse", None), 8: ("rot", cv2.ROTATE_90_COUNTERCLOCKWISE)}


def upright(image: np.ndarray, orientation: int) -> np.ndarray:
    """Apply an EXIF orientation (1-8) to stored pixels: the image as viewers show it."""
    op = _UPRIGHT.get(int(orientation))
    if op is None:
        return image
    kind, arg = op
    if kind == "flip":
        return cv2.flip(image, arg)
    if kind == "rot":
        return cv2.rotate(image, arg)
    t = cv2.transpose(image)                 # 5: transpose (mirror about the main diagonal)
    return cv2.rotate(t, cv2.ROTATE_180) if kind == "transverse" else t


def decode_photo(data: bytes, name: str = "image", max_bytes: int = MAX_BYTES,
                 max_pixels: int = MAX_PIXELS, reduce_to: int | None = None) -> Photo:
    """Decode encoded image bytes to an upright BGR ``Photo`` with its EXIF camera facts.

    reduce_to: a JPEG is decoded at 1/k of its size (libjpeg's DCT scaling: much cheaper
        than decoding it whole, and every byte of it is still read and checked), k from
        ``reduction(W, H, reduce_to)``; ``Photo.scale`` says by how much. Other formats and
        None: the whole photo.

    Raises:
        ImageError: empty, oversized, not an image, corrupt, truncated, too many pixels,
            too small, or a structure that would make decoding unbounded.
    """
    from .exif import read_exif
    t0 = time.perf_counter()
    kind = check_encoded(data, name, max_bytes, max_pixels)
    Image = _pillow()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # Pillow's EXIF/bomb warnings: we check ourselves
        try:
            im = Image.open(io.BytesIO(data), formats=_PIL_FORMATS[kind])
            w, h = im.size
        except Image.DecompressionBombError as e:
            raise ImageError(f"{name}: over the pixel limit ({e})") from None
        except Exception as e:   # a hostile header can raise anything inside the parser
            raise ImageError(f"{name}: corrupt or unsupported {kind.upper()} data "
                             f"({_why(e)})") from None
        if w * h > max_pixels:
            raise ImageError(f"{name}: {w}x{h} = {w * h / 1e6:.0f} MP is over the "
                             f"{max_pixels / 1e6:.0f} MP limit")
        info = read_exif(im, kind)
        k = reduction(w, h, reduce_to) if reduce_to and kind == "jpeg" else 1
        try:
            im.seek(0)
            if k > 1:
                im.draft("RGB", (w // k, h // k))
                if im.size != (-(-w // k), -(-h // k)):   # not drafted (e.g. several tiles)
                    k = 1 if im.size == (w, h) else 0
                if k == 0:
                    raise ValueError(f"the decoder gave {im.size[0]}x{im.size[1]} for a "
                                     f"{w}x{h} photo reduced")
            im.load()
            image = _to_bgr(im)
        except Exception as e:   # truncated or corrupt pixel data, whatever the decoder
            raise ImageError(f"{name}: corrupt or truncated {kind.upper()} data "
                             f"({_why(e)})") from None
        finally:
            im.close()
    turn = info.orientation if info.orientation_applies else 1
    image = upright(image, turn)
    _count(image_decodes=1, image_decode_us=1e6 * (time.perf_counter() - t0),
           image_decoded_kpx=image.shape[0] * image.shape[1] / 1e3)
    size = (h, w) if turn in (5, 6, 7, 8) else (w, h)
    if min(size) < 16:
        raise ImageError(f"{name}: {size[0]}x{size[1]} is too small to measure in")
    return Photo(image, kind, info, 1.0 / k, size)


def _why(e: Exception) -> str:
    text = " ".join(str(e).replace("<_io.BytesIO object", "<").split())[:160]
    if type(e).__name__ == "UnidentifiedImageError":
        return "the decoder does not recognise it"
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def decode_image(data: bytes, name: str = "image", max_bytes: int = MAX_BYTES,
                 max_pixels: int = MAX_PIXELS) -> np.ndarray:
    """Decode image bytes to an (H, W, 3) uint8 BGR array, upright (see ``decode_photo``).

    Raises:
        ImageError: empty, oversized, not an image, corrupt, or too many pixels.
    """
    return decode_photo(data, name, max_bytes, max_pixels).image


def _read_bytes(path, limits) -> tuple[str, bytes]:
    p = os.fspath(path)
    if not os.path.exists(p):
        raise ImageError(f"{p}: no such file")
    if os.path.isdir(p):
        raise ImageError(f"{p}: is a directory, not an image")
    size = os.path.getsize(p)
    if size > limits.get("max_bytes", MAX_BYTES):
        raise ImageError(f"{p}: {size / 1e6:.1f} MB is over the "
                         f"{limits.get('max_bytes', MAX_BYTES) / 1e6:.0f} MB limit")
    try:
        with open(p, "rb") as f:
            return p, f.read()
    except OSError as e:
        raise ImageError(f"{p}: cannot read it ({e.strerror})") from None


def read_photo(path: str | os.PathLike, **limits) -> Photo:
    """Read an image file (see ``decode_photo``)."""
    p, data = _read_bytes(path, limits)
    return decode_photo(data, p, **limits)


def read_image(path: str | os.PathLike, **limits) -> np.ndarray:
    """Read an image file (see ``decode_image``)."""
    return read_photo(path, **limits).image


#: Formats a bus Frame may carry as they are (Foxglove's CompressedImage names).
BUS_FORMATS = ("jpeg", "png", "webp")


def for_bus(data: bytes, name: str = "image") -> tuple[bytes, dict]:
    """(bytes a Frame can carry, lens facts) of a photo: JPEG, PNG and WebP as they are (the
    server reads their EXIF); any other format (HEIC, AVIF, BMP, TIFF) decoded, turned
    upright and re-encoded as JPEG (quality 95), with its EXIF focal length returned as
    ``{"intrinsics": {fx, fy, cx, cy, width, height}}``; the JPEG's EXIF holds only its
    compass bearing (GPSImgDirection and its reference) when the photo had one.

    Raises:
        ImageError: as ``decode_photo``.
    """
    if sniff(data) in BUS_FORMATS:
        return data, {}
    from .exif import focal_px
    photo = decode_photo(data, name)
    H, W = photo.image.shape[:2]
    f, _, _ = focal_px(photo.exif, W, H) if photo.exif is not None else (None, "", [])
    lens = {} if f is None else {"intrinsics": {"fx": f[0], "fy": f[1], "cx": (W - 1) / 2.0,
                                                "cy": (H - 1) / 2.0, "width": W, "height": H}}
    info = photo.exif
    if info is None or info.heading_deg is None:
        return encode_jpeg(photo.image, 95), lens
    from .exif import direction_block
    out = io.BytesIO()
    _pillow().fromarray(photo.image[:, :, ::-1]).save(
        out, "JPEG", quality=95, exif=direction_block(info.heading_deg, info.heading_ref))
    return out.getvalue(), lens


def encode_jpeg(image: np.ndarray, quality: int = 90) -> bytes:
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ImageError("JPEG encoding failed")
    return buf.tobytes()


def encode_png(image: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise ImageError("PNG encoding failed")
    return buf.tobytes()


def probe(data: bytes, name: str = "image"):
    """(width, height, ExifInfo) of encoded image bytes as ``decode_photo`` returns them
    (upright), from the header and the EXIF block without decoding the pixels when the
    header can be read (else by decoding, which raises ImageError for bad data)."""
    from .exif import ExifInfo, read_exif
    _count(image_probes=1)
    kind = sniff(data)
    if kind is not None:
        Image = _pillow()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                with Image.open(io.BytesIO(data), formats=_PIL_FORMATS[kind]) as im:
                    w, h = im.size
                    info = read_exif(im, kind)
                if w * h <= MAX_PIXELS and min(w, h) >= 16:
                    turned = info.orientation_applies and info.transposed
                    return (h, w, info) if turned else (w, h, info)
            except Exception:   # noqa: BLE001 - unreadable header: decoding below says why
                pass
    photo = decode_photo(data, name)
    return photo.image.shape[1], photo.image.shape[0], photo.exif or ExifInfo()


def image_size(data: bytes, name: str = "image") -> tuple[int, int]:
    """(width, height) of encoded image bytes as ``decode_image`` returns them (upright)."""
    w, h, _ = probe(data, name)
    return w, h
