"""One session's odometry bookkeeping: which photos are open (seen, not yet resolved), which
have poses, which will never come, and which must wait for a lower photo. Pure and small:
``odometry.OdometryHandler`` estimates the motions.

Bounded: poses are kept for every posed photo (about 0.3 kB each); message payloads and
prepared photos (features, layouts) only for photos still open and for the ``anchors`` most
recent posed photos (the ones the next photo chains from). A frame is held only from when it
is fetched (its hypotheses came) until its photo is prepared: frames of at most
``keep_frames`` open photos, the newest; an older one is asked for again when selected.
A photo whose motion failed keeps its selection and hypotheses (the newest ``keep_frames``
such photos) in case a nearer anchor comes late (``fail``, ``reopen_after``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from findme_core.motion.trajectory import PlanarPose

CLOSED_MEMORY = 1024   # resolved photo numbers remembered per session (not to wait on again)
LOOK_BACK = 64         # photo numbers below n that n may wait for without having heard of them


@dataclass
class Photo:
    """What odometry holds about photo n while it is open or an anchor."""

    seen: float                      # when it was first heard of (monotonic s)
    frame: object | None = None      # Frame message (fetched with its hypotheses, dropped once prepared)
    time_ns: int | None = None       # its capture time, kept once the frame was fetched
    hset: object | None = None       # HypothesisSet message
    selection: object | None = None  # Selection message
    selected_at: float | None = None
    prepared: tuple | None = None    # (rank, findme_core.motion.pair prepared photo): its motions' inputs

    def hold(self, frame) -> None:
        """Hold ``frame`` (None: nobody had it) and keep its capture time past it."""
        self.frame = frame
        if frame is not None:
            self.time_ns = frame.capture_time_ns


class OdometrySession:
    def __init__(self, keep_frames: int = 8, anchors: int = 2):
        self.keep_frames, self.anchors = keep_frames, anchors
        self.photos: dict[int, Photo] = {}
        self.poses: dict[int, PlanarPose] = {}
        self.times: dict[int, int] = {}
        self.closed: dict[int, str] = {}     # n -> "failed" | "dead" (never selected)
        self.failed: dict[int, tuple[int, Photo]] = {}   # n -> (anchor it failed from, its messages)
        self.origin: int | None = None
        self.stale = False    # another instance may have posed photos since: ask the bus

    def photo(self, n: int, now: float) -> Photo:
        p = self.photos.get(n)
        if p is None:
            p = self.photos[n] = Photo(now)
        return p

    def is_open(self, n: int) -> bool:
        """Photo n may still get a pose (heard of, not posed, failed or given up)."""
        return n in self.photos and n not in self.poses and n not in self.closed

    def close(self, n: int, why: str) -> None:
        self.closed[n] = why
        while len(self.closed) > CLOSED_MEMORY:
            del self.closed[next(iter(self.closed))]
        self.photos.pop(n, None)

    def fail(self, n: int, anchor: int) -> None:
        """Photo n's motion from ``anchor`` failed: closed, its selection and hypotheses
        kept (not its frame or features) for ``reopen_after``."""
        p = self.photos.get(n)
        self.close(n, "failed")
        if p is not None and p.selection is not None and p.hset is not None:
            self.failed[n] = (anchor, replace(p, frame=None, prepared=None))
            while len(self.failed) > self.keep_frames:
                del self.failed[min(self.failed)]

    def reopen_after(self, m: int) -> list[int]:
        """Photo m has just got a pose: the failed photos above it that failed from an anchor
        below it, with no pose between, are open again (m is now their nearest anchor: a
        photo chained past m while m was late, e.g. its host was cut off, gets its pose
        from m once m has one). Returns them, lowest first."""
        out = []
        for n, (a, p) in sorted(self.failed.items()):
            if a < m < n and not any(m < k < n for k in self.poses):
                del self.failed[n]
                self.closed.pop(n, None)
                self.photos[n] = p
                out.append(n)
        return out

    def pending(self) -> list[int]:
        """Open photos with a selection, lowest first."""
        return sorted(n for n, p in self.photos.items() if p.selection is not None and self.is_open(n))

    def blockers(self, n: int) -> list[int]:
        """Photos below n that may still get a selection: n waits for them (or gives up).
        Open photos without a selection, and numbers not heard of yet that could become
        n's anchor or the session's origin (above n's nearest posed photo below, else from
        0: a session's photos are numbered from 0 up; at most ``LOOK_BACK`` below n): a
        photo in flight, whose hypotheses (or an Error naming it: every frame ends as one)
        have not come yet."""
        known = {m for m, p in self.photos.items()
                 if m < n and p.selection is None and self.is_open(m)}
        posed = max((m for m in self.poses if m < n), default=-1)
        lo = max(0, n - LOOK_BACK, posed + 1)
        unheard = {m for m in range(lo, n) if m not in self.photos and m not in self.poses
                   and m not in self.closed}
        return sorted(known | unheard)

    def anchor(self, n: int) -> list[int]:
        """Posed photos to chain n from, best first: the nearest below, then above."""
        below = sorted((m for m in self.poses if m < n), reverse=True)
        above = sorted(m for m in self.poses if m > n)
        return below + above

    def prune(self) -> None:
        """Drop payloads no longer needed: posed photos beyond the newest anchors, and
        frames of the oldest open photos beyond ``keep_frames``."""
        posed = sorted(n for n in self.photos if n in self.poses)
        for n in posed[:max(0, len(posed) - self.anchors)]:
            del self.photos[n]
        with_frames = sorted(n for n, p in self.photos.items()
                             if p.frame is not None and n not in self.poses)
        for n in with_frames[:max(0, len(with_frames) - self.keep_frames)]:
            self.photos[n].frame = None   # asked for again if selected (its time is kept)

    def adopt(self, poses: dict[int, PlanarPose], times: dict[int, int]) -> None:
        """Take poses already on the bus that this session does not have (it was handled
        before a restart or an eviction, or by another instance); the lowest is the origin."""
        for n, p in poses.items():
            if n not in self.poses:
                self.poses[n] = p
                self.times[n] = times.get(n, 0)
                self.closed.pop(n, None)
                self.failed.pop(n, None)
        if self.poses and self.origin is None:
            self.origin = min(self.poses)
