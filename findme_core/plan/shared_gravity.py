"""One gravity for the photos of one spot: plain photos (no phone sensors) agree on gravity.

A photo's gravity from its own lines (``single/vanishing``) can be wrong, or ambiguous: one
dominant family of parallel lines (floorboards, tiles) fits frames tens of degrees apart.
Photos taken turning at one spot share more than a room: the rotation M_ij between any two
of them follows from their feature matches alone (``spot.camera_rotation``: a pure rotation,
no gravity needed), and gravity is one direction in the world, so photo j's gravity is
g_j = M_ij^T g_i. Each photo's candidates (its estimate and its alternatives) are carried
into the frame of the spot's first photo and vote; the direction most photos agree on is the
spot's gravity, given back to every photo of the spot, those whose own estimate was wrong
included. Where the photos do not agree (two directions with nearly the same support, or
fewer than ``min_votes`` photos behind any), nothing is decided: the photos keep their own
estimates and ``undecided`` says why, so that a plan can leave them out rather than draw a
wrong room.

Frames: gravity vectors are unit 3-vectors in each photo's camera coordinates (x right,
y down, z forward), pointing down; M_ij maps camera j's coordinates to camera i's; angles in
radians inside, degrees in parameters (``_deg``) and messages. Pure numpy; no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from findme_core.motion import features
from findme_core.plan import session, spot
from findme_core.single import gravity_alternatives as alt


@dataclass(frozen=True)
class SharedGravityParams:
    """Attributes:
        agree_deg: two candidates (in the spot's frame) within this angle are one direction.
        min_votes: photos that must vote for a direction before it is the spot's.
        runner_up: a second direction with this share of the best's support leaves the
            spot undecided.
        alternative_sigma_deg: 1-sigma given to an alternative (it has no fit of its own).
        link_sigma_deg: 1-sigma of the rotation between two photos (feature noise), added per
            link of the chain from the spot's first photo.
        window: each photo is matched with the next ``window`` photos.
    """

    agree_deg: float = 3.0
    min_votes: int = 2
    runner_up: float = 0.8
    alternative_sigma_deg: float = 2.0
    link_sigma_deg: float = 0.2
    window: int = 2
    spot: spot.SpotParams = spot.SpotParams(residual_px=3.0, min_inliers=15, min_fraction=0.3)


@dataclass(frozen=True)
class SharedGravity:
    """The outcome for N photos.

    Attributes:
        vectors: (N, 3) each photo's gravity (the spot's, or its own where undecided).
        sigmas: (N,) their 1-sigma per tilt axis, radians.
        spots: (N,) the spot (component of rotation links) of each photo, numbered from 0.
        status: (N,) "agreed" (its own estimate was the spot's), "corrected" (it took the
            spot's), "own" (alone, or it kept its own: see ``undecided``).
        undecided: {photo index: reason} of the photos whose spot could not decide.
    """

    vectors: np.ndarray
    sigmas: np.ndarray
    spots: np.ndarray
    status: tuple
    undecided: dict


def links(cameras, feats, params: SharedGravityParams = SharedGravityParams()) -> dict:
    """{(i, j): M_ij} for i < j <= i + ``window`` whose matches agree on a pure rotation."""
    out = {}
    for i in range(len(cameras)):
        for j in range(i + 1, min(len(cameras), i + 1 + params.window)):
            m = features.match(feats[i], feats[j])
            r = spot.camera_rotation(m, cameras[i], cameras[j], params.spot)
            if r is not None:
                out[(i, j)] = r[0]
    return out


def _components(n: int, rot: dict) -> tuple[np.ndarray, list, np.ndarray]:
    """(spot label (N,), M_root_i (N, 3, 3) into the spot's first photo, chain length (N,)),
    by breadth-first search from each spot's lowest index."""
    adj: dict[int, list] = {i: [] for i in range(n)}
    for (i, j), M in sorted(rot.items()):
        adj[i].append((j, M))          # b_i = M b_j: j's coordinates into i's
        adj[j].append((i, M.T))
    label = np.full(n, -1)
    to_root = [np.eye(3)] * n
    depth = np.zeros(n, int)
    k = 0
    for s in range(n):
        if label[s] >= 0:
            continue
        label[s], queue = k, [s]
        while queue:
            i = queue.pop(0)
            for j, M in adj[i]:
                if label[j] < 0:
                    label[j], to_root[j], depth[j] = k, to_root[i] @ M, depth[i] + 1
                    queue.append(j)
        k += 1
    return label, to_root, depth


def _candidates(est, sigma_alt: float) -> list:
    """[(gravity (3,), weight, sigma rad, its own estimate?)] of one photo's estimate: none
    when it assumed level (no evidence), else its vector (weight 1) and its alternatives
    (weight: their score ratio, which may exceed 1)."""
    if est is None or est.source == "level":
        return []
    base = est.fit_cov if est.fit_cov is not None else est.cov
    out = [(alt.down(est.vector), 1.0, math.sqrt(max(np.trace(base), 0.0) / 2.0), True)]
    out += [(alt.down(g), float(r), sigma_alt, False) for g, r in est.alternatives]
    return out


def agree(cameras, estimates, feats, params: SharedGravityParams = SharedGravityParams(),
          rotations: dict | None = None) -> SharedGravity:
    """The spots' gravities (module doc).

    Args:
        cameras: N ``Camera`` (intrinsics; their gravity is not used).
        estimates: N ``vanishing.GravityEstimate`` (None: the photo brings no candidate).
        feats: N ``features.Features`` of the photos.
        rotations: precomputed ``links`` (tests), else computed.
    """
    n = len(cameras)
    rot = links(cameras, feats, params) if rotations is None else rotations
    label, to_root, depth = _components(n, rot)
    vec = np.array([alt.down(e.vector) if e is not None else np.array([0.0, 1.0, 0.0])
                    for e in estimates])
    sig = np.array([e.sigma if e is not None else math.radians(10.0) for e in estimates])
    status = ["own"] * n
    undecided: dict[int, str] = {}
    tol = math.radians(params.agree_deg)
    for k in range(int(label.max()) + 1 if n else 0):
        members = [i for i in range(n) if label[i] == k]
        if len(members) < 2:
            continue
        votes = [(i, to_root[i] @ g, w, s, mine) for i in members
                 for g, w, s, mine in _candidates(estimates[i],
                                                  math.radians(params.alternative_sigma_deg))]
        found = _vote(votes, tol)
        why = _undecided(found, params)
        if why:
            for i in members:
                undecided[i] = why
            continue
        g0, s0, own = found[0][0], found[0][1], found[0][2]
        for i in members:
            g = to_root[i].T @ g0
            vec[i] = g / np.linalg.norm(g)
            sig[i] = math.hypot(s0, math.radians(params.link_sigma_deg) * math.sqrt(depth[i]))
            status[i] = "agreed" if i in own else "corrected"
    return SharedGravity(vec, sig, label, tuple(status), undecided)


def _vote(votes, tol: float) -> list:
    """Directions the votes agree on, best first: [(unit gravity in the root frame, its
    1-sigma, photos whose own estimate is in it, support, photos voting)].
    Greedy clustering, heaviest vote first (ties by photo index: the same on every
    machine); a photo counts once per direction, with its heaviest candidate there."""
    order = sorted(range(len(votes)), key=lambda v: (-round(votes[v][2], 6), votes[v][0], v))
    clusters: list[list] = []
    for v in order:
        g = votes[v][1] / np.linalg.norm(votes[v][1])
        for c in clusters:
            if math.acos(float(np.clip(g @ c[0], -1.0, 1.0))) < tol:
                c[1].append(v)
                break
        else:
            clusters.append([g, [v]])
    out = []
    for centre, vs in clusters:
        best: dict[int, int] = {}
        for v in vs:                       # each photo's heaviest candidate in the cluster
            i = votes[v][0]
            if i not in best or votes[v][2] > votes[best[i]][2]:
                best[i] = v
        chosen = [votes[v] for v in best.values()]
        info = np.array([1.0 / max(v[3], 1e-6) ** 2 for v in chosen])
        g = sum(w * v[1] for w, v in zip(info, chosen))
        g = g / np.linalg.norm(g)
        spread = [math.acos(float(np.clip(g @ (v[1] / np.linalg.norm(v[1])), -1.0, 1.0)))
                  for v in chosen]
        m = len(chosen)
        sigma = max(math.sqrt(1.0 / info.sum()),
                    math.sqrt(sum(x * x for x in spread) / max(m - 1, 1) / m) if m > 1 else 0.0)
        own = {votes[v][0] for v in vs if votes[v][4]}
        out.append((g, sigma, own, sum(v[2] for v in chosen), m))
    out.sort(key=lambda c: (-round(c[3], 6), -c[4], min(c[2], default=1 << 30)))
    return out


def _undecided(found: list, params: SharedGravityParams) -> str | None:
    """Why the spot's photos do not decide, or None."""
    if not found:
        return "no photo of its spot shows which way is down"
    g, _, _, support, m = found[0]
    if m < params.min_votes:
        return (f"only {m} photo of its spot shows which way is down (need "
                f"{params.min_votes} that agree)")
    if len(found) > 1 and found[1][3] >= params.runner_up * support:
        a = math.degrees(math.acos(float(np.clip(g @ found[1][0], -1.0, 1.0))))
        return (f"the photos of its spot disagree on which way is down: two directions "
                f"{a:.0f} deg apart have nearly the same support ({found[1][3]:.1f} vs "
                f"{support:.1f} votes)")
    return None


def verdicts(estimates, sg: SharedGravity) -> list:
    """What a plan does with each photo once its spot has voted: None (its gravity was given:
    as it is), a str (left out, the reason: its spot could not decide, or it stands alone
    with an ambiguous gravity), or the (3,) gravity to analyse it under."""
    out: list = []
    for i, e in enumerate(estimates):
        if e is None:
            out.append(None)
            continue
        why = sg.undecided.get(i)
        if why is None and sg.status[i] == "own" and e.alternatives:
            why = e.reason or alt.describe(e.vector, e.alternatives)
        out.append(f"gravity unknown: {why}" if why is not None else sg.vectors[i])
    return out


def analyse_plain(images, cameras, heights, estimates, params=None,
                  shared: SharedGravityParams = SharedGravityParams(), kinds=None, sigmas=None):
    """A session's photos (``session.analyse``) where some photos' gravity came from their
    own lines (``estimates[i]`` not None, ``session.Photo.gravity`` "image"; None: given,
    kept as it is, of the kind ``kinds[i]`` says, "exact" by default, its tilt's 1-sigma
    ``sigmas[i]`` radians, 0 by default): those agree on it spot by spot first (``agree``:
    the agreed gravity's 1-sigma with it), then get their hypotheses under it. Photos whose
    spot cannot decide, and lone photos whose own gravity is ambiguous (it has
    alternatives), are left out (no layout) with the reason: a plan without them beats a
    wrong room.

    Returns:
        (photos, ``SharedGravity`` or None when no photo's gravity came from its lines).
    """
    params = params or session.SessionParams()
    kinds = kinds or ["exact"] * len(images)
    sigmas = [0.0] * len(images) if sigmas is None else sigmas
    feats = [features.detect(im, params.features) for im in images]
    if all(e is None for e in estimates):
        return [session.analyse(im, c, h, params, f, gravity=k, gravity_sigma=s)
                for im, c, h, f, k, s in zip(images, cameras, heights, feats, kinds, sigmas)
                ], None
    sg = agree(cameras, estimates, feats, shared)
    photos = []
    for i, (im, c, h, f, v) in enumerate(zip(images, cameras, heights, feats,
                                             verdicts(estimates, sg))):
        if v is None:
            photos.append(session.analyse(im, c, h, params, f, gravity=kinds[i],
                                          gravity_sigma=sigmas[i]))
        elif isinstance(v, str):
            photos.append(session.Photo(c, float(h), None, None, f, v, gravity="image"))
        else:
            photos.append(session.analyse(im, c.with_gravity(v), h, params, f, gravity="image",
                                          gravity_sigma=float(sg.sigmas[i])))
    return photos, sg
