"""Joint refinement of a session's poses and the room's wall lines: one small robust
least-squares over every wall-base sample (point to its wall's line), the layouts' corners
(to the outline's vertices), the turns between photos of one spot and the feature matches
between spots (epipolar planes); the room, closed, closes the loop. Its covariance gives each
wall length a 1-sigma. The problem (unknowns, residuals, their sparsity) is
``problem``.

Frames and units: the room frame (x, z metres; level frame of photo 0). Loss: soft-L1
(``f_scale`` sigmas): furniture, doors and bad matches that got through weigh little.
Solver: ``scipy.optimize.least_squares`` (trust-region reflective, finite differences over
the residuals' sparsity).

Pure numpy + scipy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from findme_core.errors import GeometryError
from findme_core.plan.problem import Problem, RefineParams, vertices_of

__all__ = ["RefineParams", "Refined", "refine", "vertices_of"]


@dataclass(frozen=True)
class Refined:
    """The refinement's answer.

    Attributes:
        poses: (N, 3) refined poses (NaN rows stay NaN).
        normals, offsets: (K, 2), (K,) refined lines of the outline.
        vertices: (V, 2) refined outline vertices (intersections of consecutive lines).
        length, sigma_length: (V,) wall k's length (vertex k to k + 1) and its 1-sigma, m.
        sigma_pose: (N, 3) 1-sigma of each pose (x, z metres, yaw radians).
        sigma_corner: (V, 2) 1-sigma of each vertex's x and z, metres (the covariance of the
            lines it is the intersection of, and the camera height's relative error along
            its distance from the origin photo).
        chi2_dof: weighted residual sum over degrees of freedom (about 1 when the sigmas
            are right; the covariance is inflated by it when above 1).
        n_samples, n_matches: residuals of each kind that took part.
    """

    poses: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    vertices: np.ndarray
    length: np.ndarray
    sigma_length: np.ndarray
    sigma_pose: np.ndarray
    sigma_corner: np.ndarray
    chi2_dof: float
    n_samples: int
    n_matches: int




def refine(layouts, poses, spot, outline, axis=None, snapped=None, links=(), matches=None,
           focal=None, params: RefineParams = RefineParams(), prior=None,
           tilt=None) -> Refined:
    """Poses and outline lines refined together (see the module docstring).

    Args:
        layouts: N layouts (None: none); poses: (N, 3) starting poses (NaN: not placed).
        spot: (N,) spot label of each photo (photos of one spot share a position).
        outline: ``polygon.Outline`` at the starting poses (its topology is kept).
        axis, snapped: the Manhattan axis (radians, or None) and which of the outline's
            lines (K,) are on it.
        links: ``fuse.Link`` turns between photos of one spot.
        matches: {(i, j): (a (M, 3), b (M, 3))} unit level bearings of feature matches.
        focal: (N,) focal lengths in pixels (for ``match_px``), or None (500).
        prior: (N, 3) poses the spot positions are held near (``prior_m``); default
            ``poses``.
        tilt: (N,) 1-sigma of each photo's gravity tilt per axis, radians (0 or None:
            exact): marginalised in its matches' bearings (``problem.Problem._tilts``).

    Raises:
        GeometryError: nothing to refine (no placed photo sees an outline wall).
    """
    poses = np.asarray(poses, float).reshape(-1, 3)
    snapped = np.zeros(len(outline.lines.normals), bool) if snapped is None else snapped
    pr = Problem(layouts, poses, spot, outline, axis, snapped, links, matches, focal, params,
                 tilt)
    if prior is not None:
        pr.prior0 = np.concatenate([np.asarray(prior, float)[(pr.spot == s) & pr.placed][0, :2]
                                    for s in pr.spot_ix]) if pr.spot_ix else pr.prior0
    if len(pr.sp) == 0:
        raise GeometryError("no photo's wall samples lie on the outline: nothing to refine")
    res = least_squares(pr.residuals, pr.x0, loss="soft_l1", f_scale=params.f_scale,
                        max_nfev=params.max_nfev * max(1, len(pr.x0)), x_scale="jac",
                        jac_sparsity=pr.sparsity())
    m, k = len(res.fun), len(res.x)
    chi2_dof = float(2.0 * res.cost / max(m - k, 1))
    J = res.jac.toarray() if hasattr(res.jac, "toarray") else res.jac
    cov = np.linalg.pinv(J.T @ J) * max(1.0, chi2_dof)
    n, d = pr.lines(res.x)
    V = vertices_of(n, d, pr.line, pr.V0)
    length = np.linalg.norm(np.roll(V, -1, axis=0) - V, axis=1)
    # d length / d x and d vertex / d x by central differences on the line parameters
    G, Gv = np.zeros((len(V), k)), np.zeros((len(V), 2, k))
    for j in range(pr.n_pose, k):
        h = 1e-6
        xp, xm = res.x.copy(), res.x.copy()
        xp[j] += h
        xm[j] -= h
        Vp = vertices_of(*pr.lines(xp), pr.line, pr.V0)
        Vm = vertices_of(*pr.lines(xm), pr.line, pr.V0)
        G[:, j] = (np.linalg.norm(np.roll(Vp, -1, 0) - Vp, axis=1)
                   - np.linalg.norm(np.roll(Vm, -1, 0) - Vm, axis=1)) / (2 * h)
        Gv[:, :, j] = (Vp - Vm) / (2 * h)
    var = np.einsum("vi,ij,vj->v", G, cov, G) + (params.height_rel * length) ** 2
    # a vertex's x, z: the lines' covariance, and the height scaling its distance from photo 0
    var_v = np.einsum("vai,ij,vaj->va", Gv, cov, Gv) + (params.height_rel * V) ** 2
    sp = np.full((pr.N, 3), np.nan)
    for i in np.flatnonzero(pr.placed):
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        s = pr.spot[i]
        xy = (0.0, 0.0) if s == pr.spot[0] else sd[pr.spot_ix[s]:pr.spot_ix[s] + 2]
        sp[i] = (xy[0], xy[1], 0.0 if i == 0 else sd[pr.yaw_ix[i]])
    return Refined(pr.poses(res.x), n, d, V, length, np.sqrt(var), sp, np.sqrt(var_v), chi2_dof,
                   len(pr.sp), int(sum(len(m[2]) for m in pr.mt)))
