"""Reading photos: bytes or files in, a BGR array out, with limits and clear errors."""

from __future__ import annotations

import os

import cv2
import numpy as np

from findme_core.errors import ImageError

#: Largest accepted encoded file and decoded image (a 48 MP phone photo fits).
MAX_BYTES = 64 * 1024 * 1024
MAX_PIXELS = 50_000_000

_MAGIC = (b"\xff\xd8\xff", b"\x89PNG\r\n\x1a\n", b"BM", b"RIFF", b"II*\x00", b"MM\x00*")


def decode_image(data: bytes, name: str = "image", max_bytes: int = MAX_BYTES,
                 max_pixels: int = MAX_PIXELS) -> np.ndarray:
    """Decode JPEG/PNG/BMP/WebP/TIFF bytes to an (H, W, 3) uint8 BGR array.

    Raises:
        ImageError: empty, oversized, not an image, corrupt, or too many pixels.
    """
    if not data:
        raise ImageError(f"{name}: empty file")
    if len(data) > max_bytes:
        raise ImageError(f"{name}: {len(data) / 1e6:.1f} MB is over the {max_bytes / 1e6:.0f} MB limit")
    if not data.startswith(_MAGIC):
        raise ImageError(f"{name}: not an image (expected JPEG, PNG, BMP, WebP or TIFF)")
    buf = np.frombuffer(data, np.uint8)
    # check the declared size before decoding the pixels (a small file can claim 100k x 100k)
    w, h = _declared_size(data)
    if w and h and w * h > max_pixels:
        raise ImageError(f"{name}: {w}x{h} = {w * h / 1e6:.0f} MP is over the "
                         f"{max_pixels / 1e6:.0f} MP limit")
    img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    if img is None:
        raise ImageError(f"{name}: corrupt or unsupported image data")
    if img.shape[0] * img.shape[1] > max_pixels:
        raise ImageError(f"{name}: {img.shape[1]}x{img.shape[0]} is over the "
                         f"{max_pixels / 1e6:.0f} MP limit")
    if min(img.shape[:2]) < 16:
        raise ImageError(f"{name}: {img.shape[1]}x{img.shape[0]} is too small to measure in")
    return img


def read_image(path: str | os.PathLike, **limits) -> np.ndarray:
    """Read an image file (see ``decode_image``)."""
    p = os.fspath(path)
    if not os.path.exists(p):
        raise ImageError(f"{p}: no such file")
    if os.path.isdir(p):
        raise ImageError(f"{p}: is a directory, not an image")
    size = os.path.getsize(p)
    if size > limits.get("max_bytes", MAX_BYTES):
        raise ImageError(f"{p}: {size / 1e6:.1f} MB is over the "
                         f"{limits.get('max_bytes', MAX_BYTES) / 1e6:.0f} MB limit")
    with open(p, "rb") as f:
        return decode_image(f.read(), p, **limits)


def _declared_size(data: bytes) -> tuple[int, int]:
    """(width, height) from a PNG or JPEG header, (0, 0) if not found."""
    if data.startswith(b"\x89PNG") and len(data) >= 24:
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if data.startswith(b"\xff\xd8"):
        i = 2
        while i + 9 < len(data):
            if data[i] != 0xFF:
                i += 1
                continue
            marker = data[i + 1]
            if marker in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
                return (int.from_bytes(data[i + 7:i + 9], "big"),
                        int.from_bytes(data[i + 5:i + 7], "big"))
            if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
                i += 2
                continue
            i += 2 + int.from_bytes(data[i + 2:i + 4], "big")
    return 0, 0


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


def image_size(data: bytes, name: str = "image") -> tuple[int, int]:
    """(width, height) of encoded image bytes as ``decode_image`` returns them: from the
    header when possible; a JPEG with EXIF data may be stored rotated (decode_image applies
    the orientation, as every viewer does), so it is decoded to be sure."""
    w, h = _declared_size(data)
    if w and h and not (data.startswith(b"\xff\xd8") and b"Exif\x00\x00" in data[:65536]):
        return w, h
    img = decode_image(data, name)
    return img.shape[1], img.shape[0]
