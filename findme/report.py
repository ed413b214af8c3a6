"""What a session's results look like on a terminal: ``Printer`` (each photo's hypotheses,
selection, scene, motion and pose, and the errors about it, as they arrive on the bus),
``report_session`` (publish photos, print their results in order), the final measurement
and, for the bundled example, its truth. Shared by ``findme run`` and ``findme send``.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from importlib import resources

import zenoh

import schemas
from findme_core.errors import BusError, InputError
from services.pipeline.capture import Lens, publish_frames, sources
from findme_io.convert import gravity_caveat, msg_room_view
from findme_io.motion_msg import motion_gravity_text, motion_text, sigma_text
from services.runtime import bus


class Printer:
    """Prints a session's results as they arrive on the bus."""

    def __init__(self, session: str, out=None):
        self.session, self.out = session, out or sys.stdout
        self.cv = threading.Condition()
        self.seen: dict[str, object] = {}     # key -> its latest message
        self.errors: list = []                # every Error published on the session
        self.agreed: dict[int, float] = {}    # photo -> the sigma a motion's agreement gave it

    def __call__(self, sample: zenoh.Sample) -> None:
        k = str(sample.key_expr)
        try:
            msg = schemas.decode_any(sample.payload.to_bytes())
        except Exception:  # noqa: BLE001 - a foreign payload: nothing to print
            return
        with self.cv:
            if type(msg).__name__ == "Error":
                self.errors.append(msg)
            else:
                self.seen[k] = msg
            self.cv.notify_all()

    ORDER = ("frame", "hypotheses", "selection", "scene", "motion", "pose")

    @staticmethod
    def _about(err, n: int, kinds=ORDER) -> bool:
        """Whether an Error is about photo n (its key is one of photo n's keys)."""
        parts = err.key.split("/")
        return len(parts) >= 4 and parts[2] in kinds and parts[-1] == str(n)

    def report(self, n: int) -> None:
        """Print photo n's results in pipeline order (they arrive in any order), then the
        errors about it, one line each."""
        p = f"findme/{self.session}/"
        with self.cv:
            items, errors = list(self.seen.items()), list(self.errors)
        lines = []
        for kind in self.ORDER:
            for k, m in items:
                if k.startswith(p + kind + "/") and k.endswith(f"/{n}"):
                    line = self.describe(k, m)
                    if line and line not in lines:
                        lines.append(line)
        for e in errors:
            line = self.describe(e.key, e)
            if self._about(e, n) and line not in lines:
                lines.append(line)
        print("\n".join(lines), file=self.out, flush=True)

    def wait(self, done, timeout: float) -> bool:
        """Until ``done(seen, errors)`` is true (results arrived), or the timeout."""
        with self.cv:
            return self.cv.wait_for(lambda: done(self.seen, self.errors), timeout)

    def photo_done(self, n: int, odometry: bool):
        """Photo n's results are all in: its scene (or an error about it), and, when
        odometry runs, its pose (odometry publishes it with the motion that places it) or
        the motion's failure (then there is no pose)."""
        def done(seen, errors):
            p = f"findme/{self.session}/"
            failed = any(self._about(e, n, ("frame", "hypotheses", "selection")) for e in errors)
            scene = (p + f"scene/{n}" in seen and p + f"hypotheses/{n}" in seen) or failed
            if not odometry or not scene or failed:
                return scene
            return p + f"pose/{n}" in seen or any(
                k.startswith(p + "motion/") and k.endswith(f"/{n}") and m.error
                for k, m in seen.items()) or any(self._about(e, n, ("motion", "pose"))
                                                 for e in errors)
        return done

    def unit(self, n: int) -> str:
        """The length unit of photo n's results: "m" when its scene is metric, else "h"
        (camera heights: no camera height was given)."""
        scene = self.seen.get(f"findme/{self.session}/scene/{n}")
        return "m" if scene is None or scene.metric else "h"

    def _own_gravity(self, n: int) -> tuple[str, float] | None:
        """(source, 1-sigma radians) of photo n's gravity, as its hypotheses' camera says it."""
        hs = self.seen.get(f"findme/{self.session}/hypotheses/{n}")
        if hs is None or not hs.HasField("camera"):
            return None
        src, sigma = hs.camera.gravity_source, hs.camera.gravity_sigma_rad
        if n in self.agreed:   # an earlier motion completed it (the odometry carries it on)
            return ("image" if src == "level" else src), min(sigma, self.agreed[n])
        return src, sigma

    def _gravity_note(self, n: int) -> str | None:
        """``gravity_caveat`` of photo n's own gravity."""
        own = self._own_gravity(n)
        return None if own is None else gravity_caveat(f"photo {n}", *own)

    def describe(self, k: str, m) -> str | None:
        name = type(m).__name__
        if name == "Frame":
            return f"photo {m.index}: {m.device or 'frame'} ({len(m.image.data) // 1024} kB)"
        if name == "HypothesisSet":
            t = sum(m.timing_ms.values())
            frame = self.seen.get(f"findme/{self.session}/frame/{m.index}")
            h = (frame.camera_height_m if frame is not None and frame.HasField("camera_height_m")
                 else None)
            view = msg_room_view(m, h)
            note = self._gravity_note(m.index)
            return (f"photo {m.index}: {len(m.hypotheses)} hypotheses in {t:.0f} ms"
                    + (f" ({m.reason})" if m.reason else "")
                    + (f"; NOT A ROOM VIEW: {view.reason}" if view and not view.ok else "")
                    + (f"; {note}" if note else ""))
        if name == "Selection":
            return f"photo {m.index}: hypothesis {m.rank} selected ({'auto' if m.by == 2 else 'user'})"
        if name == "Scene":
            return (f"photo {m.index}: scene ready (camera {m.camera_height_m:.2f} m above the "
                    "floor)" if m.metric else f"photo {m.index}: scene ready (no camera "
                    "height: lengths in camera heights, h)")
        if name == "Motion":
            text = motion_text(m, self.unit(m.index_b)) + ("" if m.error else motion_gravity_text(
                m, f"photo {m.index_a}", f"photo {m.index_b}", self._own_gravity(m.index_a),
                self._own_gravity(m.index_b)))
            g = m.gravity
            if not m.error and m.HasField("gravity") and g.status == "agreed":
                for n, f in ((m.index_a, "sigma_a_rad"), (m.index_b, "sigma_b_rad")):
                    if g.HasField(f):
                        self.agreed[n] = min(self.agreed.get(n, math.inf), getattr(g, f))
            return text
        if name == "Pose":
            u = self.unit(m.index)
            sig = sigma_text(m, u)
            return (f"photo {m.index}: at x {m.x_m:+.3f} {u}, z {m.z_m:+.3f} {u}, heading "
                    f"{math.degrees(m.yaw_rad):+.1f} deg from photo 0"
                    + (f" ({sig})" if sig and m.index else ""))
        if name == "Plan":
            if m.reason:
                return f"floor plan: none yet ({m.reason})"
            placed = sum(q.status == schemas.PLAN_PHOTO_STATUS_PLACED for q in m.poses)
            missing = sum(w.kind == schemas.WALL_KIND_MISSING for w in m.walls)
            unit, area = ("m", "m²") if m.metric else ("h", "h²")
            return (f"floor plan: {len(m.walls)} walls (" + ", ".join(
                f"{w.length_m:.2f}" + ("?" if w.kind == schemas.WALL_KIND_MISSING
                                       else f" ± {w.sigma_m:.2f}")
                for w in m.walls) + f" {unit}; ? = not seen), area {m.area_m2:.2f} {area}"
                + (f" (closed by {missing} wall{'s' if missing > 1 else ''} not seen)"
                   if missing else "") + f", {placed} of {len(m.poses)} photos placed")
        if name == "Error":
            return f"error on {m.key}: {m.message}"
        return None

    def plan_done(self, n: int):
        """The mapper's plan has taken in (or named) every one of the n photos."""
        def done(seen, errors):
            m = seen.get(f"findme/{self.session}/plan")
            return m is not None and len(m.poses) >= n and not any(
                q.reason.startswith("waiting") for q in m.poses)
        return done


def example_paths() -> list[str]:
    base = resources.files("findme") / "examples"
    return [str(base / "room_a.jpg"), str(base / "room_b.jpg")]


def read_photos(photos, out=None) -> list:
    """Every readable photo of ``photos`` (files, folders, videos, cameras) as capture
    sources; each unreadable one is reported on one line of ``out`` (stderr) and skipped.

    Returns:
        (sources, errors): errors are (path, FindmeError).

    Raises:
        InputError: none of them could be read.
    """
    errors: list = []
    srcs = list(sources(photos, errors=errors))
    for path, e in errors:
        print(f"findme: skipped {path}: {e}", file=out or sys.stderr, flush=True)
    if not srcs:
        raise InputError(f"none of the {len(photos)} inputs is a photo that can be read")
    return srcs, errors


def report_session(printer: "Printer", publisher, session_id: str, srcs, lens: Lens,
                   odometry: bool, timeout: float, mapper: bool = False, on_first=None) -> int:
    """Publish the photos through ``publisher`` (a running capture-like Service), then print
    each photo's results in order as they arrive, and the floor plan once it has taken in
    every photo (when a mapper runs); returns the number of photos. ``on_first()`` runs
    once the first photo is out (``publish_frames``).

    Raises:
        BusError: a photo's results did not all arrive within ``timeout`` seconds.
    """
    t0 = time.perf_counter()
    n = publish_frames(publisher, session_id, srcs, lens, on_first=on_first)
    for i in range(n):
        if not printer.wait(printer.photo_done(i, odometry), timeout):
            printer.report(i)
            raise BusError(f"photo {i}: not all results arrived within {timeout:.0f} s "
                           "(is every service still running? see findme status)")
        printer.report(i)
    pk = f"findme/{session_id}/plan"
    if (mapper or pk in printer.seen) and printer.wait(printer.plan_done(n), timeout):
        print(printer.describe(pk, printer.seen[pk]), file=printer.out, flush=True)
    print(f"session {session_id}: {n} photos processed in {time.perf_counter() - t0:.2f} s",
          file=printer.out, flush=True)
    return n


def measure(session, session_id: str, pixels, example: bool, said=None, scene=None) -> None:
    """Ask the measurement service for ``pixels`` (u, v) of photo 0 (``said``: the surface
    the user says each is on, "floor", "wall", "top" or None; None for none) and print its
    answer, with how high a top is when photo 0's Scene message ``scene`` is known (its
    gravity and camera height); for the bundled ``example`` (no pixels given: its
    ground-truth floor points), its truth."""
    if not pixels and example:  # the example: its ground-truth floor points
        import json
        meta = json.loads((resources.files("findme") / "examples" / "room_a.json").read_text())
        pixels = [tuple(q["px"]) for q in meta["ground_truth"]["floor_points"][1:3]]
    if not pixels:
        return
    req = schemas.MeasureRequest(session=session_id, index=0)
    req.pixels.extend(schemas.pixels_to_msg(pixels))
    req.said.extend(schemas.surfaces_to_msg(said))
    for reply in session.get(bus.key(session_id, "measure"), payload=schemas.encode(req), timeout=10):
        if reply.ok is None:
            err = schemas.decode(schemas.Error, reply.err.payload.to_bytes())
            print(f"measure: {err.message}")
            continue
        rep = schemas.decode(schemas.MeasureReply, reply.ok.payload.to_bytes())
        bus.put(session, bus.key(session_id, "measured", rep.index), reply.ok.payload.to_bytes())  # for the record
        unit = "m" if rep.metric else "h (camera heights)"
        for p in rep.points:
            where = (f"{schemas.Surface.Name(p.surface).split('_')[1].lower()}"
                     f"{' (as you said)' if p.said else ''} at "
                     f"({p.xyz.x:+.3f}, {p.xyz.y:+.3f}, {p.xyz.z:+.3f}) {unit} ± {p.sigma_m:.3f}"
                     + _top_height(p, scene, unit)
                     + (f"\n  note: {p.note}" if p.note else "")
                     if not p.error else p.error)
            print(f"measure photo 0 pixel ({p.pixel.u:g}, {p.pixel.v:g}): {where}")
        for d in rep.distances:
            if not d.error:
                print(f"distance {d.a + 1}-{d.b + 1}: {d.distance_m:.3f} {unit} ± {d.sigma_m:.3f}")
        if example:
            _example_truth(pixels)
        return


def _top_height(p, scene, unit: str) -> str:
    """", its top 0.905 m above the floor" for a point on a top when the scene is known: the
    camera height less the point's depth along gravity (camera frame, down)."""
    if p.surface != schemas.SURFACE_TOP or scene is None or not scene.camera.HasField("gravity"):
        return ""
    g = scene.camera.gravity
    up = scene.camera_height_m - (g.x * p.xyz.x + g.y * p.xyz.y + g.z * p.xyz.z)
    return f", its top {up:.3f} {unit} above the floor"


def _example_truth(pixels) -> None:
    """The bundled example is rendered: print its true motion and distance to compare."""
    import json
    import math
    base = resources.files("findme") / "examples"
    pair = json.loads((base / "pair.json").read_text())["motion"]
    pts = {tuple(q["px"]): q["xyz_m"] for q in
           json.loads((base / "room_a.json").read_text())["ground_truth"]["floor_points"]}
    known = [pts.get(tuple(p)) for p in pixels[:2]]
    d = (f"; distance 1-2 {math.dist(*known):.3f} m" if len(known) == 2 and None not in known
         else "")   # the truth is known at the example's own points only
    print(f"truth (the example is rendered): motion x {pair['x_m']:+.3f} m, z {pair['z_m']:+.3f} m,"
          f" yaw {pair['yaw_deg']:+.2f} deg{d}")
