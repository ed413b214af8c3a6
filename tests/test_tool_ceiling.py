"""``tools/ceiling_report.py``'s geometry on rendered rooms, where the ceiling height is known:
the room height a true boundary implies is the room's, and a view without ceiling implies
none (so the tool's measured "no signal" on the dev views is the cue's, not a bug's)."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
from ceiling_report import (gradients, implied_height, ceiling_support,  # noqa: E402
                            wall_floor_points)
from findme_core.single.search import SegKind  # noqa: E402
from findme_core.synth.render import render  # noqa: E402
from findme_core.synth.room import Pose, Room  # noqa: E402

BOX = np.array([[-2.5, -2.0], [2.5, -2.0], [2.5, 3.0], [-2.5, 3.0]])


def _implied(ceiling_m: float, pitch_deg: float, yaw_deg: float) -> tuple[float, float]:
    view = render(Room(BOX, ceiling_height=ceiling_m),
                  Pose(0.3, -0.5, 1.5, yaw_deg=yaw_deg, pitch_deg=pitch_deg), hfov_deg=70)
    poly = view.ground_truth_boundary_polyline()
    floor = wall_floor_points(view.camera, view.camera_height, poly,
                              np.full(len(poly) - 1, SegKind.WALL))
    return implied_height(ceiling_support(gradients(view.image), view.camera,
                                          view.camera_height, floor))


@pytest.mark.parametrize("ceiling_m, pitch_deg, yaw_deg",
                         [(2.7, 0.0, 20.0), (2.4, 10.0, -30.0), (3.0, -5.0, 60.0)])
def test_the_true_boundary_implies_the_rooms_height(ceiling_m, pitch_deg, yaw_deg):
    height, support = _implied(ceiling_m, pitch_deg, yaw_deg)
    assert height == pytest.approx(ceiling_m, abs=0.051)
    assert support > 0.9


def test_no_ceiling_in_view_implies_no_height():
    # looking down 20 degrees with a 70 degree field of view: the ceiling is above the photo
    height, support = _implied(2.6, 20.0, 45.0)
    assert np.isnan(height) and np.isnan(support)
