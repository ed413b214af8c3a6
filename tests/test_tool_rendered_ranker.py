"""``tools/rendered_ranker.py``: its row error on polylines given by hand, and one rendered
photo's hypotheses against its exact boundary (a view of the 5 x 4 m room whose wall base is
plain: found within 2 % of the height)."""

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room
from tests.plan_room import H

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import rendered_ranker as rr  # noqa: E402


def test_row_error_is_the_mean_row_gap_over_the_height_clipped_to_the_image():
    flat = np.array([[0.0, 100.0], [639.0, 100.0]])
    assert rr.row_error(flat, flat + [0.0, 48.0], 640, 480) == pytest.approx(0.1)
    below = np.array([[0.0, 900.0], [639.0, 900.0]])      # "no floor": clipped to row 480
    assert rr.row_error(below, flat, 640, 480) == pytest.approx(380 / 480)


def test_a_plain_rendered_wall_base_is_found():
    v = render(Room.rectangle(5.0, 4.0), Pose(-0.8, -0.5, H, 0.0, 28.0, 0.0), 640, 480,
               hfov_deg=70.0, supersample=1)
    img = cv2.imdecode(cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1],
                       cv2.IMREAD_COLOR)
    top, best = rr.photo_errors(v, img, 5)
    assert top < 0.02 and best <= top
    assert "1 photos: top-1" in rr.summary([{"room": "5x4", "spots": 2, "turn": 60, "photo": 0,
                                             "top1": top, "best": best}], 5)
