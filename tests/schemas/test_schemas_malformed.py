"""Bad payloads and invalid messages raise SchemaError naming the type and the problem."""

from __future__ import annotations

import itertools
import math
import random

import pytest
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage

import schemas as S
from findme_core.errors import FindmeError, SchemaError

TYPES = sorted(S.MESSAGE_TYPES)


@pytest.mark.parametrize("type_name", TYPES)
def test_empty_payload(type_name):
    with pytest.raises(SchemaError, match=rf"cannot decode {type_name}: empty payload"):
        S.decode(S.MESSAGE_TYPES[type_name], b"")


def test_schema_error_is_a_findme_error():
    assert issubclass(S.SchemaError, FindmeError) and S.SchemaError is SchemaError
    assert issubclass(S.WrongTypeError, SchemaError)


@pytest.mark.parametrize("expected,actual", list(itertools.permutations(TYPES, 2)))
def test_wrong_type(expected, actual, sample_of):
    data = S.encode(sample_of(actual))
    with pytest.raises(S.WrongTypeError) as info:
        S.decode(S.MESSAGE_TYPES[expected], data)
    assert str(info.value) == f"expected {expected}, got a {actual} message"


def test_truncated_frame(sample_of):
    data = S.encode(sample_of("findme.v1.Frame"))
    with pytest.raises(SchemaError, match=r"cannot decode findme\.v1\.Frame: the \d+-byte "
                                          r"payload is not valid protobuf \(truncated"):
        S.decode(S.Frame, data[: len(data) // 2])


def test_every_truncation_raises_schema_error_or_decodes(sample):
    """Cutting a payload anywhere never escapes as another exception type."""
    data = S.encode(sample)
    cls = type(sample)
    for cut in range(len(data)):
        try:
            S.decode(cls, data[:cut])
        except SchemaError as exc:
            assert cls.DESCRIPTOR.full_name in str(exc)


def test_garbage_bytes():
    rng = random.Random(1234)
    for _ in range(300):
        junk = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64)))
        for cls in S.MESSAGE_TYPES.values():
            with pytest.raises(SchemaError, match=cls.DESCRIPTOR.full_name.replace(".", r"\.")):
                S.decode(cls, junk)
        with pytest.raises(SchemaError):
            S.decode_any(junk)


@pytest.mark.parametrize("junk", [b"\xff" * 8, b"\x00", b"hello world", b"\x0a\x05abc"])
def test_garbage_examples(junk):
    with pytest.raises(SchemaError, match=r"findme\.v1\.Frame"):
        S.decode(S.Frame, junk)


def test_foxglove_image_is_not_a_frame():
    img = CompressedImage(data=b"\xff\xd8\xff\xd9", format="jpeg", frame_id="cam")
    img.timestamp.seconds = 5
    with pytest.raises(SchemaError, match=r"findme\.v1\.Frame"):
        S.decode(S.Frame, img.SerializeToString())


def test_missing_schema_tag(sample_of):
    msg = sample_of("findme.v1.Selection")
    msg.schema = ""
    with pytest.raises(SchemaError, match=r"findme\.v1\.Selection: the \d+-byte payload has "
                                          r"no schema tag \(field 1\)") as info:
        S.decode(S.Selection, msg.SerializeToString())
    assert not isinstance(info.value, S.WrongTypeError)


def test_unknown_schema_tag(sample_of):
    msg = sample_of("findme.v1.Frame")
    msg.schema = "findme.v2.Frame"
    data = msg.SerializeToString()
    with pytest.raises(SchemaError, match=r"schema tag 'findme\.v2\.Frame' is not a known"):
        S.decode(S.Frame, data)
    with pytest.raises(SchemaError, match=r"'findme\.v2\.Frame' is not a known"):
        S.decode_any(data)


@pytest.mark.parametrize("payload", ["a string", 42, None, [1, 2]])
def test_non_bytes_payload(payload):
    with pytest.raises(SchemaError, match=r"cannot decode findme\.v1\.Frame: the payload must "
                                          r"be bytes"):
        S.decode(S.Frame, payload)


def test_not_a_bus_type():
    with pytest.raises(TypeError, match="not a Find Me bus message type"):
        S.decode(S.Pixel, b"\x09" + bytes(8))
    with pytest.raises(TypeError, match="not a Find Me bus message type"):
        S.encode(S.Pixel(u=1, v=2))
    with pytest.raises(TypeError):
        S.encode(CompressedImage())


def test_encode_rejects_a_foreign_schema_tag(sample_of):
    msg = sample_of("findme.v1.Scene")
    msg.schema = "findme.v1.Frame"
    with pytest.raises(SchemaError, match=r"cannot encode findme\.v1\.Scene: schema is "
                                          r"'findme\.v1\.Frame'"):
        S.encode(msg)


def test_encode_fills_the_schema_tag():
    msg = S.Selection(session="s1", index=0, rank=1, by=S.SELECTED_BY_AUTO)
    assert S.decode(S.Selection, S.encode(msg)).schema == "findme.v1.Selection"


# (type, mutation, expected message fragment). Each mutation makes a valid sample invalid.
def _set_image(m, **kw):
    for k, v in kw.items():
        setattr(m.image, k, v)


INVALID = [
    ("findme.v1.Frame", lambda m: setattr(m, "session", ""), "session is empty"),
    ("findme.v1.Frame", lambda m: setattr(m, "session", "a/b"), "session 'a/b' is not"),
    ("findme.v1.Frame", lambda m: setattr(m, "session", ".."), "session '..' is not"),
    ("findme.v1.Frame", lambda m: setattr(m, "session", "x" * 129), "is not 1-128"),
    ("findme.v1.Frame", lambda m: m.ClearField("image"), "image is missing"),
    ("findme.v1.Frame", lambda m: _set_image(m, data=b""), "image.data is empty"),
    ("findme.v1.Frame", lambda m: _set_image(m, format="jpg"),
     "image.format must be one of jpeg, png, webp, avif, got 'jpg'"),
    ("findme.v1.Frame", lambda m: setattr(m, "capture_time_ns", 7),
     "differs from capture_time_ns (7)"),
    ("findme.v1.Frame", lambda m: setattr(m.intrinsics, "fx", 0.0), "intrinsics.fx must be > 0"),
    ("findme.v1.Frame", lambda m: setattr(m.intrinsics, "cy", math.nan),
     "intrinsics.cy must be finite"),
    ("findme.v1.Frame", lambda m: setattr(m.intrinsics, "width", 0), "image size must be positive"),
    ("findme.v1.Frame", lambda m: setattr(m, "hfov_deg", 180.0), "hfov_deg must be in (0, 180)"),
    ("findme.v1.Frame", lambda m: m.gravity.CopyFrom(S.Vec3()), "gravity must not be the zero"),
    ("findme.v1.Frame", lambda m: setattr(m, "gravity_sigma_rad", -0.1),
     "gravity_sigma_rad must be >= 0"),
    ("findme.v1.Frame", lambda m: setattr(m, "heading_rad", math.inf),
     "heading_rad must be finite"),
    ("findme.v1.Frame", lambda m: (m.ClearField("heading_rad"),
                                   setattr(m, "heading_sigma_rad", 0.1)),
     "heading_sigma_rad is set without heading_rad"),
    ("findme.v1.Frame", lambda m: (setattr(m, "heading_rad", 1.0),
                                   setattr(m, "heading_sigma_rad", 2.0)),
     "heading_sigma_rad must be in (0, pi/2]"),
    ("findme.v1.Frame", lambda m: setattr(m, "heading_ref", "north"),
     "heading_ref must be one of"),
    ("findme.v1.Frame", lambda m: (m.ClearField("heading_rad"), m.ClearField("heading_sigma_rad"),
                                   setattr(m, "heading_ref", "M")),
     "heading_ref is set without heading_rad"),
    ("findme.v1.HypothesisSet", lambda m: setattr(m.camera, "gravity_source", "guess"),
     "camera.gravity_source must be one of"),
    ("findme.v1.HypothesisSet", lambda m: setattr(m.camera, "lens_source", "exiff"),
     "camera.lens_source must be one of"),
    ("findme.v1.HypothesisSet", lambda m: m.camera.gravity_cov_rad2.append(1.0),
     "gravity_cov_rad2 must have 0 or 4"),
    ("findme.v1.Scene", lambda m: setattr(m.camera, "gravity_sigma_rad", math.nan),
     "camera.gravity_sigma_rad must be finite"),
    ("findme.v1.Frame", lambda m: setattr(m, "camera_height_m", -1.0),
     "camera_height_m must be > 0, got -1.0"),
    ("findme.v1.Frame", lambda m: setattr(m, "camera_height_sigma_m", math.inf),
     "camera_height_sigma_m must be finite"),
    ("findme.v1.HypothesisSet", lambda m: setattr(m.frame_height, "camera_height_m", 0.0),
     "frame_height.camera_height_m must be > 0, got 0.0"),
    ("findme.v1.HypothesisSet", lambda m: setattr(m.frame_height, "camera_height_sigma_m", -1.0),
     "frame_height.camera_height_sigma_m must be"),
    ("findme.v1.HypothesisSet", lambda m: setattr(m.hypotheses[1], "rank", 1),
     "hypotheses[1].rank must be 2"),
    ("findme.v1.HypothesisSet", lambda m: m.hypotheses[0].polyline.kinds.append(0),
     "hypotheses[0].polyline has 4 points, so needs 3 segment kinds, got 4"),
    ("findme.v1.HypothesisSet", lambda m: m.hypotheses[0].polyline.kinds.__setitem__(0, 9),
     "hypotheses[0].polyline.kinds[0] has unknown value 9"),
    ("findme.v1.HypothesisSet", lambda m: setattr(m.hypotheses[0], "support", 1.5),
     "hypotheses[0].support must be in [0, 1]"),
    ("findme.v1.HypothesisSet", lambda m: setattr(m.hypotheses[0].polyline.points[2], "v",
                                                  math.nan),
     "hypotheses[0].polyline.points[2].v must be finite"),
    ("findme.v1.HypothesisSet", lambda m: (m.hypotheses[0].polyline.points.extend(
        [S.Pixel(u=1, v=2)] * 4093), m.hypotheses[0].polyline.kinds.extend([0] * 4093)),
     "hypotheses[0].polyline: at most 4096 points, got 4097"),
    ("findme.v1.Scene", lambda m: m.polyline.points.extend([S.Pixel(u=1, v=2)] * 5000),
     "polyline: at most 4096 points, got 5004"),
    ("findme.v1.HypothesisSet", lambda m: m.lines.append(1.0),
     "lines must hold 4 numbers per line (u1, v1, u2, v2), got 9"),
    ("findme.v1.HypothesisSet", lambda m: m.lines.__setitem__(5, math.inf),
     "lines[5] must be finite"),
    ("findme.v1.HypothesisSet", lambda m: m.lines.extend([0.0] * 4 * 4096),
     "lines: at most 4096 lines, got 4098"),
    ("findme.v1.HypothesisSet", lambda m: (m.ClearField("hypotheses"), setattr(m, "reason", "")),
     "no hypotheses and no reason"),
    ("findme.v1.HypothesisSet", lambda m: m.timing_ms.__setitem__("x", -1.0),
     "timing_ms['x'] must be >= 0"),
    ("findme.v1.Selection", lambda m: setattr(m, "rank", 0), "rank must be >= 1"),
    ("findme.v1.Selection", lambda m: setattr(m, "by", 0), "by is unset (SELECTED_BY_UNSPECIFIED)"),
    ("findme.v1.Selection", lambda m: setattr(m, "by", 7), "by has unknown value 7"),
    ("findme.v1.Scene", lambda m: m.camera.ClearField("intrinsics"), "camera.intrinsics is missing"),
    ("findme.v1.Scene", lambda m: setattr(m, "camera_height_m", 0.0), "camera_height_m must be > 0"),
    ("findme.v1.Scene", lambda m: m.ClearField("polyline"), "polyline needs at least 2 points"),
    ("findme.v1.MeasureRequest", lambda m: m.ClearField("pixels"), "pixels is empty"),
    ("findme.v1.MeasureRequest", lambda m: m.said.append(S.SURFACE_WALL),
     "said has 4 surfaces for 3 pixels: give none or one per pixel"),
    ("findme.v1.MeasureRequest", lambda m: m.said.__setitem__(1, 7), "said[1] has unknown value 7"),
    ("findme.v1.MeasureRequest", lambda m: m.pixels.extend([S.Pixel(u=1, v=2)] * 1030),
     "1033 pixels in one request, over the limit of 1024"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.points[0], "said", S.SURFACE_WALL),
     "points[0] was said to be on SURFACE_WALL but is on SURFACE_FLOOR"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.points[1], "said", 9),
     "points[1].said has unknown value 9"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.points[1], "surface", S.SURFACE_TOP),
     "points[1] is on a top, which only a point said to be there is"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.points[0], "said", S.SURFACE_TOP),
     "points[0] was said to be on SURFACE_TOP but is on SURFACE_FLOOR"),
    ("findme.v1.Scene", lambda m: m.lines.append(3.0), "lines must hold 4 numbers per line"),
    ("findme.v1.Scene", lambda m: m.lines.__setitem__(1, float("nan")), "lines[1] must be finite"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.points[2], "surface", S.SURFACE_FLOOR),
     "points[2] has an error, so must have no xyz, sigma_m, surface or note"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.points[2], "note", "the line runs below"),
     "points[2] has an error, so must have no xyz, sigma_m, surface or note"),
    ("findme.v1.MeasureReply", lambda m: m.points[0].ClearField("xyz"),
     "points[0] has neither xyz nor error"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.points[1], "surface", S.SURFACE_NONE),
     "points[1] has no error, so needs a surface"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.distances[0], "b", 5),
     "distances[0] joins points 0 and 5"),
    ("findme.v1.MeasureReply", lambda m: setattr(m.distances[1], "distance_m", 1.0),
     "distances[1] has an error, so must have no distance_m"),
    ("findme.v1.MeasureReply", lambda m: setattr(m, "error", "boom"),
     "a failed request (error set) must carry no points"),
    ("findme.v1.Motion", lambda m: setattr(m, "error", "too few matches"),
     "a failed motion (error set) must carry no numbers, has x_m, z_m, yaw_rad"),
    ("findme.v1.Motion", lambda m: m.ClearField("yaw_rad"), "yaw_rad missing and no error"),
    ("findme.v1.Motion", lambda m: setattr(m, "index_b", 3), "index_a and index_b are both 3"),
    ("findme.v1.Motion", lambda m: setattr(m, "sigma_z_m", -0.1), "sigma_z_m must be >= 0"),
    ("findme.v1.Motion", lambda m: setattr(m, "inliers", 1000), "inliers (1000) exceed matches"),
    ("findme.v1.Motion", lambda m: (m.ClearField("x_m"), m.ClearField("z_m"), m.ClearField("yaw_rad"),
                                    *(m.ClearField(f) for f in ("sigma_x_m", "sigma_z_m", "sigma_yaw_rad")),
                                    setattr(m, "error", "boom")),
     "a failed motion (error set) must carry no score, layout, alternatives or appearance"),
    ("findme.v1.Motion", lambda m: setattr(m, "appearance", 1.5),
     "appearance is a correlation in [-1, 1], got 1.5"),
    ("findme.v1.Motion", lambda m: m.alternatives.extend([m.alternatives[0]] * 8),
     "alternatives: at most 8, got 9"),
    ("findme.v1.Motion", lambda m: setattr(m.alternatives[0], "sigma_yaw_rad", -1.0),
     "alternatives[0].sigma_yaw_rad must be >= 0"),
    ("findme.v1.Motion", lambda m: setattr(m.layout, "rms_m", math.inf),
     "layout.rms_m must be finite"),
    ("findme.v1.Motion", lambda m: setattr(m.layout, "rank_b", 0), "layout ranks start at 1"),
    ("findme.v1.Pose", lambda m: setattr(m, "x_m", math.nan), "x_m must be finite"),
    ("findme.v1.Trajectory", lambda m: setattr(m.poses[2], "index", 3),
     "poses[2].index 3 out of order"),
    ("findme.v1.Trajectory", lambda m: setattr(m.poses[0], "session", "other"),
     "poses[0].session 'other' differs"),
    ("findme.v1.Trajectory", lambda m: setattr(m.poses[0], "schema", "findme.v1.Frame"),
     "poses[0].schema must be empty or findme.v1.Pose"),
    ("findme.v1.Plan", lambda m: m.walls.pop(), "walls must be one per polygon edge"),
    ("findme.v1.Plan", lambda m: setattr(m, "reason", "too few photos"),
     "a plan with a reason (no outline yet) must carry no polygon or walls"),
    ("findme.v1.Plan", lambda m: (m.ClearField("polygon"), m.ClearField("walls")),
     "polygon needs at least 3 vertices"),
    ("findme.v1.Plan", lambda m: setattr(m.polygon[2], "x_m", math.nan),
     "polygon[2].x_m must be finite"),
    ("findme.v1.Plan", lambda m: setattr(m.walls[1], "length_m", 0.0),
     "walls[1].length_m must be > 0"),
    ("findme.v1.Plan", lambda m: setattr(m.walls[2], "kind", 0),
     "walls[2].kind is unset (WALL_KIND_UNSPECIFIED)"),
    ("findme.v1.Plan", lambda m: setattr(m.walls[0].openings[0], "to_m", 7.0),
     "walls[0].openings[0] (1.2 to 7.0 m) must lie within"),
    ("findme.v1.Plan", lambda m: setattr(m.poses[2], "index", 0),
     "poses[2].index 0 out of order"),
    ("findme.v1.Plan", lambda m: m.poses[1].ClearField("yaw_rad"),
     "poses[1] is PLACED but has no yaw_rad"),
    ("findme.v1.Plan", lambda m: setattr(m.poses[3], "x_m", 1.0),
     "poses[3] is not placed, so must carry no numbers, has x_m"),
    ("findme.v1.Plan", lambda m: setattr(m.poses[0], "reason", ""),
     "poses[0] is not placed and says no reason"),
    ("findme.v1.Plan", lambda m: setattr(m.poses[2], "sigma_z_m", -1.0),
     "poses[2].sigma_z_m must be >= 0"),
    ("findme.v1.Plan", lambda m: setattr(m.polygon[1], "sigma_z_m", -0.1),
     "polygon[1].sigma_z_m must be >= 0"),
    ("findme.v1.Plan", lambda m: setattr(m.polygon[0], "sigma_x_m", 0.1),
     "polygon[0] has sigma_x_m without the other axis's 1-sigma"),
    ("findme.v1.Plan", lambda m: setattr(m, "closed", True),
     "closed is True but the missing walls are [3]"),
    ("findme.v1.Plan", lambda m: setattr(m, "camera_height_m", 0.0),
     "camera_height_m must be > 0"),
    ("findme.v1.Error", lambda m: setattr(m, "code", 0), "code is unset (ERROR_CODE_UNSPECIFIED)"),
    ("findme.v1.Error", lambda m: setattr(m, "message", " "), "message is empty"),
    ("findme.v1.Error", lambda m: setattr(m, "session", "a b"), "session 'a b' is not"),
    ("findme.v1.ServiceStatus", lambda m: setattr(m, "instance", ""), "instance is empty"),
]


@pytest.mark.parametrize("type_name,mutate,fragment", INVALID,
                         ids=[f"{t.split('.')[-1]}-{i}" for i, (t, _, _) in enumerate(INVALID)])
def test_invalid_fields(type_name, mutate, fragment, sample_of):
    msg = sample_of(type_name)
    mutate(msg)
    with pytest.raises(SchemaError) as info:
        S.decode(type(msg), msg.SerializeToString())
    assert str(info.value).startswith(f"invalid {type_name}: ")
    assert fragment in str(info.value)
    with pytest.raises(SchemaError) as info:
        S.encode(msg)
    assert str(info.value).startswith(f"cannot encode {type_name}: ")
    assert fragment in str(info.value)
    with pytest.raises(SchemaError, match="invalid"):
        S.validate(msg)
    # Without checks the bytes still round-trip (tools that inspect bad data).
    assert S.decode(type(msg), S.encode(msg, check=False), check=False) == msg


def test_many_problems_are_summarised(sample_of):
    msg = sample_of("findme.v1.MeasureRequest")
    for px in msg.pixels:
        px.u = px.v = math.nan
    with pytest.raises(SchemaError, match=r"; and 1 more$"):
        S.decode(S.MeasureRequest, msg.SerializeToString())


def test_session_pattern():
    for ok in ("s1", "2024-05-01T10-00-00Z_pixel7", "a.b", "_x", "-", "A" * 128):
        assert S.is_valid_session(ok), ok
    for bad in ("", ".", "..", ".hidden", "a/b", "a*", "a$b", "a b", "é", "A" * 129, "@x", None):
        assert not S.is_valid_session(bad), bad
