"""One whole-frame detection shared by the gravity estimate and the hypotheses
(findme_core.single.segments), on rendered rooms."""

import cv2
import numpy as np
import pytest

from findme_core.single.methods import hypothesize
from findme_core.single.segments import (LSD_SCALE, MIN_SEGMENT_PX, Segments, clip_below,
                                         detect_segments, horizon_top_row, photo_segments)


def test_clip_below_cuts_at_the_row():
    segs = np.array([[0.0, 100.0, 100.0, 300.0],     # crosses row 200
                     [0.0, 50.0, 100.0, 150.0],      # wholly above
                     [0.0, 250.0, 100.0, 260.0],     # wholly below
                     [10.0, 190.0, 300.0, 190.0]])   # along a row above
    out = clip_below(segs, 200.0)
    assert out.shape == (2, 4)
    assert np.allclose(out[0], [50.0, 200.0, 100.0, 300.0])
    assert np.allclose(out[1], segs[2])
    assert clip_below(np.zeros((0, 4)), 10.0).shape == (0, 4)


def test_below_matches_a_detection_of_those_rows(tilted_view, level_view):
    """The whole-frame segments' part below the horizon is what a detection of those rows
    alone finds (within a pixel), so the hypotheses can take it instead of detecting."""
    for v in (tilted_view, level_view):
        shared = Segments.detect(v.image)
        top = horizon_top_row(v.camera)
        own = detect_segments(v.image, "lsd", MIN_SEGMENT_PX, LSD_SCALE, top_row=top)
        part = shared.below(top)
        assert part.size and (part[:, [1, 3]] >= top - 1e-9).all()
        # every long segment of the crop detection lies on a segment of the shared part
        long = own[np.hypot(*(own[:, 2:] - own[:, :2]).T) > 40]
        for s in long:
            mid = (s[:2] + s[2:]) / 2
            d = part[:, 2:] - part[:, :2]
            n = np.column_stack([-d[:, 1], d[:, 0]]) / np.hypot(d[:, 0], d[:, 1])[:, None]
            off = np.abs(((mid - part[:, :2]) * n).sum(1))
            t = ((mid - part[:, :2]) * d).sum(1) / (d * d).sum(1)
            assert ((off < 1.5) & (t > -0.05) & (t < 1.05)).any()


def test_fits_only_the_same_detection():
    s = Segments(np.zeros((0, 4)), 640, 480, LSD_SCALE)
    assert s.fits(640, 480, LSD_SCALE, MIN_SEGMENT_PX)
    assert not s.fits(640, 480, 0.8, MIN_SEGMENT_PX)       # another scale
    assert not s.fits(320, 240, LSD_SCALE, MIN_SEGMENT_PX)  # another size
    assert s.below(100).shape == (0, 4)


def test_photo_segments_are_at_the_working_size(tilted_view):
    big = cv2.resize(tilted_view.image, (1920, 1440), interpolation=cv2.INTER_CUBIC)
    s = photo_segments(big)
    assert (s.width, s.height) == (640, 480) and s.gray.shape == (480, 640)
    assert s.segs[:, [0, 2]].max() < 640 and s.segs[:, [1, 3]].max() < 480


def test_hypotheses_from_shared_segments(tilted_view, box_view):
    """Given the photo's whole-frame segments, the hypotheses skip their own detection and
    find the same best boundary (the shared part differs from a crop detection only at the
    cut row)."""
    for v in (tilted_view, box_view):
        own = hypothesize(v.image, v.camera)
        shared = hypothesize(v.image, v.camera, segments=photo_segments(v.image))
        a, b = own.hypotheses[0].polyline, shared.hypotheses[0].polyline
        cols = np.arange(640.0)
        assert np.abs(np.interp(cols, a[:, 0], a[:, 1])
                      - np.interp(cols, b[:, 0], b[:, 1])).mean() < 1.0
    # a detection of another size is not taken: the result is the photo's own
    wrong = Segments(np.array([[0.0, 470.0, 639.0, 470.0]]), 320, 240, LSD_SCALE)
    again = hypothesize(tilted_view.image, tilted_view.camera, segments=wrong)
    ref = hypothesize(tilted_view.image, tilted_view.camera)
    assert np.allclose(again.hypotheses[0].polyline, ref.hypotheses[0].polyline)


@pytest.mark.parametrize("bad", [np.zeros((4, 4, 3, 1), np.uint8)])
def test_bad_image_is_refused(bad):
    from findme_core.errors import InputError
    with pytest.raises(InputError):
        Segments.detect(bad)
