"""``findme eval --declared-surface``: the surface a user tapping each query point would say.
A floor point is said floor, a wall point wall; a TUM non-floor point wall where its surface
is vertical (a cabinet's front), top where it is not (the cabinet's top) and nothing where the
dataset does not say."""

from __future__ import annotations

from findme.evaluation.views import declared_surfaces


def test_each_query_point_is_said_to_be_on_the_surface_its_user_would_name():
    meta = {"floor_points": [{"px": [1, 2]}, {"px": [3, 4]}],
            "wall_points": [{"px": [5, 6], "wall": 0}],
            "nonfloor_points": [{"px": [7, 8], "vertical_surface": True},
                                {"px": [9, 10], "vertical_surface": False},
                                {"px": [11, 12]}]}
    assert declared_surfaces(meta) == {"floor_points": ["floor", "floor"],
                                       "wall_points": ["wall"],
                                       "nonfloor_points": ["wall", "top", None]}
    assert declared_surfaces({}) == {"floor_points": [], "wall_points": [],
                                     "nonfloor_points": []}
