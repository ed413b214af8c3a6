"""Parsing of user-facing values shared by the command line and the services.

Degrees and comma-separated numbers live here, at the edge; the core takes radians-free
plain numbers (intrinsics in pixels, unit gravity vectors).
"""

from __future__ import annotations

import argparse
import math

from findme_core.errors import CameraError, InputError
from findme_core.geometry.camera import DEFAULT_HFOV_DEG
from findme_core.geometry.provenance import INPUT_GRAVITY_SIGMA_DEG
from findme_core.single.scene import SURFACES


def floats(text: str, n: int, name: str) -> tuple[float, ...]:
    """Parse ``n`` comma-separated finite numbers, e.g. ``"1,2.5,3"``."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != n:
        raise InputError(f"{name} needs {n} comma-separated numbers, got {text!r}")
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        raise InputError(f"{name} needs {n} comma-separated numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise InputError(f"{name} must be finite numbers, got {text!r}")
    return vals


def surfaces(said: list, where: str) -> list[str | None] | None:
    """Each point's said surface checked ("floor", "wall", "top" or None); None when none is
    said."""
    bad = [x for x in said if x is not None and x not in SURFACES]
    if bad:
        raise InputError(f"{where}: a point's surface must be floor, wall or top, got "
                         f"{bad[0]!r}")
    return said if any(said) else None


def said_points(texts, name: str) -> tuple[list[tuple[float, float]], list[str | None] | None]:
    """Pixels given as ``U,V`` or ``U,V,floor|wall|top`` (the surface the user says the pixel
    is on): (pixels, the surface said of each or None; None when none was)."""
    pixels, said = [], []
    for text in texts:
        uv, _, surface = text.rpartition(",") if text.count(",") == 2 else (text, "", None)
        pixels.append(floats(uv, 2, name))
        said.append(None if surface is None else surface.strip())
    return pixels, surfaces(said, name)


def finite_float(text: str) -> float:
    """argparse type: a finite number (``nan`` and ``inf`` are refused, one line, exit 2)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return v


def gravity_sigma(text: str) -> float:
    """argparse type: the 1-sigma of a given gravity's tilt, degrees in [0, 20] (0: exact)."""
    v = finite_float(text)
    if not 0.0 <= v <= 20.0:
        raise argparse.ArgumentTypeError(f"must be 0-20 degrees, got {v:g}")
    return v


def add_camera_args(p: argparse.ArgumentParser, gravity_flags=("--gravity",)) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument("--hfov", type=finite_float, metavar="DEG",
                   help="horizontal field of view in degrees (default: from the photo's EXIF "
                        f"focal length, else {DEFAULT_HFOV_DEG:g}, a typical phone camera)")
    g.add_argument("--intrinsics", metavar="FX,FY,CX,CY",
                   help="focal lengths and principal point in pixels of this image")
    for flag in gravity_flags:
        p.add_argument(flag, metavar="GX,GY,GZ",
                       help="gravity in camera coordinates (x right, y down, z forward), e.g. "
                            "from the phone's accelerometer, refined by the photo's vertical "
                            "and horizontal lines near it; default: estimated from those "
                            "lines, else level (0,1,0)")
    p.add_argument("--gravity-sigma", type=gravity_sigma, metavar="DEG",
                   help=f"1-sigma of the given gravity's tilt per axis, degrees (default "
                        f"{INPUT_GRAVITY_SIGMA_DEG:g}, a phone held still; 0: exact, taken as "
                        "it is)")


def photo_camera_from(photo, hfov: float | None = None, intrinsics: str | None = None,
                      gravity: str | None = None, gravity_name: str = "--gravity",
                      gravity_sigma_deg: float | None = None):
    """(Camera, Provenance) of a decoded ``findme_io.imageio.Photo`` from flag values: flags
    first (a given gravity refined by the photo's lines unless its sigma is 0), then the
    photo's EXIF and its vanishing directions, then the defaults."""
    from findme_io.camera_source import photo_camera
    g = floats(gravity, 3, gravity_name) if gravity else None
    k = floats(intrinsics, 4, "--intrinsics") if intrinsics else None
    if hfov is not None and not (0.0 < hfov < 180.0):
        raise InputError(f"--hfov: the horizontal field of view must be in (0, 180) degrees, got {hfov:g}")
    sigma = None if gravity_sigma_deg is None else math.radians(gravity_sigma_deg)
    try:
        return photo_camera(photo.image, photo.exif, k, hfov, g, sigma)
    except CameraError as e:
        raise InputError(str(e)) from None


def camera_height(value: float | None) -> tuple[float, bool]:
    """(height in metres, metric?): without a height the scene is up to scale (h = 1)."""
    if value is None:
        return 1.0, False
    if not math.isfinite(value) or value <= 0 or value > 100:
        raise InputError(f"--camera-height must be in (0, 100] metres, got {value}")
    return float(value), True
