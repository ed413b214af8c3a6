"""The floor plan of a room: its outline, walls with lengths and 1-sigma, doors and openings
seen in them, and the pose of every photo, from posed layouts (``fuse``) and the outline
(``polygon``).

Frames and units: the room frame is the level frame of the session's first photo (x right,
z forward, floor at y = camera height; metres). A photo's pose is (x, z, yaw) with yaw > 0
turned right (radians inside, degrees in ``to_dict``). The polygon is counter-clockwise seen
from above (positive shoelace area in (x, z)); wall k runs from vertex k to vertex k + 1.

Steps: wall lines (``walls``), the outline on them (``polygon``), then poses and lines refined
together (``adjust``), whose covariance gives each wall length and each corner's x and z its
1-sigma (plus the camera height's relative error times the length, or the corner's distance
from the first photo: every distance scales with the height). Without the refinement a wall's
ends move with its neighbours' offsets (``wall_sigmas``). Each is then scaled by its model
error (``PlanParams``); a wall nobody saw, and its corners, are inferred: no 1-sigma.

Pure numpy; no I/O (doors and openings: ``apertures``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from findme_core.errors import GeometryError
from findme_core.motion import register
from findme_core.plan import adjust, apertures, polygon, seen_past, wall_sigmas, walls
from findme_core.single.layout import Layout


@dataclass(frozen=True)
class PlanParams:
    """Outline and uncertainty settings.

    Attributes:
        polygon: free floor and cell voting (``polygon.PolygonParams``).
        lines: wall line search and classification (``walls.WallParams``).
        adjust: the joint refinement (``adjust.RefineParams``).
        seen_past: walls the photos saw past, redrawn or refused (``seen_past``).
        height_rel: relative 1-sigma of the camera height (scales every length).
        offset_floor_m: smallest 1-sigma of a wall line's offset.
        aperture_min_m: a stretch of wall at least this long where floor was seen beyond it
            (and no wall base) is a door or opening.
        max_range_m: floor samples are cut at this distance from their camera.
        pose_sigma_model: (k_xz, floor_xz_m, k_yaw, floor_yaw_deg): a pose's 1-sigma is
            hypot(k * the refinement's, floor) per axis: the refinement's covariance sees the
            samples' noise, not the layouts' shared errors. Fitted on the dev rooms so that
            68 % of the poses lie within 1 sigma (``tools/calibrate_plan.py``,
            leave-one-room-out figures in docs/RESULTS.md).
        length_sigma_model: (k, floor_m): the same for a seen wall's length. A wall nobody
            saw closes the outline: its length is inferred, not measured (1-sigma NaN).
        corner_sigma_model: (k, floor_m): the same for a corner's x and z (per axis); a
            corner of a wall nobody saw is inferred (1-sigma NaN).
        image_gravity_models: (pose model, length model, corner model) for gravity that is
            not exact (the refinement holds gravity fixed: its covariance misses gravity's
            error). The pose and corner models serve a session with a photo whose
            ``session.Photo.gravity`` is not "exact" (a phone's refined by its lines,
            "sensor", or "image"), and are fitted on both pooled (``tools/calibrate_plan.py
            --gravity inexact``: gravity withheld and a phone's); the length model one with
            an "image" photo (``--gravity withheld``).
            Refitted 2026-12-01 with ``inexact_snap_deg``: yaw k 6.05 -> 5.20, length k
            6.36 -> 0.95 (Manhattan walls come out right where they had come out degrees
            off); and again once the refinement marginalised each photo's tilt in its
            matches (``problem.Problem._tilts``): yaw k 5.20 -> 2.85 (raw within 1 / 2 / 3
            sigma 0.18 / 0.31 / 0.44 -> 0.31 / 0.58 / 0.70; left out 0.64 / 0.84 / 0.97 ->
            0.71 / 0.90 / 0.98), length k 0.95 -> 0.64; leave-one-room-out figures in
            docs/RESULTS.md.
        inexact_snap_deg: ``lines.snap_deg`` for a session with a photo whose gravity is not
            exact: a tilt error turns each photo's floor lines its own way (0.5 deg of tilt
            turned dev room zr_r10's layout walls by 0.2-0.9 deg, zr_r01's by 0.5-1.7 deg), so
            one room's walls, each seen by a few photos, scatter by degrees about its axes and
            the Manhattan test failed on rooms that are rectangles (dev zr_r17 with a
            phone's gravity: its lines 4-5 deg apart, one wall drawn 6 deg off and its
            neighbour 0.27 m short at +-0.07 m). Chosen leave one room out among 2-8 deg
            (``tools/choose_snap.py``, 2026-12-01: 8 on all rooms, 5-8 with one left out;
            walls ok 0.725 -> 0.750, views localised 0.825 -> 0.953 left out). No larger
            value was tried: the dev rooms are all rectangles, and a wall built at a slant
            (the 17 deg of tests/core/plan/test_floorplan.py's room) must stay off.
    """

    polygon: polygon.PolygonParams = field(default_factory=polygon.PolygonParams)
    lines: walls.WallParams = field(default_factory=walls.WallParams)
    adjust: adjust.RefineParams = field(default_factory=adjust.RefineParams)
    seen_past: seen_past.SeenPastParams = field(default_factory=seen_past.SeenPastParams)
    height_rel: float = 0.02
    offset_floor_m: float = 0.01
    aperture_min_m: float = 0.5
    max_range_m: float = 8.0
    # tools/calibrate_plan.py on the 5 dev rooms, the dataset's gravity (refitted
    # 2026-12-01: x, z k 2.58 -> 2.22, yaw 3.32 as it was, wall length (1.49, 0) -> k 0.39
    # with a 0.066 m floor, which the fit now takes; leave-one-room-out coverage within
    # 1 / 2 / 3 sigma in docs/RESULTS.md)
    pose_sigma_model: tuple = (2.22, 0.0, 3.32, 0.0)
    length_sigma_model: tuple = (0.39, 0.066)
    # corners (2026-12-02, the same tool; 16 corners' x and z with the dataset's gravity,
    # 28 with gravity withheld and a phone's pooled; within 1 / 2 / 3 sigma in sample and
    # left out in docs/RESULTS.md)
    corner_sigma_model: tuple = (1.42, 0.0)
    # Refitted 2026-12-02 by the rule that puts the goal first (``sigma_coverage.rule_key``)
    # every model moves (pose (1.73, 3.67), length k 3.67 without a floor, corners 2.22; image
    # gravity: pose (3.32, 4.26), corners 2.46 without a floor). Not shipped: left out (docs/
    # RESULTS.md's rule) the corners lose within 3 sigma with gravity withheld (0.96 -> 0.93)
    # and a phone's (1.00 -> 0.96), a phone's wall lengths come out 0.86 within 1 (0.64);
    # in sample only the dataset's gravity gains (walls 0.89 -> 0.94, corners 0.91 -> 0.94).
    image_gravity_models: tuple = ((3.15, 0.0, 2.85, 0.0), (0.64, 0.0), (0.74, 0.0291))
    inexact_snap_deg: float = 8.0

    def for_gravity(self, kinds) -> PlanParams:
        """These parameters for a session whose placed photos' gravity is of ``kinds``
        (``session.Photo.gravity``: "exact", "sensor", "image"): the pose and corner models
        of ``image_gravity_models`` and ``inexact_snap_deg`` when any is not exact, its
        length model when any came from the image."""
        kinds, out = set(kinds), self
        pm, lm, cm = self.image_gravity_models
        if kinds - {"exact"}:
            out = replace(out, pose_sigma_model=pm, corner_sigma_model=cm, lines=replace(
                out.lines, snap_deg=max(out.lines.snap_deg, self.inexact_snap_deg)))
        if "image" in kinds:
            out = replace(out, length_sigma_model=lm)
        return out


@dataclass(frozen=True)
class Wall:
    """One edge of the outline: ends a, b (2,) metres, length and 1-sigma (NaN: not
    measured, for an edge nobody saw), whether it was seen as a wall ("missing" edges close
    the outline where nothing was seen), and the apertures (from_m, to_m measured from a)
    where the floor was seen beyond it."""

    a: np.ndarray
    b: np.ndarray
    length_m: float
    sigma_m: float
    seen: bool
    apertures: tuple = ()


@dataclass(frozen=True)
class Plan:
    """A room's floor plan (see the module docstring for frames and units).

    Attributes:
        polygon: (V, 2) outline vertices, counter-clockwise.
        walls: V ``Wall`` s, wall k from vertex k to k + 1.
        area_m2: floor area of the outline.
        poses: (N, 3) (x, z, yaw) per photo, NaN rows for photos not placed.
        manhattan: True when the walls were found on two perpendicular axes.
        notes: per photo, why it was not placed (None when placed).
        ambiguity: per photo, the score of the best clearly different pose over the chosen
            pose's score (NaN when there was none; near 1: ambiguous).
        pose_sigma: (N, 3) 1-sigma of each pose (x, z metres, yaw radians) from the joint
            refinement (NaN: not refined), or None.
        corner_sigma: (V, 2) 1-sigma of each vertex's x and z, metres (NaN: a corner of a
            wall nobody saw, inferred; all NaN when not given).
    """

    polygon: np.ndarray
    walls: tuple
    area_m2: float
    poses: np.ndarray
    manhattan: bool
    notes: tuple = ()
    ambiguity: tuple = ()
    pose_sigma: np.ndarray | None = None
    corner_sigma: np.ndarray | None = None

    def __post_init__(self):
        if self.corner_sigma is None:   # none given: every corner not measured
            object.__setattr__(self, "corner_sigma", np.full((len(self.polygon), 2), np.nan))

    @property
    def closed(self) -> bool:
        """Every edge of the outline was seen as a wall."""
        return all(w.seen for w in self.walls)

    @property
    def missing(self) -> list[int]:
        """Indices of the edges that close the outline where no wall was seen."""
        return [k for k, w in enumerate(self.walls) if not w.seen]

    def to_dict(self, ids=None, outline: bool = True) -> dict:
        """JSON-ready dict: metres and degrees. ``ids`` name the photos (default 0..N-1).
        ``outline`` False: the poses without the outline (an empty polygon, no walls), as a
        refused outline's photos are given (``errors.OutlineRefused``)."""
        if not outline:
            return {**replace(self, polygon=np.zeros((0, 2)), walls=(), area_m2=0.0,
                              manhattan=False, corner_sigma=None).to_dict(ids), "closed": False}
        ids = list(ids) if ids is not None else [str(i) for i in range(len(self.poses))]
        poses = {}
        sig = self.pose_sigma if self.pose_sigma is not None else np.full((len(ids), 3), np.nan)
        for k, p, s in zip(ids, self.poses, sig):
            poses[k] = (None if not np.isfinite(p[0]) else
                        {"x_m": round(float(p[0]), 4), "z_m": round(float(p[1]), 4),
                         "yaw_deg": round(math.degrees(float(p[2])), 3)})
            if poses[k] is not None and np.all(np.isfinite(s)):
                poses[k]["sigma_xz_m"] = round(float(np.hypot(s[0], s[1])), 4)
                poses[k]["sigma_yaw_deg"] = round(math.degrees(float(s[2])), 3)
        return {
            "floor_polygon_m": np.round(self.polygon, 4).tolist(),
            "corner_sigma_m": [np.round(c, 4).tolist() if np.all(np.isfinite(c)) else None
                               for c in self.corner_sigma],
            "area_m2": round(self.area_m2, 3),
            "closed": self.closed,
            "manhattan": self.manhattan,
            "walls": [{"a": np.round(w.a, 4).tolist(), "b": np.round(w.b, 4).tolist(),
                       "length_m": round(w.length_m, 4),
                       "sigma_m": round(w.sigma_m, 4) if math.isfinite(w.sigma_m) else None,
                       "seen": w.seen,
                       "apertures": [{"kind": "opening", "from_m": round(a, 3), "to_m": round(b, 3)}
                                     for a, b in w.apertures]} for w in self.walls],
            "missing_walls": self.missing,
            "poses": poses,
            "notes": {k: n for k, n in zip(ids, self.notes) if n},
            "ambiguity": {k: round(float(a), 3) for k, a in zip(ids, self.ambiguity)
                          if np.isfinite(a)},
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Plan":
        """Inverse of ``to_dict`` (poses in the order of the dict)."""
        walls = tuple(Wall(np.array(w["a"], float), np.array(w["b"], float),
                           float(w["length_m"]),
                           float("nan") if w.get("sigma_m") is None else float(w["sigma_m"]),
                           bool(w.get("seen", True)),
                           tuple((a["from_m"], a["to_m"]) for a in w.get("apertures", ())))
                      for w in d["walls"])
        poses = np.array([[p["x_m"], p["z_m"], math.radians(p["yaw_deg"])] if p else
                          [np.nan] * 3 for p in d.get("poses", {}).values()], float).reshape(-1, 3)
        V = np.array(d["floor_polygon_m"], float).reshape(-1, 2)
        cs = d.get("corner_sigma_m")
        cs = None if cs is None else np.array([c if c is not None else [np.nan] * 2
                                               for c in cs], float).reshape(-1, 2)
        return cls(V, walls, float(d.get("area_m2", abs(polygon.area(V)))), poses,
                   bool(d.get("manhattan", False)), corner_sigma=cs)


def world_walls(L: Layout, pose) -> np.ndarray:
    """(K, 2, 2) a layout's wall base segments in the room frame."""
    if len(L.walls) == 0:
        return np.zeros((0, 2, 2))
    return register.rot2(np.array([pose[2]]), L.walls.reshape(-1, 2))[0].reshape(-1, 2, 2) + pose[:2]


def build(layouts, poses, params: PlanParams = PlanParams(), notes=(), ambiguity=(),
          spot=None, links=(), matches=None, focal=None, refine: bool = True,
          spread=None, tilt=None) -> Plan:
    """The plan from N photos' layouts (None for a photo without one) and poses (N, 3) (NaN
    rows for photos not placed); with ``refine``, poses and walls are then refined together
    (``adjust.refine``: ``spot`` labels (N,) (default: one per photo), turns ``links`` and
    feature ``matches`` as ``fuse.place`` takes them, ``focal`` (N,) pixels) and the wall
    lengths' 1-sigma come from its covariance. ``spread`` (N, 3): 1-sigma each pose gains
    from other poses its evidence fits nearly as well (``pose.spread``), added in quadrature;
    ``tilt`` (N,): each photo's gravity tilt 1-sigma, radians (``adjust.refine``).

    Raises:
        GeometryError: no placed photo saw any floor.
    """
    poses = np.asarray(poses, float).reshape(-1, 3)
    spot = np.arange(len(poses)) if spot is None else spot
    ev, wl, out, snapped = seen_past.outline(layouts, poses, params, spot)
    V, sig_len, pose_sig, sig_v = out.vertices, None, None, None
    if refine:   # refine, redraw the outline at the refined poses, refine once more
        try:
            r = adjust.refine(layouts, poses, spot, out, wl.manhattan, snapped, links, matches,
                              focal, params.adjust, tilt=tilt)
            ev, wl, out, snapped = seen_past.outline(layouts, r.poses, params, spot)
            r = adjust.refine(layouts, r.poses, spot, out, wl.manhattan, snapped, links,
                              matches, focal, params.adjust, prior=poses, tilt=tilt)
            poses, V, sig_len, pose_sig = r.poses, r.vertices, r.sigma_length, r.sigma_pose
            sig_v = r.sigma_corner
        except GeometryError:
            pass
    lines = polygon.Lines.of(wl)
    used = out.line[out.line >= 0]
    manhattan = wl.manhattan is not None and bool(np.all(snapped[used]))
    if sig_len is None:
        sig_d = wall_sigmas.offset_sigmas(ev, wl, params.offset_floor_m)
        sig_len = wall_sigmas.length_sigmas(out, lines, sig_d, params.height_rel)
        sig_v = wall_sigmas.corner_sigmas(out, lines, sig_d, params.height_rel)
    seen = np.asarray(out.seen[:len(V)], bool)
    k, f = params.length_sigma_model
    sig_len = np.where(seen, np.hypot(k * np.asarray(sig_len, float), f), np.nan)
    k, f = params.corner_sigma_model     # a corner of a wall nobody saw is inferred
    sig_v = np.where((seen & np.roll(seen, 1))[:, None],
                     np.hypot(k * np.asarray(sig_v, float), f), np.nan)
    if pose_sig is not None:
        kx, fx, ky, fy = params.pose_sigma_model
        fixed = pose_sig == 0.0                  # the frame's origin: exact by definition
        pose_sig = np.where(fixed, 0.0, np.column_stack([
            np.hypot(kx * pose_sig[:, :2], fx), np.hypot(ky * pose_sig[:, 2], math.radians(fy))]))
        if spread is not None:
            pose_sig = np.hypot(pose_sig, np.asarray(spread, float).reshape(-1, 3))
    fans, fan_photo = apertures.session_fans(layouts, poses, params.max_range_m)
    base = walls.evidence(layouts, poses)
    walls_ = []
    for k in range(len(V)):
        a, b = V[k], V[(k + 1) % len(V)]
        walls_.append(Wall(a, b, float(np.linalg.norm(b - a)), float(sig_len[k]),
                           bool(out.seen[k]), _openings(a, b, fans, fan_photo, base, params)
                           if out.seen[k] else ()))
    n = len(poses)
    return Plan(V, tuple(walls_), abs(polygon.area(V)), poses, manhattan,
                tuple(notes) or (None,) * n, tuple(ambiguity) or (float("nan"),) * n,
                pose_sig if pose_sig is not None else np.full((n, 3), np.nan), sig_v)


def _openings(a, b, fans, fan_photo, base: walls.Evidence, params: PlanParams) -> tuple:
    return apertures.stretches(a, b, fans, fan_photo, base.points, base.length, base.photo,
                               params.aperture_min_m)
