"""A session's photos put into one room frame: blocks of photos turned at one spot, then each
block registered to the photos already placed by their layouts.

Frames: the room frame is the level frame of photo 0 (x right, z forward, y down; metres).
A photo's pose is (x, z, yaw): a floor point p of its level frame is R(yaw) p + (x, z) in
the room frame, R(yaw) = [[c, s], [-s, c]] on (x, z) (``register.rot2``; yaw > 0 turned
right, radians). Photo 0 has pose (0, 0, 0).

* Links: rotation-only yaws between photos of one spot (``spot.rotation_yaw``). Photos joined
  by links form a block whose relative yaws are known; a block has one unknown yaw.
* Spots: photos taken at one spot share a position. Given spot labels, a block whose spot is
  already placed has only its yaw unknown (1 DOF); otherwise position and yaw (3 DOF).
* Placement, block by block (beam search, the biggest spots first): candidate poses from wall and corner
  correspondences with each placed photo (``register.wall_yaws`` / ``translations``),
  scored by the layout agreement of every (placed photo, block photo) pair
  (``register.scores``, both ways: agreeing wall samples minus samples on seen floor), the
  feature matches and the two-photo motions (``evidence``).

The joint refinement of all poses and walls is ``adjustment``. Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from findme_core.errors import GeometryError
from findme_core.geometry import ties
from findme_core.geometry.planar import wrap
from findme_core.motion import register
from findme_core.plan import evidence, heading


@dataclass(frozen=True)
class Link:
    """Photo j turned by ``yaw`` (radians, > 0 right) from photo i at the same spot."""

    i: int
    j: int
    yaw: float
    sigma: float
    t: tuple | None = None   # (x, z) of photo j in photo i's level frame, metres, if known


@dataclass(frozen=True)
class FuseParams:
    """Candidate search.

    Attributes:
        yaw_merge_deg, t_merge_m: candidates closer than this are one.
        max_candidates: at most this many (by count of the correspondences that gave them)
            are scored per block.
        yaw_grid_deg: a block of a placed spot also tries every this many degrees.
        min_score: a block scoring less than this is left unplaced.
        motion_weight, motion_rel: a two-photo motion (``Link`` with ``t``) adds up to
            ``motion_weight`` to a pose that puts the photo within ``motion_rel`` (1-sigma,
            relative to the distance) and ``motion_yaw_deg`` of where the motion says (the features' metric
            scale along the baseline, which the epipolar score cannot see).
        beam: placements kept at each step of the search (and distinct poses tried per
            block): a block's best pose alone may be wrong where a later block tells.
        feature_px, feature_fade_px, feature_weight, feature_top: a feature match near its
            epipolar plane scores up to ``feature_weight``, for the ``feature_top`` best
            candidates by layout (``evidence.feature_score``: the rule and why).
        turn_alike: a final state of the search that turns a block > 10 deg and scores
            this share of the block's score (``evidence.alike``) widens its 1-sigma to cover
            it (``pose.spread``).
        heading_gate: a candidate turning a block more than this many sigmas from the
            phone's headings is not tried (``heading.fits``; a Gaussian's 3, not fitted).
        register: the layout terms (``register.scores``). Samples count in full up to a
            1-sigma of 1 m (``sigma_ref``): the gate already scales with the sigma, and in a
            session every photo's far walls are the other photos' near ones (down-weighting
            them from 0.1 m loses the L-shape's far wing).
    """

    yaw_merge_deg: float = 1.0
    t_merge_m: float = 0.05
    max_candidates: int = 3000
    yaw_grid_deg: float = 2.0
    min_score: float = 1.0
    feature_px: float = 8.0
    feature_fade_px: float = 24.0
    feature_top: int = 200
    beam: int = 6
    motion_weight: float = 10.0
    motion_rel: float = 0.15
    motion_yaw_deg: float = 3.0
    feature_weight: float = 3.0
    turn_alike: float = 0.8
    heading_gate: float = 3.0
    register: register.RegisterParams = field(
        default_factory=lambda: register.RegisterParams(sigma_ref=1.0))


@dataclass
class Placement:
    """Poses of the session's photos in the room frame.

    Attributes:
        poses: (N, 3) (x, z, yaw) per photo; NaN rows for photos not placed.
        block: (N,) block index of each photo.
        rel_yaw: (N,) yaw of each photo relative to its block's first photo, radians.
        spot: (N,) spot index of each photo (given, or one per block).
        scores: per block, the layout score of its placement (0 for block 0).
        ambiguity: per block, the best score of a clearly different placement (NaN if none).
        reasons: per block, why it is unplaced (None when placed).
        order: the blocks in the order they were placed.
        alternatives: per block, ((pose offset (3,), score ratio), ...): the search's final
            states that turn it more than 10 deg and score nearly as well (``evidence.alike``).
    """

    poses: np.ndarray
    block: np.ndarray
    rel_yaw: np.ndarray
    spot: np.ndarray
    scores: list
    ambiguity: list
    reasons: list
    order: list = field(default_factory=list)
    alternatives: list = field(default_factory=list)


def relative(pa, pb):
    """Motion (yaw, t (2,)) of pose pb in the frame of pose pa (both (x, z, yaw))."""
    d = np.array([pb[0] - pa[0], pb[1] - pa[1]])
    return wrap(pb[2] - pa[2]), register.rot2(np.array([-pa[2]]), d[None])[0, 0]


def compose(pa, yaw, t):
    """Pose of a photo at motion (yaw, t) in the frame of pose pa, in the room frame."""
    q = register.rot2(np.array([pa[2]]), np.asarray(t, float)[None])[0, 0]
    return np.array([pa[0] + q[0], pa[1] + q[1], float(wrap(pa[2] + yaw))])


def blocks(n: int, links) -> tuple[np.ndarray, np.ndarray]:
    """(block (N,), rel_yaw (N,)): photos joined by links, numbered by their first photo in
    capture order, and each photo's yaw relative to its block's first photo."""
    adj = {i: [] for i in range(n)}
    for k in links:
        adj[k.i].append((k.j, k.yaw))
        adj[k.j].append((k.i, -k.yaw))
    block, rel = np.full(n, -1), np.zeros(n)
    nb = 0
    for s in range(n):
        if block[s] >= 0:
            continue
        block[s], stack = nb, [s]
        while stack:
            i = stack.pop()
            for j, y in adj[i]:
                if block[j] < 0:
                    block[j], rel[j] = nb, wrap(rel[i] + y)
                    stack.append(j)
        nb += 1
    return block, rel


def place(layouts, links=(), spots=None, matches=None, motions=(),
          params: FuseParams = FuseParams(), headings=None) -> Placement:
    """Poses of N photos from their layouts, rotation links and (optional) spot labels.

    Args:
        layouts: N ``Layout`` (or None for a photo without one), capture order.
        links: ``Link`` s between photos of one spot.
        spots: (N,) spot label per photo (photos with one label share a position), or None
            (each block its own spot).
        matches: {(i, j): (a (M, 3), b (M, 3))} unit level-frame bearings of feature
            matches between photos i and j (i < j), or None.
        motions: ``Link`` s with a translation ``t`` (photo j's pose in photo i's level
            frame, e.g. two-photo motion from features): extra candidate poses.
        headings: (N, 3) the phone's heading, its 1-sigma (radians) and its reference
            number per photo, NaN rows where unknown (``heading.table``), or None.

    Raises:
        GeometryError: photo 0 has no layout and no link (nothing to anchor the room frame).
    """
    n = len(layouts)
    if n == 0:
        raise GeometryError("a plan needs at least one photo")
    block, rel = blocks(n, links)
    nb = int(block.max()) + 1
    if spots is None:
        spot = block.copy()
    else:
        _, spot = np.unique(np.asarray(spots), return_inverse=True)
    poses = np.full((n, 3), np.nan)
    for i in np.flatnonzero(block == 0):
        poses[i] = (0.0, 0.0, wrap(rel[i] - rel[0]))
    has = np.array([L is not None for L in layouts])
    size = np.bincount(block, weights=has, minlength=nb)
    spot_size = {s: size[np.unique(block[spot == s])].sum() for s in np.unique(spot)}
    # the biggest spots first, each spot's biggest block first (the others then turn in place)
    order = sorted(range(1, nb), key=lambda b: (-spot_size[spot[block == b][0]],
                                                 int(spot[block == b][0]), -size[b], b))
    # beam search over the blocks' candidate poses: a state is (total score, poses, spot
    # positions, per-block (score, ambiguity, reason))
    beam = [(0.0, poses, {int(spot[0]): np.zeros(2)}, {})]
    for b in order:
        members = np.flatnonzero(block == b)
        nxt = []
        for total, ps, sp, info in beam:
            r = place_block(layouts, ps, rel, block, spot, sp, matches, motions, b, params,
                            headings)
            if isinstance(r, str):
                nxt.append((total, ps, sp, {**info, b: (0.0, float("nan"), r)}))
                continue
            cands, sc = r
            for k in range(len(cands)):
                q = ps.copy()
                for i in members:
                    q[i] = (cands[k, 0], cands[k, 1], wrap(cands[k, 2] + rel[i]))
                sp2 = dict(sp)
                sp2.setdefault(int(spot[members[0]]), cands[k, :2].copy())
                other = float(sc[1]) if len(sc) > 1 else float("nan")
                nxt.append((total + float(sc[k]), q, sp2,
                            {**info, b: (float(sc[k]), other if k == 0 else float(sc[0]), None)}))
        # best first; states that score alike (a symmetric room) keep the order they were
        # made in, so the beam keeps the same ones on every machine
        beam = [nxt[i] for i in ties.order(np.array([st[0] for st in nxt]))[: params.beam]]
    _, poses, _, info = beam[0]
    scores, amb, reasons = [0.0] * nb, [float("nan")] * nb, [None] * nb
    for b, (sc, am, why) in info.items():
        scores[b], amb[b], reasons[b] = sc, am, why
    alts = evidence.alike([st[0] for st in beam], [st[1] for st in beam], scores, block,
                          params.turn_alike)
    return Placement(poses, block, rel, spot, scores, amb, reasons, order, alts)


def place_block(layouts, poses, rel, block, spot, placed_spot, matches, motions, b,
                params: FuseParams, headings=None):
    """Poses of block b against the photos placed so far: (poses (K, 3), scores (K,)), the
    best first and then the best of each clearly different pose (10 deg or 0.3 m apart), or
    the reason it cannot be placed (str).

    Args:
        layouts: (N,) ``Layout`` or None; poses: (N, 3) room-frame poses, NaN rows for the
            photos not placed yet; rel: (N,) yaw of each photo in its block, radians;
            block, spot: (N,) block and spot index of each photo; placed_spot: {spot:
            (2,) position} of the spots placed so far (a block of one of them turns in
            place); matches, motions, headings: as ``place``.
    """
    members = np.flatnonzero(block == b)
    placed = np.flatnonzero(np.isfinite(poses[:, 0]) & np.array([L is not None for L in layouts]))
    mine = [i for i in members if layouts[i] is not None]
    if not mine or not len(placed):
        return "no layout to register" if not mine else "no placed photo with a layout"
    if (evidence.wall_directions(layouts, rel, mine) == 1
            and not evidence.linked(matches, motions, members, placed)):
        # else put on any placed wall at a like distance (a rendered room's: 83 deg off)
        return ("it sees walls in one direction only and shares no features with the placed "
                "photos: its layout does not tell which of the room's walls it faces")
    fixed = placed_spot.get(int(spot[members[0]]))
    cands = _candidates(layouts, poses, rel, placed, mine, fixed, params)
    cands = np.vstack([_from_motions(motions, poses, rel, members, fixed), cands])
    if not len(cands):
        return "no wall of its photos matches a wall of the placed photos"
    cands = cands[heading.fits(headings, poses, rel, np.flatnonzero(np.isfinite(poses[:, 0])),
                               members, cands, params.heading_gate)]
    if not len(cands):
        return "none of the poses its walls allow turns it as the phone's heading says"
    sc = evidence.layout_score(layouts, poses, rel, placed, mine, cands, params)
    top = ties.order(sc)[: params.feature_top]   # ties (a symmetric room): candidate order
    cands, sc = cands[top], sc[top] + evidence.feature_score(matches or {}, poses, rel,
                                                              members, cands[top], params)
    sc = sc + evidence.motion_score(motions, poses, rel, members, cands, params)
    o = ties.order(sc)
    if sc[o[0]] < params.min_score:
        return (f"its walls agree with the placed photos' walls too little (score "
                f"{sc[o[0]]:.1f} < {params.min_score})")
    keep = []   # the best pose, then the best of each clearly different one
    for k in o:
        if sc[k] < params.min_score or len(keep) >= params.beam:
            break
        if all(abs(wrap(cands[k, 2] - cands[j, 2])) > np.radians(10)
               or np.hypot(*(cands[k, :2] - cands[j, :2])) > 0.3 for j in keep):
            keep.append(k)
    return cands[keep], sc[keep]


def _candidates(layouts, poses, rel, placed, mine, fixed, params: FuseParams) -> np.ndarray:
    """(C, 3) candidate block poses (x, z, yaw of the block's first photo, rel_yaw 0)."""
    out = []
    for i in placed:
        for j in mine:
            li, lj = layouts[i], layouts[j]
            for y in np.atleast_1d(register.wall_yaws(li, lj, params.register)):
                yaw_b = wrap(poses[i, 2] + y - rel[j])          # block yaw
                if fixed is not None:
                    out.append((fixed[0], fixed[1], yaw_b))
                    continue
                for t in register.translations(li, lj, float(y), None, params.register):
                    p = compose(poses[i], float(y), t)            # photo j's pose
                    # the block's first photo shares photo j's position
                    out.append((p[0], p[1], yaw_b))
    if fixed is not None:
        g = np.radians(np.arange(-180.0, 180.0, params.yaw_grid_deg))
        out.extend((fixed[0], fixed[1], y) for y in g)
    if not out:
        return np.zeros((0, 3))
    c = np.array(out, float)
    return _dedupe(c, params)


def _from_motions(motions, poses, rel, members, fixed) -> np.ndarray:
    """(C, 3) block poses implied by the motions between a placed photo and a block photo."""
    out = []
    for i, j, yaw, t in evidence.oriented(motions, members):
        if not np.isfinite(poses[i, 0]):
            continue
        p = compose(poses[i], yaw, t)
        out.append((p[0], p[1], wrap(p[2] - rel[j])) if fixed is None
                   else (fixed[0], fixed[1], wrap(p[2] - rel[j])))
    return np.array(out, float).reshape(-1, 3)


def _dedupe(c: np.ndarray, params: FuseParams) -> np.ndarray:
    """Merge candidates within the merge radii (keeps the first of each cluster, ordered by
    how many candidates fell in it)."""
    key = np.column_stack([np.round(c[:, 0] / params.t_merge_m),
                           np.round(c[:, 1] / params.t_merge_m),
                           np.round(np.degrees(wrap(c[:, 2])) / params.yaw_merge_deg)])
    _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    o = np.argsort(-counts, kind="stable")[: params.max_candidates]
    return c[first[o]]
