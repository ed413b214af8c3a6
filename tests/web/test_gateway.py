"""The gateway without a browser: its pure parts, and one page's WebSocket on an
in-process bus (isolation between sessions, refusals, cross-origin)."""

from __future__ import annotations

import asyncio
import json
import math
import struct
from importlib import resources

import cv2
import numpy as np
import pytest

import schemas
from services.runtime import bus
from services.web.gateway import Gateway, parse_http
from services.web.page_command import parse_command
from services.web.page_input import GatewayError, build_frame, parse_upload
from services.web.page_output import to_page

CODE = schemas.ErrorCode
ROOM_A = (resources.files("findme") / "examples" / "room_a.jpg").read_bytes()


def upload_bytes(header: dict, image: bytes) -> bytes:
    h = json.dumps(header).encode()
    return struct.pack(">I", len(h)) + h + image


def code_of(fn, *a):
    with pytest.raises(GatewayError) as e:
        fn(*a)
    return CODE.Name(e.value.code).removeprefix("ERROR_CODE_"), str(e.value)


def test_parse_upload_refuses_malformed_and_oversized():
    assert parse_upload(upload_bytes({"a": 1}, b"xyz")) == ({"a": 1}, b"xyz")
    assert code_of(parse_upload, b"\x00\x00")[0] == "MALFORMED"
    assert code_of(parse_upload, struct.pack(">I", 99) + b"{}")[0] == "MALFORMED"
    assert code_of(parse_upload, struct.pack(">I", 2) + b"[]" + b"x")[0] == "MALFORMED"
    assert code_of(parse_upload, upload_bytes({}, b""))[0] == "BAD_IMAGE"
    code, text = code_of(parse_upload, upload_bytes({}, b"x" * 101), 100)
    assert code == "TOO_LARGE" and "limit" in text


def test_build_frame_takes_the_sensors_gravity_sigma():
    """The page sends 1.5 deg for a motion-sensor reading (the services weigh it so against
    the photo's lines); none for a typed gravity; no gravity, no sigma."""
    f, _ = build_frame("s1", 0, {"gravity": [0, 0.9, 0.4], "gravity_sigma_deg": 1.5}, ROOM_A)
    assert f.gravity_sigma_rad == pytest.approx(math.radians(1.5))
    f, _ = build_frame("s1", 1, {"gravity": [0, 0.9, 0.4]}, ROOM_A)
    assert not f.HasField("gravity_sigma_rad")
    f, _ = build_frame("s1", 2, {"gravity_sigma_deg": 1.5}, ROOM_A)
    assert not f.HasField("gravity") and not f.HasField("gravity_sigma_rad")


def test_build_frame_takes_the_sensors_heading():
    """A live capture's heading (degrees, wrapped) reaches the Frame in radians, with the
    1-sigma the page declared (the mapper's default when it declares none)."""
    f, _ = build_frame("s1", 0, {"heading_deg": 370.0, "heading_sigma_deg": 5}, ROOM_A)
    assert f.heading_rad == pytest.approx(math.radians(10.0))
    assert f.heading_sigma_rad == pytest.approx(math.radians(5.0))
    f, _ = build_frame("s1", 1, {"heading_deg": -90}, ROOM_A)
    assert f.heading_rad == pytest.approx(math.radians(270.0))
    assert not f.HasField("heading_sigma_rad")
    f, _ = build_frame("s1", 2, {"heading_sigma_deg": 5, "heading_ref": "M"}, ROOM_A)
    assert not f.HasField("heading_rad") and not f.HasField("heading_sigma_rad")
    assert f.heading_ref == ""
    schemas.decode(schemas.Frame, schemas.encode(f))   # valid on the bus (both check it)
    # a gallery photo's compass bearing, read by the page (it sends the photo re-encoded)
    f, info = build_frame("s1", 3, {"heading_deg": 200, "heading_sigma_deg": 15,
                                    "heading_ref": "T"}, ROOM_A)
    assert f.heading_ref == "T" and (info["heading_deg"], info["heading_ref"]) == (200.0, "T")
    assert build_frame("s1", 4, {"heading_deg": 5}, ROOM_A)[0].heading_ref == ""
    f, _ = build_frame("s1", 5, {"heading_deg": 5, "heading_ref": "?"}, ROOM_A)  # a compass's
    assert f.heading_sigma_rad == pytest.approx(math.radians(30.0)) and f.heading_ref == "?"


def test_build_frame_keeps_the_files_compass_bearing_through_its_re_encoding():
    """A portrait JPEG (EXIF orientation 6) is re-encoded upright, without its EXIF: the
    compass bearing it carried goes into the Frame (true north, the files' 1-sigma)."""
    from PIL import TiffImagePlugin

    from findme_io.frame_photo import EXIF_HEADING_SIGMA_RAD
    from tests.io.test_imageio import encode, exif_block

    def jpeg(orientation):
        rgb = cv2.imdecode(np.frombuffer(ROOM_A, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]
        return encode(rgb, "JPEG", exif_block(
            orientation, direction=TiffImagePlugin.IFDRational(1234, 10), direction_ref="T"),
            quality=90)
    f, info = build_frame("s1", 0, {}, jpeg(6))
    assert info["reencoded"] and (info["width"], info["height"]) == (480, 640)
    assert f.heading_rad == pytest.approx(math.radians(123.4))
    assert f.heading_sigma_rad == pytest.approx(EXIF_HEADING_SIGMA_RAD) and f.heading_ref == "T"
    # what the page said comes first
    f, _ = build_frame("s1", 1, {"heading_deg": 10.0}, jpeg(6))
    assert f.heading_rad == pytest.approx(math.radians(10.0)) and f.heading_ref == ""
    # upright already: published as it came, its bearing said in the Frame too
    upright = jpeg(None)
    f, info = build_frame("s1", 2, {}, upright)
    assert not info["reencoded"] and f.image.data == upright
    assert f.heading_rad == pytest.approx(math.radians(123.4)) and f.heading_ref == "T"


def test_build_frame_lenses_gravity_height():
    f, info = build_frame("s1", 0, {"lens": {"kind": "intrinsics", "fx": 500, "fy": 501, "cx": 320,
                                             "cy": 240, "width": 640, "height": 480},
                                    "gravity": [0, 0.9, 0.4], "camera_height_m": 1.42,
                                    "device": "Pixel 7"}, ROOM_A)
    assert f.image.data == ROOM_A and f.image.format == "jpeg"
    assert (f.intrinsics.fx, f.intrinsics.fy, f.intrinsics.width) == (500, 501, 640)
    assert f.camera_height_m == 1.42 and f.device == "web: Pixel 7"
    assert info["gravity"] == pytest.approx(np.array([0, 0.9, 0.4]) / math.hypot(0.9, 0.4))
    f, info = build_frame("s1", 1, {"lens": {"kind": "focal35", "focal35_mm": 26}}, ROOM_A)
    f_px = 26 * math.hypot(640, 480) / math.hypot(36, 24)
    assert f.hfov_deg == pytest.approx(math.degrees(2 * math.atan(320 / f_px)))
    assert info["fx"] == pytest.approx(f_px)
    f, _ = build_frame("s1", 2, {}, ROOM_A)
    assert f.WhichOneof("lens") is None and not f.HasField("camera_height_m")


@pytest.mark.parametrize("header, code, words", [
    ({"lens": {"kind": "intrinsics", "fx": 500, "fy": 500, "cx": 1, "cy": 1, "width": 480,
               "height": 640}}, "BAD_CAMERA", "480x640"),
    ({"lens": {"kind": "intrinsics", "fx": 500}}, "BAD_CAMERA", "fx, fy, cx and cy"),
    ({"lens": {"kind": "hfov", "hfov_deg": 190}}, "BAD_CAMERA", "field of view"),
    ({"lens": {"kind": "fisheye"}}, "BAD_CAMERA", "fisheye"),
    ({"gravity": [0, 0, 0]}, "BAD_CAMERA", "zero"),
    ({"gravity": [0, 1, 0], "gravity_sigma_deg": 0}, "BAD_CAMERA", "1-sigma"),
    ({"gravity": [0, 1, 0], "gravity_sigma_deg": "1"}, "BAD_CAMERA", "1-sigma"),
    ({"gravity": [0, 1, 0], "gravity_sigma_deg": 45}, "BAD_CAMERA", "1-sigma"),
    ({"gravity": [0, 0, 1]}, "BAD_CAMERA", "straight down"),
    ({"gravity": [0, "1", 0]}, "BAD_CAMERA", "3 finite numbers"),
    ({"heading_deg": "north"}, "BAD_CAMERA", "heading"),
    ({"heading_deg": float("inf")}, "BAD_CAMERA", "heading"),
    ({"heading_deg": 10, "heading_sigma_deg": 0}, "BAD_CAMERA", "heading's 1-sigma"),
    ({"heading_deg": 10, "heading_sigma_deg": 120}, "BAD_CAMERA", "heading's 1-sigma"),
    ({"heading_deg": 10, "heading_ref": "north"}, "BAD_CAMERA", "heading_ref"),
    ({"heading_deg": 10, "heading_ref": ["T"]}, "BAD_CAMERA", "heading_ref"),
    ({"camera_height_m": -1}, "BAD_CAMERA", "camera height"),
    ({"camera_height_m": True}, "BAD_CAMERA", "camera height"),
])
def test_build_frame_refuses_bad_camera_values(header, code, words):
    c, text = code_of(build_frame, "s1", 0, header, ROOM_A)
    assert c == code and words in text, text


def _png(w, h):
    import zlib

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    raw = zlib.compress(b"".join(b"\x00" + bytes((w + 7) // 8) for _ in range(h)))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 1, 0, 0, 0, 0))
            + chunk(b"IDAT", raw) + chunk(b"IEND", b""))


def test_build_frame_refuses_bad_images():
    assert code_of(build_frame, "s", 0, {}, b"hello, not an image")[0] == "BAD_IMAGE"
    assert code_of(build_frame, "s", 0, {}, ROOM_A[:300])[0] == "BAD_IMAGE"
    code, text = code_of(build_frame, "s", 0, {}, _png(10000, 6000))
    assert code == "TOO_LARGE" and "60 MP" in text


def test_exif_rotated_jpeg_is_sent_upright():
    """A portrait photo stored landscape with EXIF orientation 6: the frame carries the
    upright pixels the browser shows (and taps refer to)."""
    tiff = (b"MM\x00\x2a\x00\x00\x00\x08" + b"\x00\x01" + b"\x01\x12\x00\x03\x00\x00\x00\x01"
            + b"\x00\x06\x00\x00" + b"\x00\x00\x00\x00")
    app1 = b"\xff\xe1" + struct.pack(">H", 2 + 6 + len(tiff)) + b"Exif\x00\x00" + tiff
    rotated = ROOM_A[:2] + app1 + ROOM_A[2:]
    f, info = build_frame("s", 0, {}, rotated)
    assert info["reencoded"] and (info["width"], info["height"]) == (480, 640)
    img = cv2.imdecode(np.frombuffer(f.image.data, np.uint8), cv2.IMREAD_COLOR)
    assert img.shape[:2] == (640, 480)
    assert not build_frame("s", 0, {}, ROOM_A)[1]["reencoded"]


def test_parse_command():
    assert parse_command('{"type": "select", "index": 0, "rank": 2}')["rank"] == 2
    m = parse_command('{"type": "measure", "id": 1, "index": 0, "pixels": [[1, 2], [3.5, 4]]}')
    assert m["pixels"] == [(1.0, 2.0), (3.5, 4.0)]
    bad = [("nope", "MALFORMED"), ('{"type": "delete"}', "MALFORMED"),
           ('{"type": "select", "index": -1, "rank": 1}', "NO_SUCH_FRAME"),
           ('{"type": "select", "index": 0, "rank": 0}', "NO_SUCH_HYPOTHESIS"),
           ('{"type": "select", "index": 0, "rank": 1, "camera_height_m": 0}', "BAD_CAMERA"),
           ('{"type": "measure", "index": 0, "pixels": []}', "MALFORMED"),
           ('{"type": "measure", "index": 0, "pixels": [[1, "x"]]}', "BAD_CAMERA"),
           ('{"type": "measure", "index": 0, "pixels": ' + json.dumps([[1, 1]] * 65) + "}",
            "TOO_LARGE"),
           (" " * 70000, "TOO_LARGE")]
    for text, code in bad:
        assert code_of(parse_command, text)[0] == code, text


def test_parse_command_takes_what_the_user_says_each_pixel_is_on():
    """A measure's optional surfaces: one per pixel, each null, "floor", "wall" or "top"; anything
    else refused (MALFORMED) with the offending value and its place named."""
    def measure(**extra):
        return json.dumps({"type": "measure", "id": 1, "index": 0,
                           "pixels": [[1, 2], [3, 4]], **extra})
    assert parse_command(measure())["surfaces"] is None                  # nothing said
    assert parse_command(measure(surfaces=[None, "floor"]))["surfaces"] == [None, "floor"]
    assert parse_command(measure(surfaces=["wall", "floor"]))["surfaces"] == ["wall", "floor"]
    assert parse_command(measure(surfaces=[None, None]))["surfaces"] == [None, None]
    assert parse_command(measure(surfaces=["top", "wall"]))["surfaces"] == ["top", "wall"]
    for surfaces, words in [
            (["floor"], "surfaces gives 1 for 2 pixels: give one per pixel"),
            (["floor", "wall", None], "surfaces gives 3 for 2 pixels"),
            ([], "surfaces gives 0 for 2 pixels"),
            (["floor", "ceiling"], 'surfaces[1] must be null, "floor", "wall" or "top", got "ceiling"'),
            ([3, None], 'surfaces[0] must be null, "floor", "wall" or "top", got 3'),
            ([None, True], 'surfaces[1] must be null, "floor", "wall" or "top", got true'),
            (["Floor", None], 'surfaces[0] must be null, "floor", "wall" or "top", got "Floor"'),
            ([["floor"], None], 'surfaces[0] must be null, "floor", "wall" or "top", got ["floor"]'),
            ("floor", 'surfaces must be a list of null, "floor", "wall" or "top", one per pixel; '
                      'got "floor"'),
            ({"0": "floor"}, 'got {"0": "floor"}'),
            (None, "got null")]:
        code, text = code_of(parse_command, measure(surfaces=surfaces))
        assert code == "MALFORMED" and words in text, (surfaces, text)
    code, text = code_of(parse_command, measure(surfaces=["x" * 500, None]))
    assert code == "MALFORMED" and len(text) < 120 and '"xxx' in text, text


def test_to_page_measure_says_what_was_said():
    reply = schemas.MeasureReply(session="s", index=0, rank=1, metric=True, points=[
        schemas.MeasuredPoint(pixel=schemas.Pixel(u=1, v=2), surface=schemas.SURFACE_FLOOR,
                              xyz=schemas.Vec3(x=0, y=1.5, z=2), sigma_m=0.1,
                              said=schemas.SURFACE_FLOOR),
        schemas.MeasuredPoint(pixel=schemas.Pixel(u=3, v=4), surface=schemas.SURFACE_WALL,
                              xyz=schemas.Vec3(x=0, y=0, z=3), sigma_m=0.5),
        schemas.MeasuredPoint(pixel=schemas.Pixel(u=5, v=6), said=schemas.SURFACE_WALL,
                              error="choose a hypothesis whose floor line runs below it")])
    points = to_page("s", reply)["points"]
    assert [(p["surface"], p["said"]) for p in points] == [("floor", "floor"), ("wall", None),
                                                           ("none", "wall")]
    assert "floor line runs below it" in points[2]["error"]


def test_to_page_messages():
    e = schemas.Error(session="s", key="findme/s/frame/3", code=CODE.ERROR_CODE_BAD_IMAGE,
                      message="corrupt", service="hypotheses/1")
    assert to_page("s", e) == {"type": "error", "code": "BAD_IMAGE", "message": "corrupt",
                               "key": "frame/3", "service": "hypotheses/1"}
    m = schemas.Motion(session="s", index_a=0, index_b=1, x_m=0.1, z_m=0.2, yaw_rad=-0.3)
    d = to_page("s", m)
    assert (d["a"], d["b"], d["x_m"], d["yaw_rad"], d["sigma_x_m"]) == (0, 1, 0.1, -0.3, None)
    t = to_page("s", schemas.Trajectory(session="s", poses=[schemas.Pose(index=1, x_m=1)]))
    assert t["poses"][0]["x_m"] == 1
    assert to_page("s", schemas.Frame(session="s")) is None


def test_parse_http():
    assert parse_http("127.0.0.1:0") == ("127.0.0.1", 0)
    assert parse_http("8080") == ("127.0.0.1", 8080)
    assert parse_http("[::1]:9000") == ("::1", 9000)
    with pytest.raises(Exception):
        parse_http("localhost:http")


def test_one_page_sees_only_its_own_session():
    """On a live bus: the page's session id is made by the server; another session's error
    does not reach it, its own does; a forged select and an undecodable photo are refused
    with an Error on its own error key; a cross-origin upgrade is refused."""
    import aiohttp

    zs = bus.open_session()
    gw = Gateway(zs, "127.0.0.1", 0)
    url = gw.start()
    ws_url = url.replace("http", "ws") + "ws"

    async def run():
        async with aiohttp.ClientSession() as http:
            with pytest.raises(aiohttp.WSServerHandshakeError) as e:
                await http.ws_connect(ws_url, headers={"Origin": "http://evil.example"})
            assert e.value.status == 403
            async with http.ws_connect(ws_url, headers={"Origin": url.rstrip("/")}) as ws:
                hello = await ws.receive_json(timeout=10)
                sid = hello["session"]
                assert hello["type"] == "hello" and sid.startswith("web-")
                other = schemas.Error(session="someone-else", key="findme/someone-else/x",
                                      code=CODE.ERROR_CODE_INTERNAL, message="not yours")
                mine = schemas.Error(session=sid, key=f"findme/{sid}/x",
                                     code=CODE.ERROR_CODE_INTERNAL, message="yours")
                bus.put(zs, "findme/someone-else/error", schemas.encode(other))
                bus.put(zs, f"findme/{sid}/error", schemas.encode(mine))
                assert (await ws.receive_json(timeout=10))["message"] == "yours"
                await ws.send_str(json.dumps({"type": "select", "index": 0, "rank": 1}))
                got = await ws.receive_json(timeout=10)
                assert (got["code"], got["key"]) == ("NO_SUCH_FRAME", "selection/0")
                await ws.send_bytes(upload_bytes({"id": "x"}, b"GIF89a..."))
                refused = await ws.receive_json(timeout=10)
                err = await ws.receive_json(timeout=10)
                assert refused == {"type": "refused", "id": "x", "key": "frame/0"}
                assert err["code"] == "BAD_IMAGE" and err["key"] == "frame/0"
                await ws.send_str(json.dumps({"type": "ping"}))
                assert (await ws.receive_json(timeout=10))["type"] == "pong"

    try:
        asyncio.run(run())
    finally:
        gw.stop()
        zs.close()


def test_a_measure_passes_what_was_said_on_and_back():
    """On a live bus, with a stand-in measurement service that echoes what was said: a
    measure whose surfaces say something becomes a MeasureRequest with one ``said`` per
    pixel (NONE for null); one that says nothing (no surfaces, or all null) is byte for
    byte the request it was before ``said`` existed; the page's reply carries ``said``."""
    import aiohttp

    zs = bus.open_session()
    seen = []

    def stand_in(query):   # the measurement service's query, answered from the request
        raw = query.payload.to_bytes()
        req = schemas.decode(schemas.MeasureRequest, raw)
        seen.append(raw)
        said = list(req.said) or [schemas.SURFACE_NONE] * len(req.pixels)
        reply = schemas.MeasureReply(session=req.session, index=req.index, rank=1, metric=True)
        for px, s in zip(req.pixels, said):
            reply.points.add(pixel=px, surface=s or schemas.SURFACE_WALL, said=s,
                             xyz=schemas.Vec3(x=0, y=0, z=2), sigma_m=0.1)
        query.reply(str(query.key_expr), schemas.encode(reply))

    q = zs.declare_queryable("findme/*/measure", stand_in)
    gw = Gateway(zs, "127.0.0.1", 0)
    url = gw.start()

    async def run():
        async with aiohttp.ClientSession() as http:
            async with http.ws_connect(url.replace("http", "ws") + "ws") as ws:
                sid = (await ws.receive_json(timeout=10))["session"]
                await ws.send_bytes(upload_bytes({"id": "a"}, ROOM_A))
                assert (await ws.receive_json(timeout=10))["type"] == "frame"
                replies = []
                for i, extra in enumerate([{"surfaces": [None, "floor", "wall"]}, {},
                                           {"surfaces": [None, None, None]}]):
                    await ws.send_str(json.dumps({"type": "measure", "id": i, "index": 0,
                                                  "pixels": [[1, 2], [3, 4], [5, 6]], **extra}))
                    while (m := await ws.receive_json(timeout=10))["type"] != "measure":
                        pass
                    assert m["id"] == i and not m["error"], m
                    replies.append(m)
                return sid, replies

    try:
        sid, replies = asyncio.run(run())
    finally:
        gw.stop()
        q.undeclare()
        zs.close()
    reqs = [schemas.decode(schemas.MeasureRequest, r) for r in seen]
    assert list(reqs[0].said) == [schemas.SURFACE_NONE, schemas.SURFACE_FLOOR,
                                  schemas.SURFACE_WALL]
    plain = schemas.MeasureRequest(session=sid, index=0)
    plain.pixels.extend(schemas.pixels_to_msg([(1, 2), (3, 4), (5, 6)]))
    assert seen[1] == seen[2] == schemas.encode(plain)          # nothing said: as before
    assert [p["said"] for p in replies[0]["points"]] == [None, "floor", "wall"]
    assert [p["surface"] for p in replies[0]["points"]] == ["wall", "floor", "wall"]
    assert [p["said"] for p in replies[1]["points"]] == [None] * 3


def test_a_scene_carries_its_walls_on_the_floor():
    """The floor map draws each photo's walls: a scene's boundary as floor segments (metres,
    the photo's level frame), [] when its boundary or camera gives none."""
    from findme_core.geometry.camera import Camera
    from findme_core.single.search import SegKind
    from findme_io.convert import camera_msg
    cam = Camera.from_hfov(70, 640, 480)
    sc = schemas.Scene(session="s", index=0, rank=1, camera=camera_msg(cam), camera_height_m=1.5,
                       polyline=schemas.polyline_to_msg([[0, 300], [cam.cx, 400], [639, 300]],
                                                        [SegKind.WALL, SegKind.WALL]))
    walls = to_page("s", sc)["walls_m"]
    assert len(walls) == 2 and walls[0][1] == walls[1][0]            # a corner
    corner = walls[0][1]
    assert corner[0] == pytest.approx(0.0, abs=1e-3)                # straight ahead,
    assert corner[1] == pytest.approx(1.5 * cam.fy / (400 - cam.cy), rel=1e-3)  # eq. 2
    sc.polyline.CopyFrom(schemas.polyline_to_msg([[0, 100], [639, 100]], [SegKind.WALL]))
    assert to_page("s", sc)["walls_m"] == []                         # above the horizon
