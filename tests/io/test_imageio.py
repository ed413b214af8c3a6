"""Photo decoding (findme_io.imageio) on files made with the well-kept libraries: Pillow
writes JPEG/PNG with EXIF, pillow-heif writes HEIC. Orientation, HEIC, bounds, one line."""

import io
import resource
import struct
import subprocess
import sys
import zlib

import numpy as np
import pillow_heif
import pytest
from PIL import Image

from findme_core.errors import ImageError
from findme_io.imageio import MAX_JPEG_SCANS, decode_photo, image_size, probe, sniff


@pytest.fixture(autouse=True, scope="module")
def heif_writer():
    """pillow-heif's writer for the test files (the decoder registers its own opener)."""
    pillow_heif.register_heif_opener()


def upright_pattern(w=160, h=120):
    """An asymmetric picture (a bright block at the top left, a ramp to the right)."""
    a = np.zeros((h, w, 3), np.uint8)
    a[:, :, 1] = np.linspace(0, 255, w)[None, :]
    a[: h // 3, : w // 4] = 255
    return a


#: the inverse of each EXIF orientation, as Pillow's transposes: what a camera stores
STORED = {1: None, 2: Image.Transpose.FLIP_LEFT_RIGHT, 3: Image.Transpose.ROTATE_180,
          4: Image.Transpose.FLIP_TOP_BOTTOM, 5: Image.Transpose.TRANSPOSE,
          6: Image.Transpose.ROTATE_90, 7: Image.Transpose.TRANSVERSE,
          8: Image.Transpose.ROTATE_270}


def encode(img_rgb, fmt="JPEG", exif=None, **kw):
    buf = io.BytesIO()
    im = Image.fromarray(img_rgb)
    if exif is not None:
        kw["exif"] = exif
    im.save(buf, format=fmt, **kw)
    return buf.getvalue()


def exif_block(orientation=None, f35=None, focal=None, plane=None, unit=None, size=None,
               direction=None, direction_ref=None):
    ex = Image.Exif()
    if direction is not None or direction_ref is not None:
        gps = ex.get_ifd(0x8825)     # GPSImgDirection, GPSImgDirectionRef
        if direction is not None:
            gps[0x0011] = direction
        if direction_ref is not None:
            gps[0x0010] = direction_ref
    if orientation is not None:
        ex[0x0112] = orientation
    sub = ex.get_ifd(0x8769)
    if f35 is not None:
        sub[0xA405] = f35
    if focal is not None:
        sub[0x920A] = focal
    if plane is not None:
        sub[0xA20E], sub[0xA20F] = plane
    if unit is not None:
        sub[0xA210] = unit
    if size is not None:
        sub[0xA002], sub[0xA003] = size
    return ex


@pytest.mark.parametrize("orientation", range(1, 9))
@pytest.mark.parametrize("fmt", ["JPEG", "PNG"])
def test_every_exif_orientation_comes_out_upright(orientation, fmt):
    up = upright_pattern()
    stored = Image.fromarray(up)
    if STORED[orientation] is not None:
        stored = stored.transpose(STORED[orientation])
    data = encode(np.asarray(stored), fmt, exif_block(orientation), **({"quality": 95} if fmt == "JPEG" else {}))
    photo = decode_photo(data)
    assert photo.exif.orientation == orientation
    assert photo.image.shape[:2] == up.shape[:2]
    assert image_size(data) == (up.shape[1], up.shape[0])          # header only, same answer
    diff = np.abs(photo.image[:, :, ::-1].astype(int) - up).mean()
    assert diff < 4, diff


def test_heic_is_decoded_upright():
    up = upright_pattern(320, 240)
    stored = Image.fromarray(up).transpose(STORED[6])
    buf = io.BytesIO()
    stored.save(buf, format="HEIF", quality=90, exif=exif_block(6, f35=26).tobytes())
    data = buf.getvalue()
    assert sniff(data) == "heif"
    photo = decode_photo(data, "IMG_0001.HEIC")
    assert photo.format == "heif" and photo.image.shape == (240, 320, 3)
    assert np.abs(photo.image[:, :, ::-1].astype(int) - up).mean() < 8
    assert photo.exif.focal35_mm == 26
    w, h, info = probe(data)
    assert (w, h) == (320, 240) and info.focal35_mm == 26


def test_webp_and_16_bit_png():
    up = upright_pattern()
    assert decode_photo(encode(up, "WEBP", quality=95)).format == "webp"
    deep = (np.linspace(0, 65535, 160)[None, :].repeat(120, 0)).astype(np.uint16)
    buf = io.BytesIO()
    Image.fromarray(deep).save(buf, format="PNG")
    img = decode_photo(buf.getvalue()).image
    assert img.shape == (120, 160, 3) and img[0, 0, 0] == 0 and img[0, -1, 0] == 255


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def png_bomb() -> bytes:
    """Issue 11's file: a 404 kB PNG whose IDAT chunk claims 0xFFFFFFFF bytes."""
    head = b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", struct.pack(">IIBBBBB", 4000, 3000, 8, 2, 0, 0, 0))
    return head + struct.pack(">I", 0xFFFFFFFF) + b"IDAT" + bytes(404_000 - len(head) - 8)


def test_png_bomb_is_refused_before_reading():
    with pytest.raises(ImageError, match="claims 4294967295 bytes"):
        decode_photo(png_bomb())


def test_png_bomb_refused_by_the_cli_in_bounded_memory(tmp_path):
    """One line, exit 2, in a process that may not map more than 1.5 GB (the old decoder
    allocated ~4 GB for this file)."""
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(png_bomb())
    limit = 1536 * 1024 * 1024

    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    p = subprocess.run([sys.executable, "-m", "findme.cli", "hypotheses", str(bomb)],
                       capture_output=True, text=True, timeout=60, preexec_fn=cap)
    assert p.returncode == 2, p.stderr
    assert p.stderr.count("\n") == 1 and "IDAT" in p.stderr and "claims" in p.stderr


def test_jpeg_with_too_many_scans_is_refused():
    data = encode(upright_pattern(), "JPEG", quality=90)
    soi, rest = data[:2], data[2:]
    fake = soi + (b"\xff\xda\x00\x02") * (MAX_JPEG_SCANS + 1) + rest
    with pytest.raises(ImageError, match="scans"):
        decode_photo(fake)


@pytest.mark.parametrize("cut", [0.2, 0.5, 0.9])
def test_truncated_files_are_errors_not_grey(cut):
    for fmt in ("JPEG", "PNG", "WEBP"):
        data = encode(upright_pattern(320, 240), fmt)
        with pytest.raises(ImageError):
            decode_photo(data[: int(len(data) * cut)])


def test_broken_files_print_one_line(tmp_path):
    """libjpeg/libpng warnings are not printed: every rejected file is one stderr line."""
    good = encode(upright_pattern(320, 240), "JPEG")
    bad = bytearray(good)
    bad[len(bad) // 2: len(bad) // 2 + 40] = b"\xff\xd9" * 20          # garbage in the scan
    png = bytearray(encode(upright_pattern(320, 240), "PNG"))
    png[60:80] = b"x" * 20                                               # corrupt IDAT
    for name, data in (("a.jpg", bytes(bad)), ("b.png", bytes(png)), ("c.jpg", good[:900])):
        f = tmp_path / name
        f.write_bytes(data)
        p = subprocess.run([sys.executable, "-m", "findme.cli", "hypotheses", str(f), "--json"],
                           capture_output=True, text=True, timeout=60)
        if p.returncode == 0:       # libjpeg recovers some damage: then nothing is printed
            assert "warning" not in p.stderr.lower() and "Corrupt" not in p.stderr
        else:
            assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr


def test_heic_goes_on_the_bus_as_an_upright_jpeg_with_its_exif_lens():
    from findme_io.imageio import for_bus
    up = upright_pattern(320, 240)
    buf = io.BytesIO()
    Image.fromarray(up).transpose(STORED[8]).save(buf, format="HEIF", quality=90,
                                                  exif=exif_block(8, f35=26).tobytes())
    data, lens = for_bus(buf.getvalue(), "IMG.HEIC")
    assert sniff(data) == "jpeg" and image_size(data) == (320, 240)
    k = lens["intrinsics"]
    assert (k["width"], k["height"]) == (320, 240) and k["fx"] == pytest.approx(26 * 400 / 43.2666, rel=1e-3)
    jpg = encode(up, "JPEG")
    assert for_bus(jpg) == (jpg, {})        # JPEG, PNG, WebP travel as they are
    assert probe(data)[2].heading_deg is None


def test_a_heic_photos_compass_bearing_goes_on_the_bus_with_it():
    from PIL import TiffImagePlugin

    from findme_io.imageio import for_bus
    buf = io.BytesIO()
    Image.fromarray(upright_pattern(320, 240)).save(
        buf, format="HEIF", quality=90,
        exif=exif_block(direction=TiffImagePlugin.IFDRational(3071, 10),
                        direction_ref="T").tobytes())
    data, _ = for_bus(buf.getvalue(), "IMG.HEIC")
    info = probe(data)[2]
    assert sniff(data) == "jpeg" and (info.heading_deg, info.heading_ref) == (307.1, "T")
    assert set(Image.open(io.BytesIO(data)).getexif().get_ifd(0x8825)) == {0x10, 0x11}


def test_findme_run_takes_a_heic_photo(tmp_path):
    """The capture service turns a HEIC file into a frame the pipeline measures in."""
    import shutil
    from importlib import resources
    src = resources.files("findme") / "examples" / "room_a.jpg"
    rgb = np.asarray(Image.open(str(src)).convert("RGB"))
    heic = tmp_path / "room.heic"
    Image.fromarray(rgb).save(heic, format="HEIF", quality=90)
    shutil.copy(resources.files("findme") / "examples" / "room_a.json", tmp_path / "room.json")
    p = subprocess.run([sys.executable, "-m", "findme.cli", "run", str(heic), "--no-record"],
                       capture_output=True, text=True, timeout=180, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "hypotheses" in p.stdout and "room.heic" in p.stdout


def test_a_large_jpeg_is_decoded_at_a_dct_reduction_with_its_scale():
    """``reduce_to``: the largest reduction keeping the long side >= it (2560 px for 640:
    a quarter); the pixels are the photo's, averaged (pixel centres: u' = (u + 0.5) s - 0.5);
    photos under twice the size, PNG, and no ``reduce_to`` are decoded whole."""
    from findme_io.imageio import reduction
    assert [reduction(w, h, 640) for w, h in ((4032, 3024), (2560, 1920), (1600, 1200),
                                               (1280, 960), (1226, 370), (640, 480))] == \
        [4, 4, 2, 2, 1, 1]
    assert reduction(4000, 24, 640) == 1            # the short side stays >= 16 px
    rng = np.random.default_rng(0)
    small = (rng.random((60, 80, 3)) * 255).astype(np.uint8)
    big = np.kron(small, np.ones((32, 32, 1), np.uint8))          # 2560x1920, 32 px blocks
    buf = io.BytesIO()
    Image.fromarray(big).save(buf, "JPEG", quality=95)
    whole = decode_photo(buf.getvalue())
    reduced = decode_photo(buf.getvalue(), reduce_to=640)
    assert (whole.scale, whole.size, whole.image.shape) == (1.0, (2560, 1920), (1920, 2560, 3))
    assert (reduced.scale, reduced.size, reduced.image.shape) == (0.25, (2560, 1920), (480, 640, 3))
    # each 8 px block of the reduced image is the mean of the photo's 8x8 (here: uniform)
    expect = np.kron(small, np.ones((8, 8, 1), np.uint8))[:, :, ::-1].astype(int)
    assert np.median(np.abs(reduced.image.astype(int) - expect)) <= 2
    png = io.BytesIO()
    Image.fromarray(big).save(png, "PNG")
    assert decode_photo(png.getvalue(), reduce_to=640).scale == 1.0


def test_a_reduced_decode_keeps_the_exif_orientation_and_the_upright_size():
    img = Image.fromarray(np.zeros((1920, 2560, 3), np.uint8))
    exif = Image.Exif()
    exif[0x0112] = 6                                  # stored 2560x1920, shown 1920x2560
    buf = io.BytesIO()
    img.save(buf, "JPEG", exif=exif.tobytes())
    p = decode_photo(buf.getvalue(), reduce_to=640)
    assert p.size == (1920, 2560) and p.image.shape == (640, 480, 3) and p.scale == 0.25
