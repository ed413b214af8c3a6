"""Kitchen counters: the wall behind them.

A run of base cabinets hides the base of the wall it stands against. The boundary search
then follows the counter's front edge, a strong horizontal line with a smooth surface (the
counter top) above it: lifted as a floor line it puts the wall 1.2-3x too far. The wall is
where the counter top meets it, the counter's back edge, at the counter's height.

Geometry, in the photo's LEVEL frame (x right, y down, z forward; metres; floor y = h,
the camera height). A WALL segment B of the boundary is a counter's front edge when:

1. cabinet doors stand below it: at least ``min_doors`` 3D-vertical image lines whose top
   lies on B's vertical plane between ``door_top_m`` below the counter height and just
   above it (a floor line has floor below it, not door edges hanging from it);
2. the counter top lies above it: a horizontal image line above B that is parallel to it
   in 3D and, lifted on the counter plane y = h - H (H = ``height_m``, 0.9 m: the standard
   36 in), lies ``depth_m`` behind it (0.45-0.80 m: a 24 in cabinet with its overhang); the
   first such line. Nearer lines lie on the top itself: the nosing's back line, a sink's
   rim, an appliance (dev kitchen zr_r06: a sink's rim 0.16 m behind the front edge).

That line is the counter's back edge, on the wall; the wall's base is the vertical plane
through it at the floor. ``behind`` replaces B by the base's image (below the cabinets, as
a floor plan and the annotated room shape have it), joined to its neighbours by STEP
segments.

B is a *run* (``runs``): consecutive WALL segments that are one straight line at the
counter's height (their vertices within ``collinear_m`` of it). A front edge is one line,
but the boundary search breaks it where the face below changes: a dishwasher or an oven
has no door edges, a sink's cabinet no back edge above it within reach of the lines. Each
part alone fails a test the whole counter passes (dev kitchen zr_r06, spot p12: the part
in front of the dishwasher has the back edge above it but no door edge, the part beside it
three door edges but no back edge in its columns), so the tests pool the run's columns.
A run that fails whole has each of its parts tested alone: its chord, from vertices up to
``collinear_m`` off the edge, can move the back edge's depth past a counter's.
Pure numpy; no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.hypotheses import Hypothesis
from findme_core.single.layout import floor_xz
from findme_core.single.search import SegKind


@dataclass(frozen=True)
class CounterParams:
    """What a counter looks like (metres unless named)."""

    height_m: float = 0.9              # counter top above the floor
    depth_m: tuple = (0.45, 0.80)      # front edge to the wall
    door_top_m: float = 0.35           # door edges start at most this far below the top
    door_len_m: float = 0.10           # ... and run at least this far down the cabinet face
    toe_px: float = 8.0                # the cabinets' foot: a parallel line this close to it
    min_doors: int = 2                 # 3D-vertical edges below the front edge
    parallel_deg: float = 2.5          # a line parallel to B in 3D within this
    vertical_deg: float = 1.5          # a line through the vertical vanishing point within this
    min_line_px: float = 20.0          # lines shorter than this are not used
    min_segment_px: float = 30.0       # boundary segments narrower than this are not tested
    collinear_m: float = 0.05          # a run's vertices lie this near its line (counter height)


@dataclass(frozen=True)
class Counter:
    """A boundary segment found to be a counter's front edge.

    Attributes:
        segment: index of the run's first WALL segment in the hypothesis.
        normal: (2,) unit (x, z) normal of the wall, pointing away from the camera.
        wall_m: the wall's distance from the camera along ``normal``, metres.
        depth_m: front edge to wall, metres.
        doors: number of door edges found below the front edge.
        last: index of the run's last segment (``segment`` for a run of one).
    """

    segment: int
    normal: np.ndarray
    wall_m: float
    depth_m: float
    doors: int
    last: int


def runs(camera: Camera, height: float, hyp: Hypothesis,
         params: CounterParams = CounterParams()) -> list[tuple[int, int]]:
    """(first, last) segment indices of each run of ``hyp``: consecutive WALL segments whose
    vertices, lifted to the counter's height, all lie within ``collinear_m`` of the line
    through the run's end vertices (one straight edge; metres). Segments whose vertices do
    not lift (at or above the counter top's horizon) are runs of their own."""
    poly = np.asarray(hyp.polyline, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        _, q = floor_xz(camera, height - params.height_m, poly)
    out, s, n = [], 0, len(hyp.kinds)
    while s < n:
        if hyp.kinds[s] != SegKind.WALL:
            s += 1
            continue
        last = s
        while (last + 1 < n and hyp.kinds[last + 1] == SegKind.WALL
               and _straight(q[s:last + 3], params.collinear_m)):
            last += 1
        out.append((s, last))
        s = last + 1
    return out


def _straight(q: np.ndarray, tol: float) -> bool:
    """Whether the (K, 2) points (x, z) all lie within ``tol`` metres of the line through
    the first and the last (False when any is not finite or the two coincide)."""
    if not np.isfinite(q).all():
        return False
    d = q[-1] - q[0]
    L = float(np.hypot(*d))
    if L < 1e-9:
        return False
    off = (q - q[0]) @ np.array([d[1], -d[0]]) / L
    return bool(np.all(np.abs(off) <= tol))


def _row(ends: np.ndarray, u):
    """Row at columns ``u`` of the image line through the two pixels ``ends`` (2, 2)
    (extended past them; the caller makes sure it is not vertical)."""
    (u0, v0), (u1, v1) = ends
    return v0 + (np.asarray(u, float) - u0) * (v1 - v0) / (u1 - u0)


def find(camera: Camera, height: float, hyp: Hypothesis, lines: np.ndarray,
         params: CounterParams = CounterParams()) -> list[Counter]:
    """The runs of WALL segments of ``hyp`` (``runs``) that are counters' front edges
    (module docstring).

    Args:
        camera: intrinsics and gravity of the photo.
        height: camera height above the floor, metres (the counter's height is metric).
        hyp: a boundary hypothesis of the photo.
        lines: (N, 4) the photo's straight lines [u1, v1, u2, v2], pixels.
    Returns:
        The counters found, by run; none when the camera is not above the counter top.
    """
    p = params
    H = p.height_m
    ends = np.asarray(lines, float).reshape(-1, 4)
    if height <= H + 0.1 or len(ends) == 0:
        return []
    r1, r2 = camera.rays_level(ends[:, :2]), camera.rays_level(ends[:, 2:])
    n = np.cross(r1, r2)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    length = np.hypot(ends[:, 2] - ends[:, 0], ends[:, 3] - ends[:, 1])
    long = length >= p.min_line_px
    u_mid, v_mid = 0.5 * (ends[:, 0] + ends[:, 2]), 0.5 * (ends[:, 1] + ends[:, 3])
    vertical = long & (np.abs(n[:, 1]) < math.sin(math.radians(p.vertical_deg)))
    upper = (ends[:, 1] < ends[:, 3])[:, None]
    r_top = camera.rays_level(np.where(upper, ends[:, :2], ends[:, 2:]))
    r_bot = camera.rays_level(np.where(upper, ends[:, 2:], ends[:, :2]))
    u_top = np.where(upper[:, 0], ends[:, 0], ends[:, 2])
    poly = np.asarray(hyp.polyline, float)

    def test(s: int, last: int) -> Counter | None:   # segments s..last as one front edge
        b1, b2 = poly[s], poly[last + 1]
        if b2[0] - b1[0] < p.min_segment_px:
            return None
        _, pb = floor_xz(camera, height - H, np.array([b1, b2]))   # B at the counter's height
        if not np.isfinite(pb).all():
            return None
        d = pb[1] - pb[0]
        if np.linalg.norm(d) < 1e-6:
            return None
        d /= np.linalg.norm(d)
        o = np.array([d[1], -d[0]])
        if o @ pb[0] < 0:
            o = -o
        front = float(o @ pb[0])
        if front <= 0:
            return None
        par = long & (np.abs(n @ np.array([d[0], 0.0, d[1]]))
                      < math.sin(math.radians(p.parallel_deg)))
        inside = (u_mid > b1[0]) & (u_mid < b2[0])
        v_b = np.interp(u_mid, [b1[0], b2[0]], [b1[1], b2[1]])
        # 1. door edges: 3D-vertical lines on B's plane, from just below its top downwards
        k, kb = r_top[:, [0, 2]] @ o, r_bot[:, [0, 2]] @ o
        with np.errstate(divide="ignore", invalid="ignore"):
            drop = front * r_top[:, 1] / k - (height - H)   # below the counter top, metres
            run = front * (r_bot[:, 1] / kb - r_top[:, 1] / k)
        # (a floor line at right angles to B through the camera's foot looks vertical too:
        # the lines that could be one are not counted)
        plank = np.abs(n @ np.array([o[0], 0.0, o[1]])) < math.sin(math.radians(p.vertical_deg))
        doors = int(np.sum(vertical & ~plank & (u_top > b1[0]) & (u_top < b2[0]) & (k > 1e-9)
                           & (kb > 1e-9) & (drop > -0.05) & (drop < p.door_top_m)
                           & (run >= p.door_len_m)))
        if doors < p.min_doors:
            return None
        # 2. the cabinets' foot (B's plane at the floor): where the photo shows it, a line
        # parallel to B lies there (below a floor line there is floor, not a foot)
        foot, ahead = camera.project_level(np.column_stack([pb[:, 0], np.full(2, height),
                                                            pb[:, 1]]))
        if (ahead.all() and abs(foot[1, 0] - foot[0, 0]) > 1e-6
                and _row(foot, 0.5 * (b1[0] + b2[0])) < camera.height - p.toe_px
                and not np.any(par & inside & (np.abs(v_mid - _row(foot, u_mid)) < p.toe_px))):
            return None
        # 3. the counter's back edge: the first parallel line above B at a counter's depth
        # (nearer ones lie on the top: its nosing's back line, a sink's rim, an appliance)
        above = np.flatnonzero(par & inside & (v_mid < v_b - 3.0))
        if not len(above):
            return None
        q1, q2 = (floor_xz(camera, height - H, ends[above, c:c + 2])[1] for c in (0, 2))
        behind = 0.5 * (q1 @ o + q2 @ o) - front
        behind = np.where(np.isfinite(behind) & (behind >= p.depth_m[0]), behind, np.inf)
        j = int(np.argmin(behind))
        if not behind[j] <= p.depth_m[1]:
            return None
        return Counter(s, o, front + float(behind[j]), float(behind[j]), doors, last)

    found = []
    for s, last in runs(camera, height, hyp, p):
        c = test(s, last)
        if c is None and last > s:   # the run as a whole fails: each part alone may not
            found += [c for c in (test(k, k) for k in range(s, last + 1)) if c is not None]
        elif c is not None:
            found.append(c)
    return found


def behind(camera: Camera, height: float, hyp: Hypothesis, counters: list[Counter]) -> Hypothesis:
    """``hyp`` with each counter's front edge (its run of segments) replaced by the image of
    the wall's base behind it (the vertical plane at ``wall_m`` along ``normal``, at the
    floor), joined to the neighbouring segments by STEP segments (u stays non-decreasing; v
    may lie below the image, where the base is hidden under it).

    Args:
        camera, height: as ``find``.
        hyp: the hypothesis the counters were found on.
        counters: ``find``'s answer for it.
    """
    if not counters:
        return hyp
    by = {c.segment: c for c in counters}
    poly = np.asarray(hyp.polyline, float)
    verts, kinds, s = [poly[0]], [], 0
    while s < len(hyp.kinds):
        c = by.get(s)
        b1, b2 = poly[s], poly[s + 1 if c is None else c.last + 1]
        base = None if c is None else _base(camera, height, c, b1, b2)
        if base is None:
            verts.append(poly[s + 1])
            kinds.append(int(hyp.kinds[s]))
            s += 1
            continue
        verts += [np.array([b1[0], _row(base, b1[0])]), np.array([b2[0], _row(base, b2[0])]), b2]
        kinds += [int(SegKind.STEP), int(SegKind.WALL), int(SegKind.STEP)]
        s = c.last + 1
    return replace(hyp, polyline=np.array(verts), kinds=np.array(kinds))


def _base(camera: Camera, height: float, c: Counter, b1, b2) -> np.ndarray | None:
    """(2, 2) two pixels of the image of the wall's base behind counter ``c``, at the
    azimuths of its front edge's ends ``b1``, ``b2``; None when that image is vertical."""
    rays = camera.rays_level(np.array([b1, b2]))
    xz = rays[:, [0, 2]]
    t = c.wall_m / np.maximum(xz @ c.normal, 1e-9)
    uv, _ = camera.project_level(np.column_stack([t * xz[:, 0], np.full(2, height),
                                                  t * xz[:, 1]]))
    return None if abs(uv[1, 0] - uv[0, 0]) < 1e-6 else uv


def apply(hs, camera: Camera, height: float | None, max_n: int | None = None,
          lines: np.ndarray | None = None, params: CounterParams = CounterParams()):
    """A ``HypothesisSet`` with its best boundary seen behind the counters it stands on:
    ``behind`` of it first, the hypotheses as found after it (the counters' front edges, for
    a user who measures the cabinets); at most ``max_n`` (default: as many as before).
    Unchanged without a camera height (a counter's height is metric) or when no counter is
    found. The best boundary is the first hypothesis, or the second when "no floor visible"
    came first (as ``flat.no_floor_first`` puts it before a counter top's edge, smooth under
    it; the doors and the back edge found here say where the wall is).

    Args:
        hs: ``hypotheses.HypothesisSet`` of the photo (its lines and hypotheses in the
            pixels of ``camera``).
        camera: the intrinsics and gravity the hypotheses were found with.
        height: camera height above the floor, metres, or None.
        lines: (N, 4) the photo's lines in ``camera``'s pixels (default: ``hs.lines``).
    """
    if height is None or not hs.hypotheses:
        return hs
    top = next((h for h in hs.hypotheses[:2] if not np.all(h.kinds == SegKind.NONE)), None)
    if top is None:
        return hs
    found = find(camera, height, top, hs.lines.ends if lines is None else lines, params)
    if not found:
        return hs
    n = len(hs.hypotheses) if max_n is None else max_n
    return replace(hs, hypotheses=[behind(camera, height, top, found), *hs.hypotheses][:n])
