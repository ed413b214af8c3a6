"""How a recorded result and the current one are compared (``findme regress``,
``tools/make_golden.py --check``): field by field within stated tolerances
(``diff_messages``; ``TOLERANCES``), hypotheses whose scores tie matched as a set
(``match_hypotheses``), the ranks recorded results name translated to the current ones
(``ranks_now``). ``COMPARES`` says it all for ``--help`` and the README.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from services.runtime import bus

#: Tolerances of ``findme regress`` (also printed with every failure).
TOL_PX = 1.0                      # a polyline vertex / pixel may move this far (Euclidean)
TOL_M = 1e-3                      # metres: fields ending _m, 3D points (Euclidean)
TOL_RAD = math.radians(0.01)      # radians: fields ending _rad (0.01 deg)
TOL_SCORE = 1e-4                  # hypothesis score and support (absolute)
TOL_FLOAT = 1e-6                  # any other float (relative to max(1, |value|))
#: Not compared: clocks and who answered.
IGNORED = {"time_ns", "timing_ms", "service", "schema"}
TOLERANCES = (f"polyline vertices and pixels within {TOL_PX:g} px; 3D points and lengths "
              f"(_m) within {TOL_M * 1e3:g} mm; angles (_rad) within 0.01 deg; score and "
              f"support within {TOL_SCORE:g}; other numbers within {TOL_FLOAT:g} relative; "
              "integers, enums and text exact; times not compared")
#: Error codes that say how busy the machine was, not what the answer is.
TIMING_ERRORS = ("ERROR_CODE_OVERLOADED",)
#: What ``findme regress`` compares (its ``--help`` and the README say this).
COMPARES = f"""\
Every result the recording holds (hypotheses, scenes, measurements, motions,
poses, trajectory, plan, errors) is compared with the current services' answer
to the same frames and selections, field by field:
  polyline vertices and pixels   within {TOL_PX:g} px (Euclidean)
  3D points, lengths (_m)        within {TOL_M * 1e3:g} mm
  angles (_rad)                  within {math.degrees(TOL_RAD):g} deg
  hypothesis score and support   within {TOL_SCORE:g}
  other numbers                  within {TOL_FLOAT:g} relative
  integers, enums, text          exactly
  clocks, timings, instance ids  not compared
Not failures, because they are timing, not the answer (each named in a note):
  hypotheses whose scores tie (within {TOL_SCORE:g}) trading ranks: matched as a
    set; a recorded selection of one is replayed as that hypothesis at its rank
  latest-state messages ({", ".join(bus.LATEST_STATE_KINDS)}): the last of each is
    compared, however often it was published
  {", ".join(c.replace("ERROR_CODE_", "") for c in TIMING_ERRORS)} errors (how busy a service was)
Errors compare as a multiset of (key, code, message). Exit status 1 on any
difference."""


def _f(x: float) -> str:
    return f"{x:.6g}"


def _diff_scalar(fd, a, b, path: str, parent: str) -> str | None:
    from google.protobuf.descriptor import FieldDescriptor as FD
    if fd.type in (FD.TYPE_DOUBLE, FD.TYPE_FLOAT):
        name = fd.name
        if name.endswith("_m"):
            tol, unit, scale = TOL_M, "mm", 1e3
        elif name.endswith("_rad"):
            tol, unit, scale = TOL_RAD, "deg", math.degrees(1.0)
        elif name in ("score", "support"):
            tol, unit, scale = TOL_SCORE, "", 1.0
        else:
            tol, unit, scale = TOL_FLOAT * max(1.0, abs(a)), "", 1.0
        if math.isnan(a) and math.isnan(b):
            return None
        d = abs(a - b)
        if not d <= tol:
            return (f"{path}: {_f(a)} recorded, {_f(b)} now (off by {_f(d * scale)}"
                    f"{' ' + unit if unit else ''} > {_f(tol * scale)}{' ' + unit if unit else ''})")
        return None
    if a != b:
        if fd.enum_type is not None:
            a, b = fd.enum_type.values_by_number.get(a, a), fd.enum_type.values_by_number.get(b, b)
            a, b = getattr(a, "name", a), getattr(b, "name", b)
        return f"{path}: {a!r} recorded, {b!r} now"
    return None


def _diff_value(fd, a, b, path: str) -> list[str]:
    from google.protobuf.descriptor import FieldDescriptor as FD
    if fd.type != FD.TYPE_MESSAGE:
        d = _diff_scalar(fd, a, b, path, "")
        return [d] if d else []
    t = fd.message_type.full_name
    if t == "findme.v1.Pixel":
        d = math.hypot(a.u - b.u, a.v - b.v)
        if not d <= TOL_PX:
            return [f"{path}: ({a.u:.2f}, {a.v:.2f}) recorded, ({b.u:.2f}, {b.v:.2f}) now "
                    f"(moved {d:.2f} px > {TOL_PX:g} px)"]
        return []
    if t == "findme.v1.Vec3" and fd.name == "xyz":
        d = math.dist((a.x, a.y, a.z), (b.x, b.y, b.z))
        if not d <= TOL_M:
            return [f"{path}: ({a.x:.4f}, {a.y:.4f}, {a.z:.4f}) recorded, ({b.x:.4f}, {b.y:.4f}, "
                    f"{b.z:.4f}) now (moved {d * 1e3:.2f} mm > {TOL_M * 1e3:g} mm)"]
        return []
    return diff_messages(a, b, path)


def diff_messages(a, b, path: str = "") -> list[str]:
    """Readable differences between a recorded and a current message beyond the tolerances."""
    out: list[str] = []
    for fd in a.DESCRIPTOR.fields:
        if fd.name in IGNORED:
            continue
        p = f"{path}.{fd.name}" if path else fd.name
        if fd.is_repeated:
            if fd.message_type is not None and fd.message_type.GetOptions().map_entry:
                da, db = dict(getattr(a, fd.name)), dict(getattr(b, fd.name))
                if sorted(da) != sorted(db):
                    out.append(f"{p}: keys {sorted(da)} recorded, {sorted(db)} now")
                continue
            va, vb = list(getattr(a, fd.name)), list(getattr(b, fd.name))
            if len(va) != len(vb):
                out.append(f"{p}: {len(va)} recorded, {len(vb)} now")
            for i, (x, y) in enumerate(zip(va, vb)):
                out.extend(_diff_value(fd, x, y, f"{p}[{i}]"))
            continue
        if fd.has_presence:
            ha, hb = a.HasField(fd.name), b.HasField(fd.name)
            if ha != hb:
                out.append(f"{p}: {'set' if ha else 'unset'} recorded, {'set' if hb else 'unset'} now")
                continue
            if not ha:
                continue
        out.extend(_diff_value(fd, getattr(a, fd.name), getattr(b, fd.name), p))
    return out


def _without(msg, *names):
    c = type(msg)()
    c.CopyFrom(msg)
    for n in names:
        c.ClearField(n)
    return c


@dataclass
class HypothesisMatch:
    """Recorded and current hypotheses of one photo matched as a set within score ties.

    Attributes:
        ranks: recorded rank -> current rank (1-based) of every matched hypothesis.
        swaps: notes naming the ranks that traded places.
        diffs: the differences that are real (as ``diff_messages`` words them).
    """

    ranks: dict[int, int]
    swaps: list[str]
    diffs: list[str]


def match_hypotheses(rec, now) -> HypothesisMatch:
    """Compare two ``HypothesisSet`` messages, letting hypotheses whose scores tie (consecutive
    ranks within ``TOL_SCORE``, recorded or now) trade places: within such a group each
    recorded hypothesis is matched to an equal current one (within the tolerances, its rank
    aside), its own rank first. What stays unmatched is compared rank by rank."""
    diffs = diff_messages(_without(rec, "hypotheses"), _without(now, "hypotheses"))
    ha, hb = list(rec.hypotheses), list(now.hypotheses)
    n = min(len(ha), len(hb))
    if len(ha) != len(hb):
        diffs.append(f"hypotheses: {len(ha)} recorded, {len(hb)} now")
    same = lambda i, j: not diff_messages(_without(ha[i], "rank"), _without(hb[j], "rank"))  # noqa: E731
    tied = [abs(ha[i].score - ha[i + 1].score) <= TOL_SCORE
            or abs(hb[i].score - hb[i + 1].score) <= TOL_SCORE for i in range(n - 1)]
    ranks, swaps, start = {}, [], 0
    for end in range(1, n + 1):
        if end < n and tied[end - 1]:
            continue
        group, match = range(start, end), {}
        for i in group:                       # its own rank first
            if same(i, i):
                match[i] = i
        for i in group:
            if i not in match:
                j = next((j for j in group if j not in match.values() and same(i, j)), None)
                if j is not None:
                    match[i] = j
        for i in group:
            if i in match:
                ranks[i + 1] = match[i] + 1
        # the unmatched ones, compared in rank order with the current ones left over
        left = [j for j in group if j not in match.values()]
        for i, j in zip([i for i in group if i not in match], left):
            diffs.extend(diff_messages(_without(ha[i], "rank"), _without(hb[j], "rank"),
                                       f"hypotheses[{i}]" + (f" (now [{j}])" if j != i else "")))
        moved = [i for i in match if match[i] != i]
        if moved:
            swaps.append(
                "ranks " + ", ".join(str(i + 1) for i in group) + " tie (scores "
                + ", ".join(f"{ha[i].score:.6g}" for i in group) + f", within {TOL_SCORE:g}) "
                "and traded places: " + ", ".join(f"rank {i + 1} recorded is rank "
                                                  f"{match[i] + 1} now" for i in moved))
        start = end
    for i in range(n, len(ha)):
        ranks.pop(i + 1, None)
    return HypothesisMatch(ranks, swaps, diffs)


def ranks_now(msg, maps: dict[int, dict[int, int]]):
    """A copy of a recorded message with the hypothesis ranks it names (scene, measurement,
    a motion's layouts) translated to the current ranks of the same hypotheses."""
    name = msg.DESCRIPTOR.full_name
    if name in ("findme.v1.Scene", "findme.v1.MeasureReply") and msg.index in maps:
        msg = _without(msg)
        msg.rank = maps[msg.index].get(msg.rank, msg.rank)
    elif name == "findme.v1.Motion" and msg.HasField("layout") and (
            msg.index_a in maps or msg.index_b in maps):
        msg = _without(msg)
        msg.layout.rank_a = maps.get(msg.index_a, {}).get(msg.layout.rank_a, msg.layout.rank_a)
        msg.layout.rank_b = maps.get(msg.index_b, {}).get(msg.layout.rank_b, msg.layout.rank_b)
    return msg
