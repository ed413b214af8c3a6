"""3D scene of one photo under a chosen boundary: the floor plane and the walls on it.

Frames: pixels (u, v); rays and points in the camera's level frame (y down along gravity,
floor at y = h) inside, camera frame (OpenCV) at the interface. Metres.

* Floor point (paper eq. 2, P = h (x/y, 1, 1/y) for a level camera's normalised pixel
  (x, y)); generalised by gravity: P_level = (h / r_y) r for the level ray r of the pixel.
* Wall (eqs. 3-4): the vertical plane through the floor line of a boundary segment. The
  segment's image vertices are lifted to the floor (eq. 2), giving a 2D line in the level
  x-z plane; a wall pixel's 3D point is its ray scaled to meet that plane.

Each boundary segment covers an interval of azimuth (angle of the horizontal ray,
atan2(x, z)). A tapped pixel's azimuth selects its segment; it is on the floor if its ray
meets the floor before the wall, else on the wall. OPEN segments (floor continues past the
image) have floor but no known wall; NONE segments (no floor in view) have neither. A WALL
segment that lies wholly outside the image (the hypothesis continued the boundary below or
above the photo's edge) is a wall nobody saw the base of: ``locate`` gives its points no answer
(``Reason.UNSEEN``) rather than a distance that is an inference; so does every wall of a
photo that shows almost no floor under its boundary (``Reason.NO_FLOOR_VIEW``,
``seen.shows_floor``). A pixel said to be on the top of something standing on the boundary
(a table, a counter) is put on that top (``tops``). A floor point just beside a step of the
boundary may be on the face in front of it instead (``steps``). The texts a user reads are
``answers``'.

A point whose 1-sigma (``uncertainty``) exceeds ``max_rel_sigma`` of its distance is not
placed: an honest "unknown" (``Reason.LOOSE``) rather than a guess. On real photos these
are mostly wall points above a boundary chosen near the horizon (a counter's or a sill's edge
taken for the floor line), where a pixel is worth metres.

How far each point may be off (boundary, height, tap, gravity) is ``uncertainty``'s.
"""

from __future__ import annotations

import numpy as np

from findme_core.errors import GeometryError, HypothesisError
from findme_core.geometry.camera import Camera
# the answers (``Located``) and their texts live in ``answers``; re-exported here, where
# they began
from findme_core.single.answers import (FACE_OR_TOP_NOTE, FLOOR_OR_FACE_NOTE,  # noqa: F401
                                        FLOOR_PAST_LINE, NOTES, REASONS, SURFACE_CODES,
                                        SURFACE_NAMES, SURFACES, Located, Reason, said_codes)
from findme_core.single import steps, tops
from findme_core.single.search import SegKind
from findme_core.single.seen import shows_floor, walls_seen
# the uncertainty of the points lives in ``uncertainty``; re-exported here, where it began
from findme_core.geometry.uncertainty import (BOUNDARY_SIGMA_WORK_PX, WORK_SIZE_PX,  # noqa: F401
                                              boundary_sigma_px, distances, point_sigmas)

_PARALLEL = 1e-9
#: default ``max_rel_sigma``: a point whose 1-sigma is more than half its distance is not
#: placed (its distance is uncertain by a factor of three within 1-sigma); a round number,
#: not fitted
MAX_REL_SIGMA = 0.5


class Scene:
    """Floor and walls of one photo under one hypothesis.

    Args:
        camera: intrinsics and gravity.
        height: camera height above the floor, metres (> 0); 1.0 gives results up to scale.
        polyline: (M, 2) boundary vertices in pixels, u non-decreasing.
        kinds: (M - 1,) SegKind per segment (default: all WALL).
        height_sigma: 1-sigma error of ``height`` in metres.
        boundary_sigma_px: boundary error used for the uncertainty, pixels.
        gravity_cov: (2, 2) covariance (rad^2) of gravity's tilt about the level x (pitch)
            and z (roll) axes (``provenance.Provenance.gravity_cov``); None = exact.
        max_rel_sigma: a point whose 1-sigma exceeds this share of its distance from the
            camera gets no answer (reason in ``REASONS``); None answers every point.
        lines: (L, 4) the photo's straight lines [u1, v1, u2, v2], pixels, where a top's
            front edge is looked for (``tops``); None: points said on a top get no answer.
    """

    def __init__(self, camera: Camera, height: float, polyline, kinds=None,
                 height_sigma: float = 0.03, boundary_sigma_px: float = 1.0,
                 gravity_cov=None, max_rel_sigma: float | None = MAX_REL_SIGMA, lines=None):
        if not np.isfinite(height) or height <= 0:
            raise GeometryError(f"camera height must be a positive number of metres, got {height!r}")
        poly = np.asarray(polyline, float).reshape(-1, 2)
        if len(poly) < 2 or not np.all(np.isfinite(poly)):
            raise HypothesisError(f"a boundary needs at least 2 finite vertices, got {poly.tolist()}")
        kinds = np.full(len(poly) - 1, SegKind.WALL) if kinds is None else np.asarray(kinds, int)
        if len(kinds) != len(poly) - 1:
            raise HypothesisError(f"{len(kinds)} segment kinds for {len(poly)} vertices")
        self.camera, self.height, self.polyline, self.kinds = camera, float(height), poly, kinds
        self.height_sigma, self.boundary_sigma_px = float(height_sigma), float(boundary_sigma_px)
        self.gravity_cov = (np.zeros((2, 2)) if gravity_cov is None
                            else np.asarray(gravity_cov, float).reshape(2, 2))
        if not np.all(np.isfinite(self.gravity_cov)):
            raise GeometryError(f"gravity_cov must be finite, got {self.gravity_cov.tolist()}")
        if max_rel_sigma is not None and not (np.isfinite(max_rel_sigma) and max_rel_sigma > 0):
            raise GeometryError(f"max_rel_sigma must be a positive number or None, got "
                                f"{max_rel_sigma!r}")
        self.max_rel_sigma = None if max_rel_sigma is None else float(max_rel_sigma)
        lines = None if lines is None else np.asarray(lines, float)
        if lines is not None and (lines.size % 4 or not np.all(np.isfinite(lines))):
            raise GeometryError("the photo's lines must be finite pixels [u1, v1, u2, v2], 4 "
                                f"numbers each; got {lines.size} numbers"
                                + ("" if lines.size % 4 else ", not all finite"))
        self.lines = None if lines is None else lines.reshape(-1, 4)
        self._pieces = self._build(poly)
        self.shows_floor = shows_floor(poly, kinds, camera.width, camera.height)
        # the boundary part is linearised: the scene under the boundary moved down (and, for
        # a steep boundary, sideways) by at most one pixel, the displacement scaled up to
        # ``boundary_sigma_px``
        self._shift_px = min(self.boundary_sigma_px, 1.0)
        self._pieces_shifted = self._build(poly + np.array([0.0, self._shift_px]))
        self._pieces_sideways = self._build(poly + np.array([self._shift_px, 0.0]))

    def _build(self, poly, cam: Camera | None = None):
        """Pieces, one per floor or wall segment (P of them, in order): (P,) azimuths
        az0 <= az1 it covers, (P,) SegKind, (P, 2) wall normal n and (P,) offset with
        n . (x, z) = offset on the wall (zeros for a segment without a wall)."""
        cam = self.camera if cam is None else cam
        R = cam.R_level_from_cam
        r = cam.rays_cam(poly) @ R.T
        az = np.arctan2(r[:, 0], r[:, 2])
        wall = self.kinds == SegKind.WALL
        horizon = np.flatnonzero(wall & ((r[:-1, 1] <= 0) | (r[1:, 1] <= 0)))
        if len(horizon):
            s = horizon[0]
            raise HypothesisError(
                f"boundary segment {s} from {poly[s].round(1).tolist()} to "
                f"{poly[s + 1].round(1).tolist()} reaches the horizon: not a floor line")
        with np.errstate(divide="ignore", invalid="ignore"):   # (vertices of no wall)
            q = (self.height / r[:, 1])[:, None] * r[:, [0, 2]]   # eq. 2 on each vertex
            d = q[1:] - q[:-1]
            length = np.hypot(d[:, 0], d[:, 1])
        wall &= ~(length < 1e-9)                   # a wall of no length: no piece
        normal, offset = np.zeros((len(wall), 2)), np.zeros(len(wall))
        normal[wall] = np.column_stack([-d[wall, 1], d[wall, 0]]) / length[wall, None]
        offset[wall] = normal[wall, 0] * q[:-1][wall, 0] + normal[wall, 1] * q[:-1][wall, 1]
        keep = wall | ((self.kinds != SegKind.STEP) & (self.kinds != SegKind.WALL))
        if not keep.any():
            raise HypothesisError("the boundary has no floor or wall segment")
        a0, a1 = az[:-1][keep], az[1:][keep]
        return (np.minimum(a0, a1), np.maximum(a0, a1), self.kinds[keep].astype(int),
                normal[keep], offset[keep], walls_seen(poly, cam.height, wall, normal, offset)[keep])

    # ------------------------------------------------------------------ queries
    def _solve(self, pieces, rays):
        """Vectorised: (N, 3) level rays -> ((N,) ray parameter t, (N,) surface code, (N,)
        failure reason); the point is t * ray. Surfaces: 1 floor, 2 wall, 0 none."""
        n = len(rays)
        a0, a1, kind, normal, offset, seen = pieces
        k = self._piece(pieces, rays)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_floor = np.where(rays[:, 1] > 0, self.height / rays[:, 1], np.inf)
            den = (normal[k] * rays[:, [0, 2]]).sum(1)
            t = offset[k] / den
        wall = kind[k] == SegKind.WALL
        parallel = wall & (np.abs(den) <= _PARALLEL)
        behind = wall & ~parallel & ~(t > 0)
        t_wall = np.where(wall & ~parallel & ~behind, t, np.inf)
        floor = t_floor <= t_wall
        t_out = np.where(floor, t_floor, t_wall)
        surface = np.where(floor, 1, 2)
        reason = np.zeros(n, int)
        none = kind[k] == SegKind.NONE
        bad = ~np.isfinite(t_out) | none
        reason[bad & parallel] = Reason.PARALLEL_RAY
        reason[bad & behind] = Reason.BEHIND
        reason[bad & (reason == 0)] = Reason.ABOVE_HORIZON
        reason[none] = Reason.NO_FLOOR
        reason[~bad & ~floor & ~seen[k]] = Reason.UNSEEN   # on a wall whose base is not in view
        surface[bad] = 0
        return np.where(bad, np.nan, t_out), surface, reason

    @staticmethod
    def _piece(pieces, rays) -> np.ndarray:
        """(N,) the piece each (N, 3) level ray's azimuth falls in; outside every interval,
        the nearest end piece (walls extend past the image)."""
        az = np.arctan2(rays[:, 0], rays[:, 2])[:, None]
        a0, a1 = pieces[0][None, :], pieces[1][None, :]
        out = np.zeros(len(az), int)
        step = max(1, tops.BLOCK // a0.size)   # rays x pieces in blocks: bounded memory
        for i in range(0, len(az), step):
            a = az[i:i + step]
            inside = (a0 <= a) & (a <= a1)
            gap = np.minimum(np.abs(a - a0), np.abs(a - a1))
            out[i:i + step] = np.where(inside.any(1), np.argmax(inside, 1), np.argmin(gap, 1))
        return out

    def _top_t(self, pieces, rays, edge_rays) -> np.ndarray:
        """(N,) ray parameters of points on tops (``tops.top_t``) under ``pieces``."""
        k = self._piece(pieces, rays)
        return tops.top_t(rays, edge_rays, pieces[3][k], pieces[4][k])

    def locate_level(self, pixels):
        """Vectorised 3D of (N, 2) pixels in the LEVEL frame.

        Returns:
            points: (N, 3) metres (NaN where there is no answer),
            surface: (N,) 1 floor, 2 wall, 0 none,
            sigma: (N,) 1-sigma radius (m; inf where no answer),
            parts: dict of (N,) sigma components "height", "boundary", "pixel", "gravity",
                "surface" (zero here),
            reason: (N,) failure reason code (0 = answered; see ``REASONS``).

        Unlike ``locate``, points on a wall whose base is not in view (or in a photo that
        shows almost no floor) are answered: the motion's lifting weighs each point by its
        sigma and was measured with them.
        """
        return self._locate_all(pixels, unseen=True)[:5]

    def _locate_all(self, pixels, surfaces=None, unseen: bool = False):
        """``locate_level``'s five results plus the (N, 2, 3) gravity displacements
        (``uncertainty.point_sigmas``) and the (N,) note codes (``NOTES``; 0: none).
        ``surfaces``: (N,) "floor", "wall", "top" or None per pixel, the surface the user says
        it is on: a floor pixel is put on the floor whatever the boundary (below the horizon);
        a top pixel on its top (``tops.place``); a wall pixel the boundary puts on the floor
        gets no answer. ``unseen``: answer points on walls whose base is outside the photo (or
        in a photo that shows almost no floor) too, each point read on its surface alone (the
        motion's lifting; else a point nobody said the surface of gains the spread of
        ``tops.face_or_top`` or ``steps.floor_or_face``).

        Raises:
            InputError: ``surfaces`` is not one entry per pixel or names no surface."""
        cam = self.camera
        px = np.asarray(pixels, float).reshape(-1, 2)
        edges = np.full(px.shape, np.nan)   # the front edges of points on tops (``tops.place``)
        finite = np.isfinite(px).all(1)
        pxs = np.where(finite[:, None], px, 0.0)
        inside = (finite & (pxs[:, 0] >= -0.5) & (pxs[:, 0] <= cam.width - 0.5)
                  & (pxs[:, 1] >= -0.5) & (pxs[:, 1] <= cam.height - 0.5))
        rays = cam.rays_level(pxs)
        t, surface, reason = self._solve(self._pieces, rays)
        if unseen:
            reason = np.where(reason == Reason.UNSEEN, 0, reason)
        elif not self.shows_floor:   # no wall's foot is seen (``seen.shows_floor``)
            reason = np.where((reason == 0) & (surface == 2), Reason.NO_FLOOR_VIEW, reason)
        note = np.zeros(len(px), int)
        said = said_codes(surfaces, len(px))     # 0: nothing said
        if said.any():
            floor = (said == 1) & (rays[:, 1] > 0)
            note[floor & (surface != 1)] = FLOOR_PAST_LINE   # the line puts no floor here
            t = np.where(floor, self.height / np.where(floor, rays[:, 1], 1.0), t)
            surface = np.where(floor, 1, surface)
            reason = np.where(floor, 0, np.where(said == 1, Reason.ABOVE_HORIZON, reason))
            reason = np.where((said == 2) & (reason == 0) & (surface == 1), Reason.NOT_WALL, reason)
            if (said == 3).any():
                t, surface, reason, edges = tops.place(self, said == 3, pxs, rays, t, surface,
                                                        reason)
        reason = np.where(inside, reason, np.where(finite, Reason.OUTSIDE, Reason.NOT_FINITE))
        ok = reason == 0
        surface = np.where(ok, surface, 0)
        P = t[:, None] * rays
        P[~ok] = np.nan
        # which surface (not lifting's): a face with a top's edge below the point, a floor point
        # beside a step of the boundary; the spread of the two readings (a point has one)
        top = step = np.zeros(len(px))
        if not unseen:
            top = tops.face_or_top(self, said == 0, pxs, rays, t, surface, reason)
            step = steps.floor_or_face(self, said == 0, pxs, rays, t, surface, reason,
                                       self.boundary_sigma_px)
        note = np.select([top > 0, step > 0], [FACE_OR_TOP_NOTE, FLOOR_OR_FACE_NOTE], note)

        parts, jac = point_sigmas(self, pxs, rays, P, surface, edges)
        parts["surface"] = top + step
        sigma = np.sqrt(sum(x * x for x in parts.values()))
        if self.max_rel_sigma is not None:
            with np.errstate(invalid="ignore"):
                loose = ok & ~(sigma <= self.max_rel_sigma * np.linalg.norm(P, axis=1))
            rest = np.maximum.reduce([parts[k] for k in ("height", "boundary", "pixel")])
            by_gravity = parts["gravity"] >= np.maximum(rest, parts["surface"])
            by_surface = ~by_gravity & (parts["surface"] >= rest)
            reason = np.where(loose, np.select(
                [by_gravity, by_surface & (step > 0), by_surface],
                [Reason.LOOSE_GRAVITY, Reason.FLOOR_OR_FACE, Reason.FACE_OR_TOP], Reason.LOOSE),
                reason)
            ok &= ~loose
            surface = np.where(ok, surface, 0)
            P[~ok] = np.nan
        sigma = np.where(ok, sigma, np.inf)
        return P, surface, sigma, parts, reason, jac, np.where(ok, note, 0)

    def locate(self, pixels, surfaces=None) -> list[Located]:
        """3D of each (u, v) pixel (N, 2) in the camera frame; failures are reported per
        point (``Located.error``), not raised. ``surfaces``: as ``_locate_all`` (InputError
        when they are not one surface or None per pixel)."""
        px = np.asarray(pixels, float).reshape(-1, 2)
        P, surface, sigma, parts, reason, jacs, notes = self._locate_all(px, surfaces)
        R = self.camera.R_level_from_cam
        out = []
        for i, (u, v) in enumerate(px):
            if reason[i]:
                out.append(Located((u, v), None, None, error=self._reason_text(reason[i], u, v)))
                continue
            jac = jacs[i] if np.any(self.gravity_cov) else None
            out.append(Located((u, v), SURFACE_NAMES[surface[i]], R.T @ P[i], float(sigma[i]),
                               {k: float(x[i]) for k, x in parts.items()}, gravity_jac=jac,
                               note=NOTES.get(int(notes[i]))))
        return out

    def _reason_text(self, code: int, u: float, v: float) -> str:
        if code == Reason.OUTSIDE:
            return f"pixel ({u:g}, {v:g}) is outside the {self.camera.width}x{self.camera.height} image"
        if code == Reason.NOT_FINITE:
            return f"pixel ({u}, {v}) is not finite"
        return REASONS[code]

    def floor_point(self, pixel) -> np.ndarray:
        """(3,) camera-frame floor point of a pixel (eq. 2), whatever the walls.

        Raises:
            GeometryError: the pixel is at or above the horizon.
        """
        ray = self.camera.rays_level([pixel])[0]
        if ray[1] <= 1e-12:
            raise GeometryError(f"pixel {tuple(np.round(pixel, 2))} is at or above the horizon: "
                                "its ray never meets the floor")
        return self.camera.R_level_from_cam.T @ (self.height / ray[1] * ray)
