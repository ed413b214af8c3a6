"""Make the golden recordings of the regression suite (recordings/golden/*.mcap).

    python tools/make_golden.py            # rewrite them
    python tools/make_golden.py --check    # exit 1 if a fresh run differs from the files
                                           # (beyond findme regress's tolerances)

Run it after an INTENDED change of behaviour (new ranking weights, a fixed bug, a new
service such as odometry whose results should be covered), check ``git diff --stat
recordings/golden`` and ``findme regress`` on the old files to see what moved, and commit
the new files with the change. Never to make a failing regression test pass by itself.

Each golden session runs the embedded pipeline (as ``findme run``: capture, hypotheses,
selection, measurement, odometry when installed) with the recorder, on pictures the project
may ship: the bundled examples (rendered by tools/make_examples.py) and rooms rendered here by
``findme_core.synth.render``; never ../shared data. The recording is then made deterministic: its
messages are put in a canonical order (photo, then pipeline stage), log times become a fixed
clock (T0 + photo s + stage ms), time fields become those log times, stage timings 0 and
instance ids "golden"; so the same code gives byte-identical files on one machine. On
another (another OpenBLAS kernel, other CPU features) the floats may differ in their last
bits: ``--check`` then compares the files message by message within ``findme regress``'s
tolerances, the inputs (frames, selections) byte for byte.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import findme  # noqa: E402,F401 - first: drops an OPENBLAS_CORETYPE this CPU cannot run
import schemas  # noqa: E402
from findme_io.imageio import encode_jpeg  # noqa: E402
from services.runtime import bus  # noqa: E402
from findme_io.convert import make_frame  # noqa: E402
from services.recording.mcap_reader import read_recording  # noqa: E402
from services.recording.mcap_writer import McapRecording  # noqa: E402

OUT = ROOT / "recordings" / "golden"
T0 = 1_700_000_000_000_000_000       # 2023-11-14T22:13:20Z, the golden clock
KIND_ORDER = ("frame", "hypotheses", "selection", "scene", "measured", "motion", "pose",
              "trajectory", "error")


@dataclass
class Photo:
    jpeg: bytes
    intrinsics: tuple | None = None      # fx, fy, cx, cy, w, h
    gravity: tuple | None = None
    camera_height_m: float | None = None
    device: str = ""


@dataclass
class Spec:
    """One golden session: photos, the user's choices (rank, height) per photo (None: the
    selection service's auto choice), pixels to measure per photo: (u, v), or (u, v,
    "floor" | "wall") for a tap the user says is on that surface."""

    name: str
    photos: list[Photo]
    choices: dict[int, tuple[int, float | None]] = field(default_factory=dict)
    measure: dict[int, list[tuple]] = field(default_factory=dict)
    note: str = ""


def _example(name: str) -> Photo:
    base = ROOT / "findme" / "examples"
    meta = json.loads((base / f"{name}.json").read_text())
    k = meta["intrinsics"]
    return Photo((base / f"{name}.jpg").read_bytes(),
                 (k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"]),
                 tuple(meta["gravity_cam"]), meta["camera_height_m"], f"file:{name}.jpg")


def _render(room, pose, w, h, hfov, seed, height_known=True) -> Photo:
    from findme_core.synth.render import render
    v = render(room, pose, w, h, hfov_deg=hfov, seed=seed)
    c = v.camera
    return Photo(encode_jpeg(v.image, 90), (c.fx, c.fy, c.cx, c.cy, c.width, c.height),
                 tuple(round(float(x), 6) for x in c.gravity),
                 v.camera_height if height_known else None, f"synth:seed{seed}")


def _plain(room, pose) -> Photo:
    """A rendered photo as a camera app saves it: JPEG, lens known, no gravity."""
    from findme_core.synth.render import render
    v = render(room, pose, 640, 480, hfov_deg=70.0, supersample=1)
    c = v.camera
    return Photo(encode_jpeg(v.image, 95), (c.fx, c.fy, c.cx, c.cy, c.width, c.height), None,
                 1.4, "synth:plain")


def specs() -> list[Spec]:
    from findme_core.synth.render import Box, Pose, Room
    pair = _example("room_a"), _example("room_b")
    meta = json.loads((ROOT / "findme" / "examples" / "room_a.json").read_text())
    gt = [tuple(map(float, q["px"])) for q in meta["ground_truth"]["floor_points"][1:4]]
    box_room = Room.rectangle(5.0, 6.0, floor_style="wood",
                              boxes=(Box(0.2, 1.2, 0.8, 0.5, 0.7, yaw_deg=15.0),))
    box = _render(box_room, Pose(0.4, -1.8, 1.4, yaw_deg=20.0, pitch_deg=20.0, roll_deg=3.0),
                  640, 480, 70.0, 3, height_known=False)
    l_room = _render(Room.l_shape(), Pose(-1.5, -1.5, 1.5, yaw_deg=30.0, pitch_deg=20.0),
                     320, 240, 70.0, 4)
    broken = Photo(b"\xff\xd8\xff\xe0" + bytes(200), device="corrupt.jpg")
    plain = [_plain(Room.rectangle(5.0, 4.0), Pose(0.3, -0.2, 1.4, yaw, 30.0, 0.0))
             for yaw in (135.0, 180.0, 225.0)]
    return [
        Spec("examples-pair", list(pair), measure={0: gt},
             note="the bundled example photos as findme run sees them (auto selection)"),
        Spec("synth-box-user", [box], choices={0: (2, 1.3)},
             measure={0: [(320.0, 400.0), (500.0, 300.0), (320.0, 20.0),
                          (100.0, 200.0, "floor"), (320.0, 400.0, "wall"),
                          (103.0, 197.0, "top")]},
             note="a rendered room with a cabinet, tilted phone; the user picks hypothesis 2 "
                  "and gives the camera height with the choice; one tap above the horizon; "
                  "a wall pixel said to be floor (put on the floor), a floor pixel said "
                  "to be wall (no point: choose a lower floor line) and a pixel of the "
                  "cabinet's top said top (on it, by its front edge)"),
        Spec("bad-input", [broken, l_room], measure={1: [(160.0, 200.0), (60.0, 180.0)]},
             note="a corrupt photo (errors, the session goes on) then a small L-shaped room"),
        Spec("plain-turn", plain, measure={1: [(320.0, 400.0)]},
             note="three photos turning at one spot without gravity (a camera app's): the "
                  "second's lines leave it 50 deg off, the motions complete it from the "
                  "first's through their matches (Motion.gravity)"),
    ]


class ScriptedChooser:
    """The user's recorded choice for some photos, rank 1 (auto) for the others."""

    def __init__(self, choices):
        self.choices = choices
        self.by = schemas.SELECTED_BY_AUTO

    def __call__(self, hset, frame=None) -> int:
        choice = self.choices.get(hset.index)
        self.by = schemas.SELECTED_BY_USER if choice else schemas.SELECTED_BY_AUTO
        return choice[0] if choice else 1


def _with_height(handler, choices):
    """Selections carry the user's camera height when the spec gives one."""
    inner = handler.on_message

    def on_message(key, hset):
        outs = inner(key, hset)
        for o in outs:
            c = choices.get(o.msg.index)
            if c and c[1] is not None:
                o.msg.camera_height_m = float(c[1])
        return outs
    handler.on_message = on_message
    return handler


def run_session(spec: Spec, out_dir: Path) -> Path:
    """Run the embedded pipeline on a spec with the recorder; the raw recording's path."""
    from findme.regression.regress import wait_result
    from findme.regression.replay import Watch, ask_measure
    from services.pipeline.capture import CaptureHandler
    from services.pipeline.hypotheses import HypothesesHandler
    from services.pipeline.measurement import MeasurementHandler
    from services.recording.recorder import RecorderHandler
    from services.runtime.handler import Output
    from services.runtime.service import Group
    from services.pipeline.selection import SelectionHandler

    sid = f"golden-{spec.name}"
    session = bus.open_session(bus.BusConfig())
    group = Group(session)
    watch = Watch(session, sid)
    try:
        recorder = group.add(RecorderHandler(out_dir)).handler
        capture = group.add(CaptureHandler())
        group.add(HypothesesHandler("findme", 10))
        sel = SelectionHandler(ScriptedChooser(spec.choices))
        group.add(_with_height(sel, spec.choices))
        group.add(MeasurementHandler())
        try:
            from services.pipeline.odometry import OdometryHandler
            group.add(OdometryHandler())
        except ImportError:
            pass
        for n, p in enumerate(spec.photos):
            f = schemas.Frame(schema="findme.v1.Frame", session=sid, index=n,
                              capture_time_ns=T0 + n * 1_000_000_000, device=p.device)
            if p.intrinsics is not None or p.gravity is not None:
                f = make_frame(sid, n, p.jpeg, intrinsics=p.intrinsics, gravity=p.gravity,
                               camera_height_m=p.camera_height_m, device=p.device,
                               time_ns=T0 + n * 1_000_000_000)
                capture.publish(Output(bus.key(sid, "frame", n), f))
            else:  # not a valid image: publish the bytes as a phone would, unchecked
                f.image.data, f.image.format = p.jpeg, "jpeg"
                bus.put(session, bus.key(sid, "frame", n), f.SerializeToString(deterministic=True))
        def finished(n):   # its scene is built, or an error about its frame came back
            def pred(c):
                if c[bus.key(sid, "scene", n)] > 0:
                    return True
                errs = [schemas.decode(schemas.Error, p, check=False).key
                        for k, p in watch.got if k == bus.key(sid, "error")]
                return any(e.endswith((f"/frame/{n}", f"/hypotheses/{n}", f"/selection/{n}"))
                           for e in errs)
            return pred
        for n in range(len(spec.photos)):
            wait_result(group, watch, finished(n), 120)
        # taps once the bus is quiet: after the motions, and the scenes they built again
        # under an agreed gravity (regress asks again at the same scene)
        wait_result(group, watch, lambda c: False, 120)
        for n, pixels in spec.measure.items():
            wait_result(group, watch, finished(n), 120)
            said = [p[2] if len(p) > 2 else None for p in pixels]
            req = schemas.MeasureRequest(session=sid, index=n,
                                         pixels=schemas.pixels_to_msg([p[:2] for p in pixels]),
                                         said=schemas.surfaces_to_msg(said))
            payload, err = ask_measure(session, sid, req)
            if payload is None:
                raise SystemExit(f"{spec.name}: measure photo {n}: {err}")
            bus.put(session, bus.key(sid, "measured", n), payload)
        watch.wait(lambda c: all(c[bus.key(sid, "measured", n)] > 0 for n in spec.measure), 30)
        wait_result(group, watch, lambda c: False, 60)
    finally:
        watch.close()
        group.stop()
        session.close()
    path = recorder.path_of(sid)
    if path is None:
        raise SystemExit(f"{spec.name}: nothing was recorded")
    return path


def _index(key: str, payload: bytes) -> int:
    k = bus.parse_key(key)
    if k.kind == "error":
        try:
            e = schemas.decode(schemas.Error, payload, check=False)
            last = e.key.rsplit("/", 1)[-1]
            return int(last) if last.isdigit() else 10**6
        except Exception:  # noqa: BLE001
            return 10**6
    if k.kind == "trajectory":
        msg = schemas.decode(schemas.Trajectory, payload, check=False)
        return max((p.index for p in msg.poses), default=0)
    nums = [int(p) for p in k.parts if p.isdigit()]
    return nums[-1] if nums else 0


def canonical(raw: Path, dst: Path, spec: Spec) -> int:
    """Rewrite a recording deterministically (module docstring); returns its message count."""
    recs = read_recording(raw)
    kinds = [bus.parse_key(r.key).kind for r in recs]
    last = {r.key: pos for pos, (r, kind) in enumerate(zip(recs, kinds))
            if kind in bus.LATEST_STATE_KINDS}   # only the last of a latest-state key is kept
    keyed = []
    for pos, (r, kind) in enumerate(zip(recs, kinds)):
        if last.get(r.key, pos) != pos:
            continue
        rank = KIND_ORDER.index(kind) if kind in KIND_ORDER else len(KIND_ORDER)
        tie = (r.key, _normalised(r.payload, 0)) if kind == "error" else (pos,)
        keyed.append(((_index(r.key, r.payload), rank, tie), r))
    keyed.sort(key=lambda x: x[0])
    dst.parent.mkdir(parents=True, exist_ok=True)
    if dst.exists():
        dst.unlink()
    out = McapRecording(dst, bus.parse_key(recs[0].key).session,
                        metadata={"golden": spec.name, "note": spec.note,
                                  "made_by": "tools/make_golden.py"})
    last_photo, step = None, 0
    for (photo, _, _), r in keyed:
        step = step + 1 if photo == last_photo else 0
        last_photo = photo
        t = T0 + min(photo, 10**4) * 1_000_000_000 + step * 1_000_000
        out.write(r.key, _normalised(r.payload, t), t)
    out.close()
    return len(keyed)


def _normalised(payload: bytes, t: int) -> bytes:
    try:
        msg = schemas.decode_any(payload, check=False)
    except Exception:  # noqa: BLE001 - a malformed payload stays as it was
        return payload
    name = msg.DESCRIPTOR.full_name
    if name in ("findme.v1.Selection", "findme.v1.Scene", "findme.v1.Motion",
                "findme.v1.Trajectory", "findme.v1.Error"):
        msg.time_ns = t
    if name == "findme.v1.HypothesisSet":
        for k in list(msg.timing_ms):
            msg.timing_ms[k] = 0.0
    if name == "findme.v1.Error" and msg.service:
        msg.service = msg.service.split("/", 1)[0] + "/golden"
    return msg.SerializeToString(deterministic=True)


def check(target: Path, fresh: Path) -> tuple[bool, str]:
    """Whether a golden file holds what a fresh run gives: byte for byte, or else message for
    message within ``findme regress``'s tolerances (last-bit differences of another CPU's
    floating point are not a change; the inputs, frames and selections, must be identical).
    Returns (same, what to print)."""
    from collections import defaultdict

    from findme.regression.regress import Regression, compare_results
    if not target.exists():
        return False, "MISSING"
    if target.read_bytes() == fresh.read_bytes():
        return True, "up to date"
    old, new = read_recording(target), read_recording(fresh)
    out = Regression(str(target), bus.parse_key(old[0].key).session if old else "")
    is_input = lambda r: bus.parse_key(r.key).kind in ("frame", "selection")  # noqa: E731
    ins = [{r.key: r.payload for r in recs if is_input(r)} for recs in (old, new)]
    bad = sorted(k for k in ins[0].keys() | ins[1].keys() if ins[0].get(k) != ins[1].get(k))
    if bad:
        return False, f"DIFFERS from a fresh run: its inputs differ ({', '.join(bad)})"
    results = [defaultdict(list), defaultdict(list)]
    for recs, d in zip((old, new), results):
        for r in recs:
            if not is_input(r):
                d[r.key].append(r.payload)
    compare_results(*results, out)
    if out.differences:
        return False, "DIFFERS from a fresh run:\n" + "\n".join(out.report().splitlines()[1:-1])
    return True, ("up to date within regress's tolerances (not byte for byte: this machine's "
                  "floating point differs in the last bits)"
                  + "".join(f"\n  note: {n}" for n in out.notes))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="compare with the files, write nothing")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--only", action="append", help="just these goldens (by name)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)
    differ = 0
    with tempfile.TemporaryDirectory() as tmp:
        for spec in specs():
            if args.only and spec.name not in args.only:
                continue
            raw = run_session(spec, Path(tmp) / "raw")
            fresh = Path(tmp) / f"{spec.name}.mcap"
            n = canonical(raw, fresh, spec)
            target = args.out / f"{spec.name}.mcap"
            if args.check:
                same, detail = check(target, fresh)
                differ += not same
                print(f"{target}: {detail}")
            else:
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(fresh.read_bytes())
                print(f"wrote {target}: {n} bus messages, {target.stat().st_size // 1024} kB")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
