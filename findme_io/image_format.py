"""What encoded image bytes are, and whether they may be decoded: the checks made before
any decoder runs (``imageio`` decodes what passes).

Bounds, whatever the bytes claim (issue 11):

* bytes: ``max_bytes``; pixels: ``max_pixels``, read from the header BEFORE any pixel is
  decoded, so memory is at most about 4 bytes x ``max_pixels`` for the decoded image plus
  its converted copy;
* structure: every PNG chunk must fit in the file (a chunk that claims 4 GB is refused, not
  read) and a PNG has at most ``MAX_PNG_CHUNKS`` chunks; a JPEG has at most
  ``MAX_JPEG_SCANS`` scans (each progressive scan is a pass over the whole image, so scans x
  pixels bounds the time).

Every refusal is one ``ImageError`` naming the file.
"""

from __future__ import annotations

from findme_core.errors import ImageError

#: Largest accepted encoded file and decoded image (a 48 MP phone photo fits).
MAX_BYTES = 64 * 1024 * 1024
MAX_PIXELS = 50_000_000
#: A JPEG scan is one pass over the image; phones write 1 (baseline) to ~10 (progressive).
MAX_JPEG_SCANS = 64
#: A PNG's chunks (encoders write 8-64 kB IDAT chunks: a 64 MB file has a few thousand).
MAX_PNG_CHUNKS = 100_000

_HEVC_BRANDS = {b"heic", b"heix", b"hevc", b"hevx", b"heim", b"heis", b"hevm", b"hevs"}
_AVIF_BRANDS = {b"avif", b"avis"}
#: Pillow format names accepted for each sniffed kind.
_PIL_FORMATS = {"jpeg": ("JPEG", "MPO"), "png": ("PNG",), "bmp": ("BMP",), "webp": ("WEBP",),
                "tiff": ("TIFF",), "heif": ("HEIF",), "avif": ("AVIF", "HEIF")}
NAMES = "JPEG, PNG, WebP, HEIC/HEIF, AVIF, BMP or TIFF"


def sniff(data: bytes) -> str | None:
    """The container kind of encoded image bytes from their magic number, or None."""
    if data.startswith(b"\xff\xd8\xff"):
        return "jpeg"
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return "png"
    if data.startswith(b"RIFF") and data[8:12] == b"WEBP":
        return "webp"
    if data.startswith(b"BM"):
        return "bmp"
    if data.startswith((b"II*\x00", b"MM\x00*")):
        return "tiff"
    if data[4:8] == b"ftyp":   # ISO base media file: the major brand, then compatible ones
        brands = {data[8:12]} | {data[i:i + 4] for i in range(16, min(len(data), 64), 4)}
        if data[8:12] in _AVIF_BRANDS or (brands & _AVIF_BRANDS and not brands & _HEVC_BRANDS):
            return "avif"
        if brands & (_HEVC_BRANDS | {b"mif1", b"msf1"}):
            return "heif"
    return None


def check_encoded(data: bytes, name: str = "image", max_bytes: int = MAX_BYTES,
                  max_pixels: int = MAX_PIXELS) -> str:
    """The kind of image ``data`` holds (``sniff``) once it passed every check that needs
    no decoder: not empty, at most ``max_bytes``, a known magic number, at most
    ``max_pixels`` by its header, and a sound PNG / JPEG structure.

    Raises:
        ImageError: naming ``name`` and what is wrong.
    """
    if not data:
        raise ImageError(f"{name}: empty file")
    if len(data) > max_bytes:
        raise ImageError(f"{name}: {len(data) / 1e6:.1f} MB is over the {max_bytes / 1e6:.0f} MB limit")
    kind = sniff(data)
    if kind is None:
        raise ImageError(f"{name}: not an image (expected {NAMES})")
    w, h = declared_size(data)   # the header's claim, before any parser runs
    if w * h > max_pixels:
        raise ImageError(f"{name}: {w}x{h} = {w * h / 1e6:.0f} MP is over the "
                         f"{max_pixels / 1e6:.0f} MP limit")
    if kind == "png":
        check_png(data, name)
    elif kind == "jpeg":
        check_jpeg(data, name)
    return kind


def check_png(data: bytes, name: str) -> None:
    """Every chunk must fit in the file: a length field is never trusted for reading."""
    i, n, end = 8, 0, len(data)
    first = True
    while i + 8 <= end:
        length = int.from_bytes(data[i:i + 4], "big")
        cid = data[i + 4:i + 8]
        if first and (cid != b"IHDR" or length != 13):
            raise ImageError(f"{name}: corrupt PNG: the first chunk is not a 13-byte IHDR")
        first = False
        if length > end - i - 12:
            raise ImageError(f"{name}: corrupt PNG: chunk {cid!r} at byte {i} claims {length} "
                             f"bytes but the file has {max(0, end - i - 12)} left")
        n += 1
        if n > MAX_PNG_CHUNKS:
            raise ImageError(f"{name}: PNG with more than {MAX_PNG_CHUNKS} chunks refused")
        if cid == b"IEND":
            return
        i += 12 + length
    if first:
        raise ImageError(f"{name}: corrupt PNG: no header chunk")


def check_jpeg(data: bytes, name: str) -> None:
    # 0xFF 0xDA is a start-of-scan marker: entropy-coded data stuffs every 0xFF as FF 00, so
    # the count is the number of scans (an EXIF thumbnail adds its own one)
    scans = data.count(b"\xff\xda")
    if scans > MAX_JPEG_SCANS:
        raise ImageError(f"{name}: JPEG with {scans} scans refused (at most {MAX_JPEG_SCANS})")


def declared_size(data: bytes) -> tuple[int, int]:
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
