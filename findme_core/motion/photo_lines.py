"""A photo's straight lines in its own pixels, as ``methods.hypothesize`` finds them (at the
working size), for the parts of a motion that use them (the room's orientation, a top's
front edge) and for the services that pass them on instead of detecting them again.

Frames and units: pixels of the photo, [u1, v1, u2, v2] per line (pixel-centre origin).
"""

from __future__ import annotations

import numpy as np

from findme_core.single.hypotheses import HypothesisParams
from findme_core.single.lines import detect_segments, merge_collinear
from findme_core.single.segments import work_pixels, work_scale


def _work_scale(image) -> float:
    """The scale ``methods.hypothesize`` works at for this image (1: full size)."""
    return work_scale(*image.shape[:2])


def _full_size(ends, s: float):
    """Segments (N, 4) found at working scale ``s`` back in the photo's pixels."""
    return ends if s == 1.0 else (np.asarray(ends, float) + 0.5) / s - 0.5


def photo_lines(hs, image) -> np.ndarray:
    """(N, 4) the lines ``methods.hypothesize`` found in ``image`` (its ``HypothesisSet``
    ``hs``, at the working size) in the photo's pixels: what ``line_segments`` detects."""
    return _full_size(np.asarray(hs.lines.ends, float).reshape(-1, 4), _work_scale(image))


def segment_lines(segments, image) -> np.ndarray:
    """(N, 4) the merged lines of a whole-frame detection (``segments.photo_segments``, as a
    gravity estimate carries it) in the photo's pixels: what ``line_segments`` detects,
    without detecting again."""
    return _full_size(merge_collinear(segments.segs).ends, _work_scale(image))


def line_segments(image) -> np.ndarray:
    """(N, 4) the photo's merged straight lines [u1, v1, u2, v2] in its pixels, as
    ``methods.hypothesize`` finds them (same working size, detector and settings), for a
    photo whose hypotheses came without their lines (e.g. over the bus)."""
    p = HypothesisParams()
    small, s = work_pixels(image)
    segs = detect_segments(small, p.segment_method, p.min_segment_px, lsd_scale=p.lsd_scale)
    return _full_size(merge_collinear(segs).ends, s)
