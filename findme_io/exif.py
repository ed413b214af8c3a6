"""What a photo's EXIF block says about its camera: orientation, focal length and heading.

Parsing is Pillow's (``Image.getexif``; pillow-heif fills it for HEIC), never by hand. A
broken block (truncated, bad offsets, values of the wrong type or out of range) is ignored
with the reason in ``ExifInfo.notes``: it never fails a photo.

Focal length in pixels of the UPRIGHT image (width x height after the orientation):

* ``FocalLength`` (mm) with ``FocalPlaneXResolution`` / ``FocalPlaneYResolution`` (sensor
  pixels per ``FocalPlaneResolutionUnit``: 2 inch, 3 cm, 4 mm, 5 micrometre) gives fx, fy of
  the stored pixels at ``PixelXDimension`` x ``PixelYDimension`` (the stored image size when
  absent), scaled to the actual size and swapped for a transposing orientation (5-8);
* else ``FocalLengthIn35mmFilm`` (mm, relative to the 36 x 24 mm frame's diagonal of
  43.27 mm, CIPA DC-008): f_px = f35 * diagonal_px / 43.27 (the diagonal does not depend on
  the orientation), fx = fy;
* else nothing (a bare ``FocalLength`` without the sensor's size gives no pixels).

Heading: ``GPSImgDirection`` (GPS IFD, degrees in [0, 360), the bearing the camera looked
along, from the phone's compass when the photo was taken) with ``GPSImgDirectionRef`` ("T":
from true north, "M": from magnetic north; absent: not said). Indoors a compass is off by
10-30 deg and more near steel; ``plan.heading`` compares only headings from one reference.

``read_exif`` is the one EXIF reader of the package (the capture-time reader can use
``exif_tags`` for other tags).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Diagonal of the 36 x 24 mm frame a 35 mm-equivalent focal length refers to, mm.
FILM_DIAGONAL_MM = math.hypot(36.0, 24.0)
#: FocalPlaneResolutionUnit -> millimetres per unit (EXIF 2.3: 2 inch, 3 cm; EXIF 3.0 adds
#: 4 mm and 5 micrometre).
UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}
#: Accepted horizontal fields of view from EXIF, degrees: outside is a broken tag, not a lens.
HFOV_RANGE_DEG = (10.0, 150.0)

_ORIENTATION, _EXIF_IFD = 0x0112, 0x8769
_FOCAL, _FOCAL35 = 0x920A, 0xA405
_FP_XRES, _FP_YRES, _FP_UNIT = 0xA20E, 0xA20F, 0xA210
_PIX_X, _PIX_Y = 0xA002, 0xA003
_GPS_IFD, _IMG_DIR_REF, _IMG_DIR = 0x8825, 0x0010, 0x0011


@dataclass(frozen=True)
class ExifInfo:
    """Camera facts of one photo's EXIF block.

    Attributes:
        orientation: EXIF orientation 1-8 of the stored pixels (1 when absent or invalid).
        orientation_applies: False when the decoder has already turned the pixels upright
            (HEIF: libheif applies the file's rotation and reports orientation 1).
        focal_mm: FocalLength, mm (> 0) or None.
        focal35_mm: FocalLengthIn35mmFilm, mm (> 0) or None.
        plane_px_per_mm: (x, y) focal-plane resolution of the stored pixels, pixels/mm.
        plane_size: (PixelXDimension, PixelYDimension) the resolution refers to, or None.
        heading_deg: GPSImgDirection, degrees in [0, 360), or None.
        heading_ref: its GPSImgDirectionRef, "T" or "M"; "" when the file does not say.
        notes: what was ignored and why (one short sentence each).
    """

    orientation: int = 1
    orientation_applies: bool = True
    focal_mm: float | None = None
    focal35_mm: float | None = None
    plane_px_per_mm: tuple[float, float] | None = None
    plane_size: tuple[int, int] | None = None
    notes: tuple[str, ...] = ()
    heading_deg: float | None = None
    heading_ref: str = ""

    @property
    def transposed(self) -> bool:
        """True when the upright image swaps the stored image's axes (orientation 5-8)."""
        return self.orientation in (5, 6, 7, 8)


def _positive(value, name: str, notes: list) -> float | None:
    """A positive finite number from an EXIF value (int, rational, 1-tuple), else None with
    the reason in ``notes``."""
    v = value
    if isinstance(v, tuple) and len(v) == 1:
        v = v[0]
    try:
        if isinstance(v, (bytes, str, tuple, list, dict)) or isinstance(v, bool):
            raise TypeError
        x = float(v)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        notes.append(f"EXIF {name} ignored: {type(value).__name__} {str(value)[:40]!r} is not a number")
        return None
    if not math.isfinite(x) or x <= 0:
        notes.append(f"EXIF {name} ignored: {x:g} is not a positive number")
        return None
    return x


def exif_tags(im) -> tuple[dict, dict, list]:
    """(IFD0 tags, Exif sub-IFD tags, notes) of an open Pillow image; empty dicts when the
    block is missing or unreadable (the reason in notes)."""
    notes: list[str] = []
    try:
        exif = im.getexif()
        ifd0 = dict(exif)
    except Exception as e:   # noqa: BLE001 - any parser failure means "no usable EXIF"
        notes.append(f"EXIF block unreadable, ignored ({type(e).__name__})")
        return {}, {}, notes
    sub: dict = {}
    try:
        sub = dict(exif.get_ifd(_EXIF_IFD))
    except Exception as e:   # noqa: BLE001 - a broken sub-IFD: IFD0 (orientation) still counts
        notes.append(f"EXIF sub-IFD unreadable, ignored ({type(e).__name__})")
    return ifd0, sub, notes


def read_exif(im, kind: str = "") -> ExifInfo:
    """The camera facts of an open Pillow image (its EXIF block; nothing is decoded).

    Args:
        im: ``PIL.Image.Image`` just opened.
        kind: container ("heif": pixels already upright, see ``ExifInfo``).
    """
    ifd0, sub, notes = exif_tags(im)
    orientation, applies = 1, True
    if kind == "heif":
        applies = False
        orientation = im.info.get("original_orientation") or 1
    elif _ORIENTATION in ifd0:
        o = ifd0[_ORIENTATION]
        if isinstance(o, int) and not isinstance(o, bool) and 1 <= o <= 8:
            orientation = o
        else:
            notes.append(f"EXIF Orientation {str(o)[:20]!r} is not 1-8: taken as upright")
    if not isinstance(orientation, int) or not 1 <= orientation <= 8:
        orientation = 1
    f = _positive(sub[_FOCAL], "FocalLength", notes) if _FOCAL in sub else None
    f35 = _positive(sub[_FOCAL35], "FocalLengthIn35mmFilm", notes) if _FOCAL35 in sub else None
    plane = size = None
    if _FP_XRES in sub and _FP_YRES in sub:
        unit = sub.get(_FP_UNIT, 2)
        xr = _positive(sub[_FP_XRES], "FocalPlaneXResolution", notes)
        yr = _positive(sub[_FP_YRES], "FocalPlaneYResolution", notes)
        if not (isinstance(unit, int) and unit in UNIT_MM):
            notes.append(f"EXIF FocalPlaneResolutionUnit {str(unit)[:20]!r} is not a length unit: "
                         "focal-plane resolution ignored")
        elif xr and yr:
            plane = (xr / UNIT_MM[unit], yr / UNIT_MM[unit])
        px, py = sub.get(_PIX_X), sub.get(_PIX_Y)
        if all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in (px, py)):
            size = (px, py)
    heading, ref = _heading(im, notes)
    return ExifInfo(orientation, applies, f, f35, plane, size, tuple(notes), heading, ref)


def _heading(im, notes: list) -> tuple[float | None, str]:
    """(GPSImgDirection in degrees [0, 360) or None, its reference "T" | "M" | "") of an open
    Pillow image; a broken or out-of-range value is ignored with the reason in ``notes``."""
    try:
        gps = dict(im.getexif().get_ifd(_GPS_IFD))
    except Exception as e:   # noqa: BLE001 - a broken GPS IFD: the rest of the block counts
        notes.append(f"EXIF GPS IFD unreadable, ignored ({type(e).__name__})")
        return None, ""
    if _IMG_DIR not in gps:
        return None, ""
    v = gps[_IMG_DIR]
    try:
        if isinstance(v, (bytes, str, tuple, list, dict, bool)):
            raise TypeError
        d = float(v)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        notes.append(f"EXIF GPSImgDirection ignored: {type(v).__name__} {str(v)[:40]!r} is not "
                     "a number")
        return None, ""
    if not (math.isfinite(d) and 0.0 <= d <= 360.0):
        notes.append(f"EXIF GPSImgDirection ignored: {d:g} is not a bearing in [0, 360] deg")
        return None, ""
    ref = gps.get(_IMG_DIR_REF, "")
    ref = ref.strip("\x00 ").upper() if isinstance(ref, str) else ""
    if ref not in ("T", "M"):
        if ref:
            notes.append(f"EXIF GPSImgDirectionRef {ref[:10]!r} is not T or M: not said")
        ref = ""
    return d % 360.0, ref


def _hfov_ok(fx: float, width: int) -> bool:
    hfov = math.degrees(2 * math.atan(width / (2 * fx)))
    return HFOV_RANGE_DEG[0] <= hfov <= HFOV_RANGE_DEG[1]


def focal_px(info: ExifInfo, width: int, height: int) -> tuple[tuple[float, float] | None, str, list]:
    """((fx, fy) in pixels of the upright ``width`` x ``height`` image or None, how it was
    found ("focal-plane" | "35mm" | ""), notes on what was ignored)."""
    notes: list[str] = []
    if info.focal_mm and info.plane_px_per_mm:
        sw, sh = (height, width) if info.transposed else (width, height)   # stored size
        pw, ph = info.plane_size or (sw, sh)
        fxs = info.focal_mm * info.plane_px_per_mm[0] * sw / pw
        fys = info.focal_mm * info.plane_px_per_mm[1] * sh / ph
        fx, fy = (fys, fxs) if info.transposed else (fxs, fys)
        if _hfov_ok(fx, width) and 0.5 < fx / fy < 2.0:
            return (fx, fy), "focal-plane", notes
        notes.append(f"EXIF FocalLength {info.focal_mm:g} mm with the focal-plane resolution "
                     f"gives fx {fx:.0f} px, fy {fy:.0f} px: not a camera lens, ignored")
    if info.focal35_mm:
        f = info.focal35_mm * math.hypot(width, height) / FILM_DIAGONAL_MM
        if _hfov_ok(f, width):
            return (f, f), "35mm", notes
        notes.append(f"EXIF FocalLengthIn35mmFilm {info.focal35_mm:g} mm gives a field of view "
                     "outside 10-150 deg: ignored")
    return None, "", notes


def direction_block(degrees: float, ref: str = ""):
    """A ``PIL.Image.Exif`` holding only a compass bearing: GPSImgDirection ``degrees`` in
    [0, 360) and GPSImgDirectionRef ``ref`` ("T" | "M"; "" leaves it out). Nothing else of
    the GPS block (no position) is written."""
    from PIL import Image, TiffImagePlugin
    ex = Image.Exif()
    gps = ex.get_ifd(_GPS_IFD)
    gps[_IMG_DIR] = TiffImagePlugin.IFDRational(round(degrees % 360.0 * 100), 100)
    if ref:
        gps[_IMG_DIR_REF] = ref
    return ex
