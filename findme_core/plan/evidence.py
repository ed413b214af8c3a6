"""How well candidate poses of a block of photos agree with the photos already placed: the
three terms ``fuse.place`` adds up for each candidate.

* layout: ``register.scores`` of every (placed photo, block photo) pair, both ways
  (agreeing wall samples minus samples on floor the other photo sees);
* features: feature matches the pose puts on their epipolar planes, in front of both
  cameras (planar motion, no height change; full within a few pixels, then fading);
* motions: two-photo motions (``fuse.Link`` with ``t``) between a placed photo and a block
  photo, a Gaussian in the position error (relative to the distance) and in the yaw error.

Frames: the room frame (x, z metres; yaw radians, > 0 turned right). A candidate is the
pose (x, z, yaw) of the block's first photo; photo j of the block has yaw ``cand yaw +
rel[j]`` and the block's position (one spot). ``params`` is a ``fuse.FuseParams`` (its
``register``, ``feature_*`` and ``motion_*`` fields). Pure numpy; no I/O.
"""

from __future__ import annotations

import numpy as np

from findme_core.geometry import planar
from findme_core.geometry.planar import wrap
from findme_core.motion import register


def oriented(motions, members):
    """The motions between a placed photo i and a block photo j (``members``), each as
    (i, j, yaw, t (2,)): photo j's pose in photo i's level frame (a motion given the other
    way round is inverted)."""
    mem = set(int(m) for m in members)
    for m in motions:
        i, j = m.i, m.j
        if (i in mem) == (j in mem) or m.t is None:
            continue
        yaw, t = m.yaw, np.asarray(m.t, float)
        if i in mem:   # invert: photo i's pose in photo j's frame
            i, j = j, i
            t = -register.rot2(np.array([-yaw]), t[None])[0, 0]
            yaw = -yaw
        yield i, j, yaw, t


def wall_directions(layouts, rel, mine, tol_deg: float = 30.0) -> int:
    """How many directions the walls of the block photos ``mine`` run in, in the block's
    frame (photo j's walls turned by its ``rel[j]``, radians); walls within ``tol_deg`` of
    parallel are one direction. 0 without walls."""
    ang = []
    for j in mine:
        w = layouts[j].walls
        if len(w):
            d = w[:, 1] - w[:, 0]   # R(yaw) turns an (x, z) direction by -yaw
            ang += list(np.degrees(np.arctan2(d[:, 1], d[:, 0]) - rel[j]) % 180.0)
    dirs = []
    for a in ang:   # in the photos' and walls' order: the same count on every machine
        if all(min(abs(a - b), 180.0 - abs(a - b)) > tol_deg for b in dirs):
            dirs.append(a)
    return len(dirs)


def linked(matches, motions, members, placed) -> bool:
    """Whether a block photo (``members``) shares feature matches or a two-photo motion
    with a placed photo (``placed``): evidence of its pose besides the layouts."""
    mem, pl = set(int(m) for m in members), set(int(p) for p in placed)
    pairs = [(i, j) for i, j in (matches or {})] + [(m.i, m.j) for m in motions]
    return any((i in mem and j in pl) or (j in mem and i in pl) for i, j in pairs)


def alike(totals, poses, scores, block, ratio: float, turn_deg: float = 10.0) -> list:
    """Per block, the placements of it turned more than ``turn_deg`` from the chosen one
    that the whole search found nearly as good: ((pose offset (3,), yaw wrapped; ratio), ...).

    Args:
        totals: (S,) total score of each final state of the search, the chosen one first;
        poses: S (N, 3) poses (NaN rows: not placed); scores: (B,) the chosen state's score
            of each block; block: (N,) block of each photo.
    A state is an alternative of block b when b's pose is turned; its ratio is what b's
    score would be with the state's shortfall taken from it alone, over b's score,
    (s_b - (totals[0] - totals[k])) / s_b: later blocks that agree less with the turned
    pose count against it. Kept when >= ``ratio``.
    """
    out = [[] for _ in range(len(scores))]
    for b in range(len(scores)):
        i = int(np.flatnonzero(np.asarray(block) == b)[0])
        if not scores[b] > 0 or not np.isfinite(poses[0][i, 0]):
            continue
        for k in range(1, len(totals)):
            d = poses[k][i] - poses[0][i]
            r = (scores[b] - (totals[0] - totals[k])) / scores[b]
            if np.isfinite(d[0]) and abs(wrap(d[2])) > np.radians(turn_deg) and r >= ratio:
                out[b].append((np.array([d[0], d[1], wrap(d[2])]), float(r)))
    return [tuple(a) for a in out]


def _block_poses(cands, rel, j):
    """(C, 3) poses of block photo j for C block candidates."""
    return np.column_stack([cands[:, 0], cands[:, 1], wrap(cands[:, 2] + rel[j])])


def _in_frame(pi, pj):
    """(yaw (C,), t (C, 2)) of poses pj (C, 3) in the frame of pose pi (3,)."""
    yaw = wrap(pj[:, 2] - pi[2])
    t = register.rot2(np.full(len(pj), -pi[2]), (pj[:, :2] - pi[:2])[:, None])[:, 0]
    return yaw, t


def layout_score(layouts, poses, rel, placed, mine, cands, params) -> np.ndarray:
    """(C,) summed layout score of C block poses (C, 3) over every (placed photo, block
    photo with a layout ``mine``) pair."""
    total = np.zeros(len(cands))
    for j in mine:
        pj = _block_poses(cands, rel, j)
        for i in placed:
            yaw, t = _in_frame(poses[i], pj)
            total += register.scores(layouts[i], layouts[j], yaw, t, params.register)
    return total


def feature_score(matches, poses, rel, members, cands, params) -> np.ndarray:
    """(C,) feature matches between placed photos and the block's photos that C block poses
    put near their epipolar planes, in front of both cameras (planar motion, no height
    change: t = (x, 0, z)); each scores ``feature_weight`` within ``feature_px`` (at 500 px
    focal length), falling linearly to 0 at ``feature_fade_px`` (``fuse.FuseParams``); with
    ``feature_fade_px`` <= ``feature_px``, MSAC: 1 - (r / ``feature_px``)^2 within it. A
    pose within ``t_merge_m`` of the placed photo is at its place: there r is the match's
    angle from a pure turn (``planar.turn_residuals``; the epipolar plane of a nil baseline
    holds every match of the right turn, and random ones by the thousand).

    Flat, not MSAC: a block's candidate poses are not refined (their directions are ~1 deg
    off), and the matches' residuals within that say nothing about which candidate is right;
    the layouts do (dev zr_r06: the poses put ~1.9x too far, along the line of three spots
    where the matches cannot tell the distance, won over a candidate 0.05 m from the truth by
    0.8 deg of direction, i.e. by 16 of ~830 MSAC points; flat within 8 px, 0 at 20-32 px: 10
    of 14 right instead of 2, the other rooms unchanged; flat within 6 or 12 px, or 0 at 16
    or 40 px: 2 of 14). MSAC serves ``find_spot``, which scores a found photo that nothing
    refines after (a plan's poses are refined, ``adjust``). A match is independent evidence
    (the wall's appearance) where neighbouring layout samples (6 px apart on one boundary
    line) are not: one match weighs as 12 layout samples (3.0 / 0.25; chosen on dev among 1,
    3: it turns zr_r10's flipped corridor spots right and changes no other room)."""
    total = np.zeros(len(cands))
    mem = set(int(m) for m in members)
    pix, fade = params.feature_px / 500.0, params.feature_fade_px / 500.0
    for (i, j), (a, b) in matches.items():
        if (i in mem) == (j in mem):
            continue
        if i in mem:                     # block photo first: swap to (placed, block)
            i, j, a, b = j, i, b, a
        if not np.isfinite(poses[i, 0]) or len(a) == 0:
            continue
        yaw, t2 = _in_frame(poses[i], _block_poses(cands, rel, j))
        t = np.column_stack([t2[:, 0], np.zeros(len(t2)), t2[:, 1]])
        r = np.abs(planar.epipolar_residuals(yaw, t, a, b))
        la, lb = planar.depths(yaw, t, a, b)
        front = (la > 0) & (lb > 0)
        turn = np.hypot(t2[:, 0], t2[:, 1]) < params.t_merge_m   # one place: a pure turn
        if turn.any():
            r[turn], front[turn] = planar.turn_residuals(yaw[turn], a, b), True
        if fade > pix:
            s = np.where(front & (r < fade), np.clip((fade - r) / (fade - pix), 0.0, 1.0), 0.0)
        else:          # MSAC
            s = np.where(front & (r < pix), 1.0 - (r / pix) ** 2, 0.0)
        total += params.feature_weight * np.sum(s, 1)
    return total


def motion_score(motions, poses, rel, members, cands, params) -> np.ndarray:
    """(C,) agreement of C block poses with the two-photo motions between placed photos and
    the block's photos: ``motion_weight`` x a Gaussian in the position error (1-sigma
    ``motion_rel`` x the motion's length, at least 0.3 m) and in the yaw error (1-sigma
    ``motion_yaw_deg``)."""
    total = np.zeros(len(cands))
    for i, j, yaw, t in oriented(motions, members):
        if not np.isfinite(poses[i, 0]):
            continue
        dyaw = wrap(cands[:, 2] + rel[j] - poses[i, 2] - yaw)
        # where the motion puts photo j, in the room frame; the candidates put it at cands[:, :2]
        want = poses[i, :2] + register.rot2(np.array([poses[i, 2]]), t[None])[0, 0]
        sig = params.motion_rel * max(float(np.hypot(*t)), 0.3)
        d = np.hypot(*(cands[:, :2] - want).T)
        total += params.motion_weight * np.exp(-0.5 * (d / sig) ** 2
                                               - 0.5 * (dyaw / np.radians(params.motion_yaw_deg)) ** 2)
    return total
