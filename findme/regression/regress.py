"""``findme regress``: a recording's inputs run again through the current services, every
result compared with the recorded one (``regress`` -> ``Regression``), field by field
(``diff.diff_messages``). ``diff.COMPARES`` says what is compared, for ``--help`` and the README.

Tolerances (``TOLERANCES``, printed with every failure): pixels and polyline vertices
``TOL_PX`` (px, Euclidean, bus pixel convention); fields ending ``_m`` and 3D points
``TOL_M`` (metres, Euclidean; reported in mm); fields ending ``_rad`` ``TOL_RAD`` (radians;
reported in degrees); score and support ``TOL_SCORE``; other floats ``TOL_FLOAT`` relative;
integers, enums and text exact. Clocks and who answered (``IGNORED``) are not compared.
Errors compare as a multiset of (key, code, message). The recording is only read.

What is a property of timing, not of the answer, is not a failure:

* hypotheses whose scores lie within ``TOL_SCORE`` of each other are a tie, and their ranks
  may trade places: they are matched as a set (``match_hypotheses``) and the swap is named in
  a note. A recorded selection of a swapped hypothesis is replayed as the same hypothesis
  at its current rank, and the ranks the results name (scene, measurement, a motion's
  layouts) are compared through that map;
* latest-state messages (``bus.LATEST_STATE_KINDS``: trajectory, plan), republished as a
  session grows, compare by their last message, however often they were published;
* errors that say how busy the machine was (``TIMING_ERRORS``: OVERLOADED) are left out (a
  recording whose services dropped a photo under load lacks that photo's results, which the
  replay gives: those still differ, as a session that lost a photo is another session).
"""

from __future__ import annotations

import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field

import schemas
from services.runtime import bus
from services.recording.mcap_reader import read_recording, recording_session

from .diff import TIMING_ERRORS, TOLERANCES, diff_messages, match_hypotheses, ranks_now
from .replay import INPUT_KINDS, Source, Watch, ask_measure, measure_request

#: Result kinds only the odometry service produces.
ODOMETRY_KINDS = ("motion", "pose", "trajectory")

@dataclass
class Regression:
    """The outcome of ``regress``: what was compared and every difference found."""

    recording: str
    session: str
    compared: int = 0
    differences: dict[str, list[str]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.differences

    def report(self) -> str:
        lines = [f"regress {self.recording} (session {self.session}): {self.compared} results "
                 f"compared, {len(self.differences)} differ"]
        lines += [f"  note: {n}" for n in self.notes]
        for key, diffs in self.differences.items():
            lines.append(f"  {key}:")
            lines += [f"    {d}" for d in diffs[:12]]
            if len(diffs) > 12:
                lines.append(f"    ... and {len(diffs) - 12} more")
        lines.append(("PASS" if self.ok else "FAIL") + f" (tolerances: {TOLERANCES})")
        return "\n".join(lines)


def _short(key: str, session: str) -> str:
    p = f"{bus.ROOT}/{session}/"
    return key[len(p):] if key.startswith(p) else key


def _error_sig(payload: bytes) -> tuple:
    try:
        e = schemas.decode(schemas.Error, payload, check=False)
        return (e.key, schemas.ErrorCode.Name(e.code), e.message)
    except Exception:  # noqa: BLE001
        return ("?", "?", payload[:40].hex())


def regress(path, *, method: str | None = None, max_n: int = 10, timeout: float = 120.0,
            handlers=None) -> Regression:
    """Replay a recording's frames, selections and measurements through the current services
    (embedded, one in-process Zenoh session, as ``findme run``) and compare every result
    with the recorded one. ``handlers`` replaces the services (tests)."""
    from services.runtime.service import Group

    recs = read_recording(path)
    session_id = recording_session(path)
    out = Regression(str(path), session_id)
    recs = [r for r in recs if bus.parse_key(r.key).session == session_id]
    expected: dict[str, list[bytes]] = defaultdict(list)
    for r in recs:
        kind = bus.parse_key(r.key).kind
        if kind not in INPUT_KINDS and kind != "measured":
            expected[r.key].append(r.payload)
    kinds = {bus.parse_key(k).kind for k in expected}
    if handlers is None:
        handlers = _handlers(recs, kinds, method, max_n, out.notes)

    session = bus.open_session(bus.BusConfig())   # peer, no endpoints: in-process only
    group = Group(session)
    watch = Watch(session, session_id)
    measured_now: list[tuple[str, bytes | None, str]] = []
    rank_maps: dict[int, dict[int, int]] = {}   # photo -> recorded rank -> current rank
    try:
        for h in handlers:
            group.add(h)
        source = Source(session, session_id)
        scenes = Counter()   # each photo's scenes recorded so far
        for r in recs:
            k = bus.parse_key(r.key)
            if k.kind == "scene":
                scenes[r.key] += 1
            if k.kind == "frame":
                source.put(r.key, r.payload)
            elif k.kind == "selection":
                need = bus.key(session_id, "hypotheses", *k.parts)
                wait_result(group, watch, lambda c, need=need: c[need] > 0, timeout)
                source.put(r.key, _same_choice(r.payload, expected.get(need), watch, need,
                                               rank_maps, out.notes))
            elif k.kind == "measured":
                # asked when the photo's scene is as it was when recorded (built, or built
                # again under a gravity a motion agreed on)
                need = bus.key(session_id, "scene", *k.parts)
                at = max(scenes[need], 1)
                wait_result(group, watch, lambda c, need=need, at=at: c[need] >= at, timeout)
                rep = schemas.decode(schemas.MeasureReply, r.payload, check=False)
                payload, err = ask_measure(session, session_id, measure_request(rep), timeout)
                measured_now.append((r.key, payload, err))
        # every recorded result as often as it was recorded (or quiet: it will not come);
        # then quiet, so that extra results are seen too
        wait_result(group, watch, lambda c: all(c[k] >= len(v) for k, v in expected.items()),
                    timeout)
        wait_result(group, watch, lambda c: False, timeout)
        source.close()
    finally:
        watch.close()
        group.stop()
        session.close()

    got: dict[str, list[bytes]] = defaultdict(list)
    for k, payload in watch.got:
        if bus.parse_key(k).kind not in INPUT_KINDS + ("measured",):
            got[k].append(payload)
    compare_results(expected, got, out, rank_maps)
    recorded_measures = [r for r in recs if bus.parse_key(r.key).kind == "measured"]
    for i, (r, (key, payload, err)) in enumerate(zip(recorded_measures, measured_now)):
        short = f"{_short(key, session_id)} (measurement {i + 1})"
        out.compared += 1
        if payload is None:
            out.differences[short] = [f"no answer now: {err}"]
            continue
        diffs = _compare_payloads(r.payload, payload, rank_maps)
        if diffs:
            out.differences[short] = diffs
    return out


def compare_results(expected: dict, got: dict, out: Regression,
                    rank_maps: dict | None = None) -> None:
    """Compare recorded and current results, {key: [payload, ...]} each, of ``out.session``
    (see the module docstring), adding to ``out``'s differences and notes; ``rank_maps``
    (photo -> recorded rank -> current rank) is used and completed."""
    session_id = out.session
    rank_maps = {} if rank_maps is None else rank_maps
    for key in sorted(set(expected) | set(got)):
        short = _short(key, session_id)
        rec_list, now_list = expected.get(key, []), got.get(key, [])
        kind = bus.parse_key(key).kind
        out.compared += 1
        if kind == "error":   # a multiset of errors, those of timing left out
            sigs = [list(map(_error_sig, x)) for x in (rec_list, now_list)]
            timing = [sum(e[1] in TIMING_ERRORS for e in x) for x in sigs]
            if any(timing):
                out.notes.append(f"{short}: not compared, timing: {timing[0]} recorded and "
                                 f"{timing[1]} current {'/'.join(TIMING_ERRORS)}")
            a, b = (Counter(e for e in x if e[1] not in TIMING_ERRORS) for x in sigs)
            diffs = [f"recorded, not now: {e[0]}: {e[1]}: {e[2]}" for e in (a - b).elements()]
            diffs += [f"now, not recorded: {e[0]}: {e[1]}: {e[2]}" for e in (b - a).elements()]
            if diffs:
                out.differences[short] = diffs
            continue
        if not now_list:
            out.differences[short] = [f"missing: recorded {len(rec_list)} message(s), none now"]
            continue
        if not rec_list:
            out.differences[short] = [f"new: {len(now_list)} message(s) now, none recorded"]
            continue
        diffs = []
        # latest state (bus.LATEST_STATE_KINDS): how often it is republished is timing
        if len(rec_list) != len(now_list) and kind not in bus.LATEST_STATE_KINDS:
            diffs.append(f"published {len(rec_list)} time(s) when recorded, {len(now_list)} now "
                         "(comparing the last)")
        if kind == "hypotheses":
            m = _match_payloads(rec_list[-1], now_list[-1])
            if isinstance(m, list):
                diffs += m
            else:
                diffs += m.diffs
                out.notes += [f"{short}: {w}" for w in m.swaps]
                rank_maps.setdefault(_photo(key), m.ranks)
        else:
            diffs += _compare_payloads(rec_list[-1], now_list[-1], rank_maps)
        if diffs:
            out.differences[short] = diffs


def _photo(key: str) -> int:
    """The photo a per-photo key names (``.../hypotheses/<n>``)."""
    return int(bus.parse_key(key).parts[-1])


def _match_payloads(recorded: bytes, now: bytes):
    """``match_hypotheses`` of two payloads, or the list of differences when one does not
    decode as a hypothesis set."""
    try:
        a = schemas.decode(schemas.HypothesisSet, recorded, check=False)
        b = schemas.decode(schemas.HypothesisSet, now, check=False)
    except Exception:  # noqa: BLE001 - not a hypothesis set: compared as any payload
        return _compare_payloads(recorded, now)
    return match_hypotheses(a, b)


def _same_choice(payload: bytes, recorded_sets, watch: Watch, key: str,
                 rank_maps: dict, notes: list[str]) -> bytes:
    """A recorded selection, to replay: the same hypothesis the user chose, at its current
    rank when it traded places with a tied one (``match_hypotheses``); ``rank_maps`` learns
    the photo's map."""
    with watch.cv:
        now = [p for k, p in watch.got if k == key]
    if not recorded_sets or not now:
        return payload
    m = _match_payloads(recorded_sets[-1], now[-1])
    if isinstance(m, list):
        return payload
    n = _photo(key)
    rank_maps[n] = m.ranks
    try:
        sel = schemas.decode(schemas.Selection, payload, check=False)
    except Exception:  # noqa: BLE001 - replayed as recorded; its error will show
        return payload
    rank = m.ranks.get(sel.rank, sel.rank)
    if rank == sel.rank:
        return payload
    notes.append(f"selection/{n}: rank {sel.rank} recorded is replayed as rank {rank}, the "
                 "same hypothesis (a score tie traded their places)")
    sel.rank = rank
    return sel.SerializeToString(deterministic=True)


def _compare_payloads(recorded: bytes, now: bytes, rank_maps=None) -> list[str]:
    try:
        a = schemas.decode_any(recorded, check=False)
    except Exception as e:  # noqa: BLE001
        return [f"the recorded payload does not decode ({e})"] if recorded != now else []
    try:
        b = schemas.decode_any(now, check=False)
    except Exception as e:  # noqa: BLE001
        return [f"the current payload does not decode ({e})"]
    if type(a) is not type(b):
        return [f"a {a.DESCRIPTOR.full_name} recorded, a {b.DESCRIPTOR.full_name} now"]
    return diff_messages(ranks_now(a, rank_maps) if rank_maps else a, b)


def wait_result(group, watch: Watch, pred, timeout: float, step: float = 0.05) -> bool:
    """Until ``pred(counts)`` holds (True), or the bus has gone quiet without it (False):
    every service idle and nothing new arriving for three steps in a row, so it will not
    come. ``timeout`` caps the wait. With ``pred`` never true this waits for quiet."""
    deadline = time.monotonic() + timeout
    last, stable = None, 0
    while True:
        if watch.wait(pred, step):
            return True
        with watch.cv:
            n = len(watch.got)
        idle = all(s.idle.is_set() for s in group.services)
        state = (n, tuple(s.counters.frames_in for s in group.services))
        stable = stable + 1 if (idle and state == last) else 0
        last = state
        if stable >= 3 or time.monotonic() > deadline:
            with watch.cv:
                return bool(pred(watch.count))


def _handlers(recs, kinds, method, max_n, notes) -> list:
    from services.pipeline.hypotheses import HypothesesHandler
    from services.pipeline.measurement import MeasurementHandler
    if method is None:
        for r in recs:
            if bus.parse_key(r.key).kind == "hypotheses":
                m = schemas.decode(schemas.HypothesisSet, r.payload, check=False).method
                method = m.split("/", 1)[0] if m else None
                break
    hs = [HypothesesHandler(method or "findme", max_n), MeasurementHandler()]
    if kinds & set(ODOMETRY_KINDS):
        try:
            from services.pipeline.odometry import OdometryHandler
            hs.append(OdometryHandler())
        except ImportError:
            notes.append("the recording has odometry results but this build has no odometry "
                         "service")
    else:
        notes.append("odometry not run: the recording has no motion, pose or trajectory")
    if "plan" in kinds:   # the recording was made with a mapper
        from services.pipeline.mapper import MapperHandler
        hs.append(MapperHandler())
    return hs
