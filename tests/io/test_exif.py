"""Camera from EXIF (findme_io.exif, camera_source) on files written by Pillow: the 35 mm
equivalent, FocalLength with the focal-plane resolution, orientation, the compass heading
(GPSImgDirection), broken blocks."""

import io
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image, TiffImagePlugin

from findme_io.camera_source import lens_camera, photo_camera
from findme_io.convert import make_frame
from findme_io.exif import FILM_DIAGONAL_MM, focal_px
from findme_io.frame_photo import EXIF_HEADING_SIGMA_RAD, exif_heading, frame_heading
from findme_io.imageio import decode_photo
from tests.io.test_imageio import encode, exif_block, upright_pattern

R = TiffImagePlugin.IFDRational


def jpeg(w=400, h=300, **exif):
    return encode(upright_pattern(w, h), "JPEG", exif_block(**exif), quality=90)


def test_35mm_equivalent_via_the_diagonal():
    photo = decode_photo(jpeg(f35=26))
    cam, src, notes = lens_camera(400, 300, exif=photo.exif)
    f = 26 * math.hypot(400, 300) / FILM_DIAGONAL_MM
    assert src == "exif" and cam.fx == pytest.approx(f) and cam.fy == pytest.approx(f)
    assert (cam.cx, cam.cy) == (199.5, 149.5) and not notes


@pytest.mark.parametrize("unit,per_unit", [(2, 25.4), (3, 10.0), (4, 1.0)])
def test_focal_length_with_the_focal_plane_resolution(unit, per_unit):
    # 4.25 mm lens, 1.4 um pixels (714.29 px/mm): fx = 3035.7 px at the sensor's 4000 px
    px_per_mm = 1 / 0.0014
    plane = (R(px_per_mm * per_unit), R(px_per_mm * per_unit))
    photo = decode_photo(jpeg(400, 300, focal=R(4.25), plane=plane, unit=unit, size=(4000, 3000)))
    (fx, fy), how, notes = focal_px(photo.exif, 400, 300)
    assert how == "focal-plane" and not notes
    assert fx == pytest.approx(4.25 * px_per_mm / 10, rel=1e-6)      # image is 1/10 the sensor
    assert fy == pytest.approx(fx)


def test_focal_plane_axes_follow_the_orientation():
    """Orientation 6 (stored landscape, upright portrait): the upright image's x is the
    stored y, so fx comes from FocalPlaneYResolution."""
    plane = (R(700.0), R(500.0))                    # unequal on purpose, px/mm
    photo = decode_photo(jpeg(400, 300, orientation=6, focal=R(1.0), plane=plane, unit=4))
    H, W = photo.image.shape[:2]
    assert (W, H) == (300, 400)
    (fx, fy), how, _ = focal_px(photo.exif, W, H)
    assert how == "focal-plane" and fx == pytest.approx(500.0) and fy == pytest.approx(700.0)


def test_flags_override_exif_and_the_default_comes_last():
    photo = decode_photo(jpeg(f35=26))
    cam, prov = photo_camera(photo.image, photo.exif, hfov_deg=50.0, gravity=(0, 1, 0))
    assert prov.camera == "input" and math.degrees(2 * math.atan(200 / cam.fx)) == pytest.approx(50)
    bare = decode_photo(jpeg())
    cam, src, notes = lens_camera(400, 300, exif=bare.exif)
    assert src == "default" and "no focal length" in notes[-1]


BROKEN = [
    dict(f35="26mm"),                         # a string where a number belongs
    dict(f35=0),                              # EXIF's "unknown"
    dict(f35=5000),                           # absurd: a 0.5 deg lens
    dict(focal=R(4, 0), plane=(R(700), R(700)), unit=4),   # zero denominator
    dict(focal=R(4.0), plane=(R(700), R(700)), unit=9),    # not a unit
    dict(orientation=42),
]


@pytest.mark.parametrize("tags", BROKEN)
def test_malformed_values_are_ignored_with_the_reason(tags):
    photo = decode_photo(jpeg(**tags))
    assert photo.image.shape == (300, 400, 3)
    cam, src, notes = lens_camera(400, 300, exif=photo.exif)
    assert src == "default" and len(notes) >= 2          # what was ignored, then the default


def _with_app1(jpeg_bytes: bytes, payload: bytes) -> bytes:
    """The JPEG with its APP1 (EXIF) segment's TIFF data replaced by ``payload``."""
    i = jpeg_bytes.index(b"Exif\x00\x00")
    seg_start = i - 4
    seg_len = int.from_bytes(jpeg_bytes[seg_start + 2:seg_start + 4], "big")
    body = b"Exif\x00\x00" + payload
    return (jpeg_bytes[:seg_start] + b"\xff\xe1" + (len(body) + 2).to_bytes(2, "big") + body
            + jpeg_bytes[seg_start + 2 + seg_len:])


@pytest.mark.parametrize("damage", ["truncated", "bad_offset", "garbage", "empty"])
def test_broken_exif_blocks_are_tolerated(damage):
    good = jpeg(orientation=6, f35=26)
    tiff = exif_block(orientation=6, f35=26).tobytes()[6:]      # without "Exif\0\0"
    payload = {"truncated": tiff[:14], "garbage": bytes(range(200)),
               "bad_offset": tiff[:4] + (10 ** 8).to_bytes(4, "little") + tiff[8:],
               "empty": b""}[damage]
    photo = decode_photo(_with_app1(good, payload))
    assert photo.image.shape[2] == 3 and photo.exif is not None
    cam, src, notes = lens_camera(photo.image.shape[1], photo.image.shape[0], exif=photo.exif)
    assert src in ("default", "exif")


def test_cli_reports_the_exif_camera(tmp_path):
    f = tmp_path / "phone.jpg"
    f.write_bytes(jpeg(640, 480, f35=28))
    p = subprocess.run([sys.executable, "-m", "findme.cli", "hypotheses", str(f), "--json"],
                       capture_output=True, text=True, timeout=60)
    out = json.loads(p.stdout)
    fpx = 28 * 800 / FILM_DIAGONAL_MM
    assert out["camera"]["source"] == "exif" and out["camera"]["fx"] == pytest.approx(fpx, rel=1e-5)
    assert out["camera"]["hfov_deg"] == pytest.approx(math.degrees(2 * math.atan(320 / fpx)), rel=1e-5)
    assert out["gravity"]["source"] in ("image", "level") and len(out["gravity"]["vector"]) == 3
    assert np.isfinite(out["gravity"]["sigma_deg"])


@pytest.mark.parametrize("ref,want", [("M", "M"), ("T", "T"), (None, "?")])
def test_the_files_compass_heading_and_its_reference(ref, want):
    photo = decode_photo(jpeg(direction=R(24350, 100), direction_ref=ref))
    assert photo.exif.heading_deg == pytest.approx(243.5) and not photo.exif.notes
    h, sigma, got = exif_heading(photo.exif)
    assert h == pytest.approx(math.radians(243.5)) and got == want
    assert sigma == EXIF_HEADING_SIGMA_RAD
    assert exif_heading(decode_photo(jpeg()).exif) is None


@pytest.mark.parametrize("tags,why", [
    (dict(direction=R(400)), "not a bearing"),
    (dict(direction=R(1, 0)), "not a bearing"),       # 1/0: NaN in Pillow's rational
    (dict(direction=R(90), direction_ref="X"), "not T or M"),
])
def test_a_broken_heading_is_ignored_with_the_reason(tags, why):
    exif = decode_photo(jpeg(**tags)).exif
    assert why in " ".join(exif.notes), exif.notes
    assert tags.get("direction_ref") == "X" or exif_heading(exif) is None


def test_a_frames_own_heading_comes_before_its_files():
    data = jpeg(direction=R(90), direction_ref="T")
    frame = make_frame("s", 0, data)
    h, _, ref = frame_heading(frame)
    assert h == pytest.approx(math.pi / 2) and ref == "T"
    frame = make_frame("s", 0, data, heading_rad=0.25, heading_sigma_rad=0.1)
    assert frame_heading(frame) == (0.25, 0.1, "")
