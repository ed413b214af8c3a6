"""When a photo or a video frame was taken, as int ns since the Unix epoch (UTC).

* Photos: EXIF ``DateTimeOriginal`` (tag 0x9003 of the Exif IFD), with
  ``SubSecTimeOriginal`` (0x9291) for the fraction of a second and ``OffsetTimeOriginal``
  (0x9011, e.g. "+02:00") for the time zone. A camera writes its local wall-clock time; with
  no offset tag it is read in this machine's time zone (``TZ``), which is right when the
  photos are processed where they were taken. Read with Pillow's ``getexif`` (JPEG, PNG,
  WebP, TIFF), headers only: the pixels are not decoded.
* Videos: the creation time of an MP4 / QuickTime file (``moov/mvhd``, seconds since
  1904-01-01 UTC, what phones write when recording starts); a frame's time is that plus the
  frame's position in the video.

``None`` whenever the file does not say (no EXIF, no date, a malformed or zero value): the
caller decides what to use instead (services/pipeline/capture.py stamps the frame when it
takes the photo in, in capture order).
"""

from __future__ import annotations

import datetime as dt
import io
import struct

_EXIF_IFD = 0x8769
_DATETIME_ORIGINAL, _OFFSET_ORIGINAL, _SUBSEC_ORIGINAL = 0x9003, 0x9011, 0x9291
_MP4_EPOCH = dt.datetime(1904, 1, 1, tzinfo=dt.timezone.utc)


def exif_time_ns(data: bytes) -> int | None:
    """Capture time from a photo's EXIF (see the module docstring), or None."""
    from PIL import Image, UnidentifiedImageError
    try:
        with Image.open(io.BytesIO(data)) as im:
            ifd = im.getexif().get_ifd(_EXIF_IFD)
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError, struct.error):
        return None     # not an image Pillow reads, or broken EXIF: no capture time in it
    return parse_exif_time(ifd.get(_DATETIME_ORIGINAL), ifd.get(_SUBSEC_ORIGINAL),
                           ifd.get(_OFFSET_ORIGINAL))


def _text(v) -> str:
    if isinstance(v, bytes):
        v = v.decode("ascii", "replace")
    return str(v).strip().strip("\x00").strip() if v is not None else ""


def parse_exif_time(stamp, subsec=None, offset=None) -> int | None:
    """ns since the epoch from EXIF strings ``"YYYY:MM:DD HH:MM:SS"``, ``"123"`` (fraction
    digits) and ``"+HH:MM"``; None when the stamp is missing or not a real date."""
    try:
        t = dt.datetime.strptime(_text(stamp), "%Y:%m:%d %H:%M:%S")
    except ValueError:
        return None     # "0000:00:00 00:00:00" (unset) and anything else that is not a date
    off = _text(offset)
    if off:
        try:
            t = t.replace(tzinfo=dt.datetime.strptime(off, "%z").tzinfo)
        except ValueError:
            off = ""
    if not off:
        t = t.astimezone()      # naive: this machine's local time zone
    frac = "".join(c for c in _text(subsec) if c.isdigit())[:9]
    ns = int((frac + "000000000")[:9]) if frac else 0
    sec = int(t.timestamp())
    return sec * 1_000_000_000 + ns if sec > 0 else None


def _boxes(f, end: int):
    """(type, payload start, payload end) of the ISO-BMFF boxes from f's position to end."""
    while f.tell() + 8 <= end:
        start = f.tell()
        size, kind = struct.unpack(">I4s", f.read(8))
        head = 8
        if size == 1:
            size, head = struct.unpack(">Q", f.read(8))[0], 16
        elif size == 0:
            size = end - start
        if size < head or start + size > end:
            return
        yield kind, start + head, start + size
        f.seek(start + size)


def video_start_ns(path) -> int | None:
    """Creation time of an MP4 / QuickTime file (``moov/mvhd``), or None."""
    try:
        with open(path, "rb") as f:
            f.seek(0, io.SEEK_END)
            size = f.tell()
            f.seek(0)
            for kind, a, b in _boxes(f, size):
                if kind != b"moov":
                    continue
                f.seek(a)
                for k2, a2, b2 in _boxes(f, b):
                    if k2 == b"mvhd" and b2 - a2 >= 12:
                        f.seek(a2)
                        version = f.read(1)[0]
                        f.read(3)
                        secs = (struct.unpack(">Q", f.read(8))[0] if version == 1
                                else struct.unpack(">I", f.read(4))[0])
                        if secs == 0:
                            return None
                        t = _MP4_EPOCH + dt.timedelta(seconds=secs)
                        return int(t.timestamp()) * 1_000_000_000
                return None
    except (OSError, struct.error, IndexError, OverflowError):
        return None
    return None
