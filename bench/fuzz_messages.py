"""Malformed bus messages for bench/bench_fuzz_bus.py: a valid template of every message
type, mutations of it (random bytes, truncation, bit flips, another type, absurd values,
key/payload mismatches, keys that name no valid session or photo), and the verdict a
service's decoding, schema checks and key authority give each one.

Keys: ``kind/<i>`` with a message number ``i`` unique in the run (``motion/<i>/<i+1>``;
``trajectory``, ``error`` and ``measure`` are per session).
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

import schemas
from findme_core.errors import FindmeError
from findme_io.convert import make_frame
from services.runtime import authority

SESSIONS = [f"fz{i:02d}" for i in range(64)]
BAD_SESSIONS = ["x" * 200, "..", ".hidden", "a b", "séance"]
U32 = 2 ** 32 - 1


@functools.cache
def tiny_jpeg():
    img = np.zeros((48, 64, 3), np.uint8)
    cv2.rectangle(img, (5, 30), (60, 47), (200, 200, 200), -1)
    return cv2.imencode(".jpg", img)[1].tobytes()


def templates(session: str, i: int) -> dict:
    """A valid message of every type whose key rule is kind/<i> (motion: <i>/<i+1>)."""
    jpg = tiny_jpeg()
    f = make_frame(session, i, jpg, hfov_deg=60.0, gravity=(0.0, 1.0, 0.0), camera_height_m=1.4,
                   device="fuzz")
    poly = schemas.polyline_to_msg(np.array([[0, 40.0], [63, 40.0]]), np.array([0]))
    hs = schemas.HypothesisSet(session=session, index=i, width=64, height=48, method="fuzz",
                               hypotheses=[schemas.Hypothesis(rank=1, score=0.5, support=0.5,
                                                              polyline=poly)])
    sel = schemas.Selection(session=session, index=i, rank=1, by=schemas.SELECTED_BY_USER,
                            time_ns=1)
    cam = schemas.Camera(intrinsics=schemas.Intrinsics(fx=50, fy=50, cx=31.5, cy=23.5, width=64,
                                                       height=48),
                         gravity=schemas.Vec3(x=0, y=1, z=0))
    sc = schemas.Scene(session=session, index=i, rank=1, camera=cam, camera_height_m=1.4,
                       metric=True, polyline=poly, time_ns=1)
    mo = schemas.Motion(session=session, index_a=i, index_b=i + 1, x_m=0.1, z_m=0.2, yaw_rad=0.1,
                        sigma_x_m=0.01, sigma_z_m=0.01, sigma_yaw_rad=0.01, method="fuzz")
    po = schemas.Pose(session=session, index=i, x_m=0.1, z_m=0.2, yaw_rad=0.1, time_ns=1)
    tr = schemas.Trajectory(session=session, poses=[schemas.Pose(index=0)], time_ns=1)
    er = schemas.Error(session=session, key=f"findme/{session}/frame/{i}", code=1, message="m",
                       time_ns=1, service="fuzz")
    rq = schemas.MeasureRequest(session=session, index=i, pixels=[schemas.Pixel(u=1, v=40)])
    mr = schemas.MeasureReply(session=session, index=i, error="none")
    out = {"frame": f, "hypotheses": hs, "selection": sel, "scene": sc, "motion": mo,
           "pose": po, "trajectory": tr, "error": er, "measured": mr, "measure": rq}
    for m in out.values():
        m.schema = m.DESCRIPTOR.full_name
    return out


KIND_TYPE = {k: type(m) for k, m in templates("s", 0).items()}


def key_of_kind(session, kind, i):
    if kind == "motion":
        return f"findme/{session}/motion/{i}/{i + 1}"
    if kind in ("trajectory", "error", "measure"):
        return f"findme/{session}/{kind}"
    return f"findme/{session}/{kind}/{i}"


# ------------------------------------------------------------------------------ mutations
def absurd(rng, m):
    """Set one field to something absurd: NaN, infinities, huge numbers or counts, empty or
    unknown values (the message is serialised without the schema checks)."""
    choices = []
    for fd in m.DESCRIPTOR.fields:
        if fd.is_repeated or fd.message_type is not None:
            continue
        choices.append(fd)
    fd = rng.choice(choices)
    t = fd.type
    if t in (fd.TYPE_DOUBLE, fd.TYPE_FLOAT):
        setattr(m, fd.name, rng.choice([math.nan, math.inf, -math.inf, 1e308, -1e308, 0.0, -1.0]))
    elif t in (fd.TYPE_UINT32, fd.TYPE_UINT64, fd.TYPE_INT32, fd.TYPE_INT64, fd.TYPE_ENUM):
        setattr(m, fd.name, rng.choice({fd.TYPE_UINT32: [0, U32, 1234567],
                                        fd.TYPE_UINT64: [0, 2 ** 64 - 1],
                                        fd.TYPE_ENUM: [0, 999, 2 ** 31 - 1]}.get(t, [-1, 0])))
    elif t == fd.TYPE_STRING:
        setattr(m, fd.name, rng.choice(["", "x" * 5000, "../../etc", "\u202e\x00"]))
    elif t == fd.TYPE_BOOL:
        setattr(m, fd.name, True)
    # nested absurdities where the type has them
    name = m.DESCRIPTOR.name
    if name == "Frame" and rng.random() < 0.5:
        g = rng.choice([(math.nan, 1, 0), (0, 0, 0), (0, 0, 1), (1e300, 1e300, 1e300)])
        m.gravity.x, m.gravity.y, m.gravity.z = g
    if name == "Frame" and rng.random() < 0.3:
        m.intrinsics.width, m.intrinsics.height = U32, U32
        m.intrinsics.fx = m.intrinsics.fy = rng.choice([-1.0, 0.0, math.nan, 1e-300])
    if name == "HypothesisSet" and rng.random() < 0.3:
        h = m.hypotheses[0] if m.hypotheses else m.hypotheses.add()
        h.polyline.points.add(u=math.nan, v=-1e9)
        if rng.random() < 0.05:
            for _ in range(5000):
                m.hypotheses.add(rank=0)
    if name == "MeasureRequest" and rng.random() < 0.5:
        for _ in range(rng.choice([0] * 9 + [10000])):
            m.pixels.add(u=math.nan, v=math.inf)
    return m.SerializeToString()


def mutate(rng, kind, session, i, good):
    """(category, key, payload) of one mutation of ``good`` (kind's template)."""
    key = key_of_kind(session, kind, i)
    enc = good.SerializeToString()
    c = rng.choices(["random", "truncated", "bitflip", "wrong_type", "absurd", "mismatch",
                     "bad_key"], [15, 15, 15, 10, 20, 15, 10])[0]
    if c == "random":
        n = min(int(rng.expovariate(1 / 200)), 1 << 20) if rng.random() > 0.002 else 4 << 20
        return c, key, rng.randbytes(n)
    if c == "truncated":
        return c, key, enc[:rng.randrange(len(enc))]
    if c == "bitflip":
        b = bytearray(enc)
        for _ in range(rng.randint(1, 8)):
            op, p = rng.random(), rng.randrange(len(b))
            if op < 0.6:
                b[p] ^= 1 << rng.randrange(8)
            elif op < 0.8:
                b.insert(p, rng.randrange(256))
            elif len(b) > 1:
                del b[p]
        return c, key, bytes(b)
    if c == "wrong_type":
        other = rng.choice([k for k in KIND_TYPE if KIND_TYPE[k] is not type(good)])
        return c, key, templates(session, i)[other].SerializeToString()
    if c == "absurd":
        m = type(good)()
        m.CopyFrom(good)
        return c, key, absurd(rng, m)
    if c == "mismatch":
        m = type(good)()
        m.CopyFrom(good)
        what = rng.choice(["session", "index", "kind"]) if key.count("/") > 2 and \
            kind not in ("measure", "trajectory", "error") else "session"
        if what == "session" or not any(f.name.startswith("index") for f in m.DESCRIPTOR.fields):
            m.session = rng.choice(["bob-1", "web-0123456789ab", session + "x"])
        elif what == "index":
            f = [f.name for f in m.DESCRIPTOR.fields if f.name.startswith("index")][0]
            setattr(m, f, rng.choice([U32, getattr(m, f) + 1, 0 if getattr(m, f) else 7]))
        else:
            other = rng.choice([k for k in ("frame", "hypotheses", "selection") if k != kind])
            return c, key_of_kind(session, other, i), enc     # a message on another kind's key
        return c, key, m.SerializeToString()
    # bad_key: a valid payload on a key whose session or photo number is not valid
    how = rng.random()
    if how < 0.6 or kind in ("trajectory", "error", "measure"):
        s = rng.choice(BAD_SESSIONS)
        return c, key_of_kind(s, kind, i), enc
    part = rng.choice(["-1", f"{i:07d}", "x", "4294967296", "1e3"])
    return c, key.rsplit("/", 1)[0] + "/" + part if kind != "motion" else \
        f"findme/{session}/motion/{part}/{i + 1}", enc


def verdict(kind, key, payload):
    """What a service with a typed input on ``kind`` does with it: 'refused' (decode, schema
    checks or the key authority, as Service.process does) or 'valid'."""
    try:
        msg = schemas.decode(KIND_TYPE[kind], payload)
        authority.check(key, msg)
    except FindmeError:
        return "refused"
    return "valid"
